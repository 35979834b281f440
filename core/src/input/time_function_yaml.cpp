#include <talus/input/time_function_yaml.hpp>

#include <fmt/format.h>

namespace talus {

PiecewiseLinear read_piecewise_linear(const yaml::Node &node) {
    if (node.is_scalar()) return PiecewiseLinear({{0.0, node.as_double()}});
    if (!node.is_sequence() || node.size() == 0)
        node.fail("expected a number or a non-empty sequence of [time, value] pairs");
    std::vector<std::array<double, 2>> pts;
    for (std::size_t i = 0; i < node.size(); ++i) {
        const yaml::Node p = node.at(i);
        const std::vector<double> tv = p.as_doubles();
        if (tv.size() != 2)
            p.fail(fmt::format("expected a [time, value] pair, got {} numbers", tv.size()));
        if (!pts.empty() && !(tv[0] > pts.back()[0]))
            p.fail(fmt::format("times must increase strictly: {:g} follows {:g}", tv[0],
                               pts.back()[0]));
        pts.push_back({tv[0], tv[1]});
    }
    return PiecewiseLinear(std::move(pts));
}

} // namespace talus
