// A function of time as the YAML gives it.
#pragma once

#include <talus/input/yaml_input.hpp>
#include <talus/mpm/time_function.hpp>

namespace talus {

// A number (a constant) or a sequence of [t, value] pairs with strictly
// increasing t.
PiecewiseLinear read_piecewise_linear(const yaml::Node &node);

} // namespace talus
