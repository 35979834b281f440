// Functions of time given in YAML: a constant or a piecewise-linear table.
#pragma once

#include <talus/yaml_input.hpp>

#include <array>
#include <vector>

namespace talus {

// A piecewise-linear function of time through (t_i, v_i), constant beyond
// its ends. A single point is a constant.
class PiecewiseLinear {
  public:
    PiecewiseLinear() = default;
    explicit PiecewiseLinear(std::vector<std::array<double, 2>> points);
    double operator()(double t) const;
    // Reads a number (constant) or a sequence of [t, value] pairs with
    // strictly increasing t.
    static PiecewiseLinear read(const yaml::Node &node);

  private:
    std::vector<std::array<double, 2>> points_{{0.0, 0.0}};
};

} // namespace talus
