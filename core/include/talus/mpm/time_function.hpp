// Functions of time: a constant or a piecewise-linear table
// (input/time_function_yaml.hpp reads them).
#pragma once

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

  private:
    std::vector<std::array<double, 2>> points_{{0.0, 0.0}};
};

} // namespace talus
