#include <talus/mpm/time_function.hpp>

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

} // namespace talus
