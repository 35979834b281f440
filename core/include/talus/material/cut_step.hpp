// How a host honours a plugin's request for a smaller step
// (TALUS_STATUS_CUT_STEP with a factor f in (0, 1), as a UMAT's PNEWDT): the
// one policy of the solver and the point driver. The increment is split
// into n = max(2, ceil(1 / f)) equal parts, each retried (and split again
// if need be), until a part would be smaller than kSmallestPart of the
// original increment: then the model, not the size of the step, is the
// problem, and the host stops with the model's message. f is floored at
// 1e-3 so that one request cannot ask for more than 1000 parts.
#pragma once

#include <algorithm>
#include <cmath>

namespace talus::cut_step {

inline constexpr double kSmallestPart = 1e-6;

// Parts to split an increment into, which is `fraction` of the original;
// 0 when the parts would be smaller than kSmallestPart of the original.
inline long parts(double factor, double fraction) {
    const double f = std::isfinite(factor) ? std::clamp(factor, 1e-3, 0.5) : 0.5;
    const long n = static_cast<long>(std::ceil(1.0 / f - 1e-9));
    return fraction / static_cast<double>(n) < kSmallestPart * (1.0 - 1e-9) ? 0 : n;
}

} // namespace talus::cut_step
