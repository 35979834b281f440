#include <talus/time_function.hpp>

#include <fmt/format.h>

namespace talus {

PiecewiseLinear::PiecewiseLinear(std::vector<std::array<double, 2>> points)
    : points_(std::move(points)) {}

double PiecewiseLinear::operator()(double t) const {
    if (t <= points_.front()[0]) return points_.front()[1];
    if (t >= points_.back()[0]) return points_.back()[1];
    std::size_t i = 1;
    while (points_[i][0] < t)
        ++i;
    const auto &a = points_[i - 1];
    const auto &b = points_[i];
    const double w = (t - a[0]) / (b[0] - a[0]);
    return a[1] + w * (b[1] - a[1]);
}

PiecewiseLinear PiecewiseLinear::read(const yaml::Node &node) {
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
