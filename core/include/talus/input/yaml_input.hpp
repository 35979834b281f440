// Reading user YAML with precise errors: every message starts with
// file:line:column, names the key, says what was expected, and suggests the
// closest known key for a misspelt one. Unknown keys are always errors.
#pragma once

#include <talus/error.hpp>
#include <talus/text.hpp>

#include <yaml-cpp/yaml.h>

#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace talus::yaml {

// A YAML node with the file it came from and its key path ("material.model"),
// so that any error about it can say where it is.
class Node {
  public:
    // `fallback`: where to point when the node has no position of its own
    // (an absent key: its parent's). An absent node is held as a valid,
    // undefined one, so that asking it anything never throws yaml-cpp's
    // InvalidNode.
    Node(YAML::Node node, std::string file, std::string path,
         YAML::Mark fallback = YAML::Mark::null_mark());

    const YAML::Node &raw() const { return node_; }
    const std::string &file() const { return file_; }
    const std::string &path() const { return path_; }
    // "file:line:col" (1-based) of this node.
    std::string where() const;

    bool is_map() const { return node_.IsMap(); }
    bool is_sequence() const { return node_.IsSequence(); }
    bool is_scalar() const { return node_.IsScalar(); }
    bool has(std::string_view key) const;

    // Child by key. `require` throws if absent.
    Node require(std::string_view key) const;
    // Child by key, or an undefined node (check with defined()).
    Node get(std::string_view key) const;
    bool defined() const { return node_.IsDefined() && !node_.IsNull(); }
    Node at(std::size_t index) const;
    std::size_t size() const { return node_.size(); }
    // The keys of a map in file order (a key given twice is an error).
    std::vector<std::string> keys() const;
    // The keys with their values, in file order, in one pass over the map
    // (get() searches the whole map for each key).
    std::vector<std::pair<std::string, Node>> entries() const;

    // Scalars, with type errors naming the key and the expected type.
    double as_double() const;
    long long as_integer() const;
    bool as_bool() const;
    std::string as_string() const;
    std::vector<double> as_doubles() const;

    // Throws unless this is a map (or a sequence, or a scalar).
    void expect_map() const;
    void expect_sequence() const;
    // Throws at the first key not in `allowed`, with a "did you mean".
    void allow_keys(std::span<const std::string_view> allowed) const;

    // An Error whose message starts with where() and names path().
    [[noreturn]] void fail(const std::string &what) const;

  private:
    YAML::Node node_;
    std::string file_;
    std::string path_;
    YAML::Mark mark_;
};

// Load a file; syntax errors become talus::Error with file:line:column.
Node load_file(const std::string &path);
// The file's text (what load_file parses); throws talus::Error if it cannot
// be opened.
std::string read_text_file(const std::string &path);
// Load from text (tests, generated input); `name` stands in for the file.
Node load_string(const std::string &text, const std::string &name);

using talus::closest_match; // talus/text.hpp

} // namespace talus::yaml
