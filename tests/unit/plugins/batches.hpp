// Runs points through a model's update in batches of a chosen size, for the
// tests that a point's result does not depend on the batch it falls in or
// on an in-place update (the host's batches change with the block size and
// the particle count, and results must not).
#pragma once

#include <talus/material/plugin_loader.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <vector>

namespace talus::test {

// n points: stresses (6 each), states (state_size each), strain increments
// (6), densities and F (9, for F_start and F_end alike).
struct PointsIn {
    std::size_t n = 0, state_size = 0;
    std::vector<double> s0, q0, de, rho, F;
};

struct PointsOut {
    std::vector<double> s, q, c, D; // stress, state, wave speed, tangent (row-major)
};

// Points [0, n) in batches of `size`, asking for wave speeds and tangents;
// in place: the end arrays are the start arrays.
// `tangent`: whether each batch asks for the tangent (the solver's explicit
// steps do not; the point driver's implicit ones do).
inline PointsOut update_in_batches(const MaterialInstance &mi, const PointsIn &in, std::size_t size,
                                   bool in_place, bool tangent = true) {
    const std::size_t n = in.n, ns = in.state_size;
    PointsOut r{in.s0, in.q0, std::vector<double>(n), std::vector<double>(36 * n)};
    const std::vector<double> s_start = in.s0, q_start = in.q0;
    for (std::size_t b0 = 0; b0 < n; b0 += size) {
        talus_batch b{};
        b.flags = TALUS_BATCH_WANT_WAVE_SPEED | (tangent ? TALUS_BATCH_WANT_TANGENT : 0u);
        b.n_points = std::min(size, n - b0);
        b.dt = 1.0;
        b.step = 1;
        b.strain_increment = &in.de[6 * b0];
        b.F_start = &in.F[9 * b0];
        b.F_end = &in.F[9 * b0];
        b.density = &in.rho[b0];
        b.stress_start = in_place ? &r.s[6 * b0] : &s_start[6 * b0];
        b.stress_end = &r.s[6 * b0];
        if (ns > 0) {
            b.state_start = in_place ? &r.q[ns * b0] : &q_start[ns * b0];
            b.state_end = &r.q[ns * b0];
        }
        b.wave_speed = &r.c[b0];
        b.tangent = tangent ? &r.D[36 * b0] : nullptr;
        const auto res = mi.update(b);
        EXPECT_TRUE(res.ok()) << res.message;
    }
    return r;
}

} // namespace talus::test
