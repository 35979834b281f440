#include <talus/mpm/spatial_field.hpp>

#include <talus/text.hpp>

#include <fmt/format.h>
#include <muParser.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <numbers>
#include <string_view>
#include <vector>

namespace talus {

namespace {

constexpr std::array<std::string_view, 3> kCoordinates = {"x", "y", "z"};

bool is_identifier(const std::string &s) {
    if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
    return std::all_of(s.begin(), s.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    });
}

} // namespace

struct SpatialField::Compiled {
    std::string text;
    mu::Parser parser;
    double x[3] = {0.0, 0.0, 0.0};
};

std::string SpatialField::check_constant_name(const std::string &name) {
    if (!is_identifier(name))
        return "a constant's name is a letter or '_' followed by letters, digits or '_'";
    if (std::find(kCoordinates.begin(), kCoordinates.end(), name) != kCoordinates.end() ||
        name == "pi")
        return fmt::format("'{}' is a coordinate or pi, which every expression knows", name);
    // muParser's own table of its functions, not a copy of it.
    static const mu::Parser defaults;
    if (defaults.GetFunDef().count(name) > 0)
        return fmt::format("'{}' is the name of a function", name);
    return {};
}

SpatialField SpatialField::expression(const std::string &text, int dim,
                                      std::span<const NamedConstant> constants) {
    auto c = std::make_shared<Compiled>();
    c->text = text;
    std::vector<std::string> known;
    try {
        for (int d = 0; d < dim; ++d) {
            const std::string name(kCoordinates[static_cast<std::size_t>(d)]);
            c->parser.DefineVar(name, &c->x[d]);
            known.push_back(name);
        }
        c->parser.DefineConst("pi", std::numbers::pi);
        known.emplace_back("pi");
        for (const NamedConstant &k : constants) {
            c->parser.DefineConst(k.name, k.value);
            known.push_back(k.name);
        }
        c->parser.SetExpr(text);
        // Parsing happens at the first evaluation: do it now, at the
        // origin, so that a mistake is found while reading.
        (void)c->parser.Eval();
    } catch (const mu::Parser::exception_type &e) {
        const std::size_t pos = e.GetPos() < 0 ? 0 : static_cast<std::size_t>(e.GetPos());
        if (e.GetCode() == mu::ecUNASSIGNABLE_TOKEN) {
            const std::string &token = e.GetToken();
            std::string list;
            for (const std::string &k : known)
                list += (list.empty() ? "" : ", ") + k;
            const std::string guess = closest_match(token, std::span<const std::string>(known));
            throw ExpressionError(
                fmt::format("unknown name '{}' in \"{}\"{} (names here: {}{})", token, text,
                            guess.empty() ? "" : fmt::format("; did you mean '{}'?", guess), list,
                            dim == 2 && token == "z" ? "; z is not a coordinate in 2D" : ""),
                pos);
        }
        std::string msg = e.GetMsg();
        // muParser ends its messages with " at position N." or a period;
        // the reader's location says where.
        for (const char *tail : {" at position", " at expression position"})
            if (const auto at = msg.find(tail); at != std::string::npos) msg.erase(at);
        while (!msg.empty() && (msg.back() == '.' || msg.back() == ' '))
            msg.pop_back();
        if (!msg.empty())
            msg[0] = static_cast<char>(std::tolower(static_cast<unsigned char>(msg[0])));
        throw ExpressionError(fmt::format("in the expression \"{}\": {}", text, msg), pos);
    }
    SpatialField f;
    f.compiled_ = std::move(c);
    return f;
}

const std::string &SpatialField::text() const {
    static const std::string none;
    return compiled_ ? compiled_->text : none;
}

double SpatialField::operator()(const double *x) const {
    if (!compiled_) return value_;
    std::copy_n(x, 3, compiled_->x);
    try {
        return compiled_->parser.Eval();
    } catch (const mu::Parser::exception_type &e) {
        throw ExpressionError(
            fmt::format("in the expression \"{}\": {}", compiled_->text, e.GetMsg()), 0);
    }
}

} // namespace talus
