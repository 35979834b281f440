#include <talus/input/yaml_input.hpp>
#include <talus/regular_file.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <unordered_map>

namespace talus::yaml {

namespace {

std::string mark_text(const std::string &file, const YAML::Mark &m) {
    if (m.is_null()) return file;
    return fmt::format("{}:{}:{}", file, m.line + 1, m.column + 1);
}

// A node's path; the user's names in it are data (a material's name goes
// to its plugin), clipped only where a message shows it.
std::string child_path(const std::string &parent, std::string_view key) {
    return parent.empty() ? std::string(key) : parent + "." + std::string(key);
}

} // namespace

// IsDefined() is the one question a missing child (yaml-cpp's "zombie")
// answers without throwing; it is replaced, never assigned to (assigning to
// a yaml-cpp node writes through to the document).
Node::Node(YAML::Node node, std::string file, std::string path, YAML::Mark fallback)
    : node_(node.IsDefined() ? std::move(node) : YAML::Node(YAML::NodeType::Undefined)),
      file_(std::move(file)), path_(std::move(path)), mark_(fallback) {
    if (node_.IsDefined() && !node_.Mark().is_null()) mark_ = node_.Mark();
}

std::string Node::where() const { return mark_text(file_, mark_); }

void Node::fail(const std::string &what) const {
    const std::string key = path_.empty() ? std::string() : fmt::format(" '{}'", clip(path_));
    throw Error(fmt::format("{}: error:{} {}", where(), key, what));
}

bool Node::has(std::string_view key) const {
    return node_.IsMap() && node_[std::string(key)].IsDefined();
}

Node Node::get(std::string_view key) const {
    expect_map();
    return Node(node_[std::string(key)], file_, child_path(path_, key), mark_);
}

Node Node::require(std::string_view key) const {
    expect_map();
    const YAML::Node child = node_[std::string(key)];
    if (!child.IsDefined())
        throw Error(fmt::format("{}: error: missing required key '{}'", where(),
                                clip(child_path(path_, key))));
    return Node(child, file_, child_path(path_, key), mark_);
}

Node Node::at(std::size_t index) const {
    expect_sequence();
    return Node(node_[index], file_, fmt::format("{}[{}]", path_, index), mark_);
}

std::vector<std::string> Node::keys() const {
    std::vector<std::string> out;
    for (auto &[key, value] : entries())
        out.push_back(std::move(key));
    return out;
}

std::vector<std::pair<std::string, Node>> Node::entries() const {
    expect_map();
    std::vector<std::pair<std::string, Node>> out;
    // Where each key was first seen, by name: a map of many keys (groups)
    // is read in one pass, not in one search of the whole map per key.
    std::unordered_map<std::string, YAML::Mark> seen;
    for (const auto &kv : node_) {
        // A key is a name: `? [a, b]: 1`, `{a: 1}: 2`, `"": 1` or an empty `: 1`
        // is not.
        if (!kv.first.IsScalar() || kv.first.Scalar().empty())
            throw Error(fmt::format("{}: error: {}a key must be a plain name, got {}",
                                    mark_text(file_, kv.first.Mark()),
                                    path_.empty() ? "" : fmt::format("in '{}': ", clip(path_)),
                                    kv.first.IsNull() || kv.first.IsScalar() ? "an empty key"
                                    : kv.first.IsMap()                       ? "a mapping"
                                                                             : "a sequence"));
        const std::string key = kv.first.Scalar();
        // yaml-cpp keeps both of two equal keys and hands out the first for
        // every lookup: a key (or a group or material name) given twice
        // would silently lose its second definition.
        const auto [first, fresh] = seen.emplace(key, kv.first.Mark());
        if (!fresh)
            throw Error(
                fmt::format("{}: error: '{}' is given twice (first at {}); keys must be unique",
                            mark_text(file_, kv.first.Mark()), clip(child_path(path_, key)),
                            mark_text(file_, first->second)));
        out.emplace_back(key, Node(kv.second, file_, child_path(path_, key), mark_));
    }
    return out;
}

void Node::expect_map() const {
    if (!node_.IsMap()) fail("expected a mapping (key: value pairs)");
}
void Node::expect_sequence() const {
    if (!node_.IsSequence()) fail("expected a sequence ([a, b, ...])");
}

void Node::allow_keys(std::span<const std::string_view> allowed) const {
    keys(); // rejects a key given twice, or one that is not a name
    for (const auto &kv : node_) {
        const std::string key = kv.first.Scalar();
        if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
        const std::string guess = closest_match(key, allowed);
        std::string list;
        for (const auto &a : allowed)
            list += (list.empty() ? "" : ", ") + std::string(a);
        const std::string hint =
            guess.empty() ? fmt::format("allowed keys here: {}", list)
                          : fmt::format("did you mean '{}'? (allowed keys here: {})", guess, list);
        throw Error(fmt::format("{}: error: unknown key '{}'; {}",
                                mark_text(file_, kv.first.Mark()), clip(child_path(path_, key)),
                                hint));
    }
}

double Node::as_double() const {
    if (!node_.IsScalar()) fail("expected a number");
    double v = 0.0;
    try {
        v = node_.as<double>();
    } catch (const YAML::Exception &) {
        fail(fmt::format("expected a number, got '{}'", clip(node_.Scalar())));
    }
    if (!std::isfinite(v))
        fail(fmt::format("expected a finite number, got '{}'", clip(node_.Scalar())));
    return v;
}

long long Node::as_integer() const {
    if (!node_.IsScalar()) fail("expected an integer");
    try {
        return node_.as<long long>();
    } catch (const YAML::Exception &) {
        fail(fmt::format("expected an integer, got '{}'", clip(node_.Scalar())));
    }
}

bool Node::as_bool() const {
    if (!node_.IsScalar()) fail("expected true or false");
    try {
        return node_.as<bool>();
    } catch (const YAML::Exception &) {
        fail(fmt::format("expected true or false, got '{}'", clip(node_.Scalar())));
    }
}

std::string Node::as_string() const {
    if (!node_.IsScalar()) fail("expected a string");
    return node_.Scalar();
}

std::vector<double> Node::as_doubles() const {
    expect_sequence();
    std::vector<double> out;
    for (std::size_t i = 0; i < node_.size(); ++i)
        out.push_back(at(i).as_double());
    return out;
}

Node load_string(const std::string &text, const std::string &name) {
    try {
        YAML::Node root = YAML::Load(text);
        if (!root.IsDefined() || root.IsNull())
            throw Error(fmt::format("{}: error: the file is empty", name));
        // A second document would be ignored: refused. Found by its marker,
        // '---' at the start of a line after the first document's content
        // (where YAML always starts a new one), not by YAML::LoadAll, which
        // loops for ever on some malformed input (yaml-cpp 0.7).
        bool content = false;
        std::size_t line = 0;
        for (std::size_t at = 0; at < text.size(); ++line) {
            const std::size_t eol = std::min(text.find('\n', at), text.size());
            const std::string_view l(text.data() + at, eol - at);
            const bool marker = l.substr(0, 3) == "---" &&
                                (l.size() == 3 || l[3] == ' ' || l[3] == '\t' || l[3] == '\r');
            if (marker && content)
                throw Error(fmt::format("{}:{}:1: error: a second YAML document (after a '---' "
                                        "line): a file holds one document, and the rest would be "
                                        "ignored; remove the '---' or split the file",
                                        name, line + 1));
            const std::size_t first = l.find_first_not_of(" \t\r");
            if (marker ? l.find_first_not_of(" \t\r", 3) != std::string_view::npos &&
                             l[l.find_first_not_of(" \t\r", 3)] != '#'
                       : first != std::string_view::npos && l[first] != '#' && l[first] != '%')
                content = true;
            at = eol + 1;
        }
        return Node(root, name, "");
    } catch (const YAML::ParserException &e) {
        throw Error(fmt::format("{}: error: YAML syntax: {}", mark_text(name, e.mark), e.msg));
    }
}

std::string read_text_file(const std::string &path) {
    try {
        return read_regular_file(path);
    } catch (const Error &e) {
        // "<path>: error: ...", as every message about an input file.
        const std::string m = e.what();
        throw Error(
            fmt::format("{}: error: {}", path, m.substr(std::min(m.size(), path.size() + 2))));
    }
}

Node load_file(const std::string &path) { return load_string(read_text_file(path), path); }

} // namespace talus::yaml
