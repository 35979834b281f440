// A quantity that may vary in space: a number, or an expression of the
// initial position (x, y in 2D; x, y, z in 3D), pi and the scenario's
// named constants, such as "v0*sin(pi*x/(2*L))". The expression is compiled
// when the scenario is read (so every error is found by `talus validate`)
// and evaluated once per particle when its group is created. The library
// is muParser (docs/scenario-reference.md, "Expressions"): its syntax, its
// functions (sin, cos, tan, asin, acos, atan, sinh, cosh, tanh, exp, ln,
// log10, log2, sqrt, abs, sign, rint, min, max, sum, avg), operators
// (+ - * / ^, comparisons, &&, ||, the ternary ?:).
#pragma once

#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

namespace talus {

struct NamedConstant {
    std::string name;
    double value = 0.0;
};

// A mistake in an expression: `position` is the offset of the offending
// character in the text (0-based), for the reader to locate it in its file.
struct ExpressionError : std::runtime_error {
    ExpressionError(const std::string &what, std::size_t pos)
        : std::runtime_error(what), position(pos) {}
    std::size_t position;
};

class SpatialField {
  public:
    SpatialField(double value = 0.0) : value_(value) {}
    // Throws ExpressionError for a syntax error or an unknown name (with a
    // "did you mean" among the names it knows).
    static SpatialField expression(const std::string &text, int dim,
                                   std::span<const NamedConstant> constants);
    // Empty when `name` may name a constant, else why not (a function's or
    // a coordinate's name, not an identifier).
    static std::string check_constant_name(const std::string &name);

    bool is_constant() const { return !compiled_; }
    double constant() const { return value_; }
    // The expression's text ("" for a number).
    const std::string &text() const;
    // The value at position x (3 components; z unused in 2D). Not
    // reentrant: a compiled
    // expression keeps its variables inside, so one thread evaluates it.
    double operator()(const double *x) const;

  private:
    struct Compiled;
    std::shared_ptr<Compiled> compiled_;
    double value_ = 0.0;
};

} // namespace talus
