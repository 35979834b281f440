// The shipped linear_elastic plugin against Hooke's law in closed form, in
// every batching the host may use. Its update runs as the SDK's quick pass
// over chunks of 64 points of the batch (the set-up call too: the model has
// no init_state, so the host's start is its update); a point's bits must
// not depend on the chunk it falls in or on an in-place update, or a run's
// result would depend on how its particles were grouped.
#include "batches.hpp"
#include "test_paths.hpp"

#include <talus/material/plugin_loader.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <span>
#include <vector>

namespace {

TEST(LinearElastic, HookesLawWithTheSameBitsInEveryBatching) {
    talus::PluginRegistry reg;
    const talus::Model &model =
        reg.load((talus::test::plugin_dir() / "talus_linear_elastic.so").string()).models()[0];
    const double E = 2.5e7, nu = 0.27;
    const std::vector<double> params{E, nu};
    const auto mi = model.create(std::span<const double>(params));
    const double G = E / (2.0 * (1.0 + nu)), lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));

    // 250 points: three full chunks of the quick pass (64 points) and a
    // partial one.
    const std::size_t n = 250;
    std::mt19937 gen(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> s0(6 * n), de(6 * n), rho(n), F(9 * n, 0.0);
    for (std::size_t k = 0; k < n; ++k) {
        for (std::size_t i = 0; i < 6; ++i) {
            s0[6 * k + i] = 1e5 * u(gen);
            de[6 * k + i] = 1e-4 * u(gen);
        }
        rho[k] = 1800.0 + 300.0 * u(gen);
        for (std::size_t i = 0; i < 3; ++i)
            F[9 * k + 4 * i] = 1.0;
    }
    const talus::test::PointsIn points{n, 0, s0, {}, de, rho, F};
    auto run = [&](std::size_t size, bool in_place) {
        return talus::test::update_in_batches(*mi, points, size, in_place);
    };
    const talus::test::PointsOut whole = run(n, false);
    // Hooke's law: sigma + lambda tr(de) I + 2 G de (tensor shear: G times
    // the engineering shear strain). The plugin's moduli and the reference's
    // are computed the same way; the update's few products and sums round
    // at 1e-16 of the stress, so 1e-15 of its 1e5 scale is a bound with room.
    for (std::size_t k = 0; k < n; ++k) {
        const double *d = &de[6 * k];
        const double tr = d[0] + d[1] + d[2];
        for (std::size_t i = 0; i < 6; ++i) {
            const double ref = s0[6 * k + i] + (i < 3 ? lambda * tr + 2.0 * G * d[i] : G * d[i]);
            EXPECT_NEAR(whole.s[6 * k + i], ref, 1e-15 * 1e5) << k << " " << i;
        }
        for (std::size_t i = 0; i < 6; ++i)
            for (std::size_t j = 0; j < 6; ++j) {
                const double ref =
                    i < 3 && j < 3 ? lambda + (i == j ? 2.0 * G : 0.0) : (i == j ? G : 0.0);
                EXPECT_NEAR(whole.D[36 * k + 6 * i + j], ref, 1e-15 * E) << k << " " << i << j;
            }
        // The P-wave speed sqrt((K + 4G/3) / rho): a division and a square
        // root, each correctly rounded, of a modulus rounded a few times: a
        // few ulps (2.2e-16 each).
        EXPECT_NEAR(whole.c[k], std::sqrt((lambda + 2.0 * G) / rho[k]), 1e-15 * whole.c[k]);
    }
    // Every batching, and in place, gives the same bits (== on every
    // double; a NaN would fail, as it should). Batches of 1 and 7 leave the
    // wave speeds' pairs an odd point; 64 is the SDK's chunk.
    for (const auto &[size, in_place] :
         {std::pair<std::size_t, bool>{1, false}, {7, false}, {64, false}, {n, true}, {7, true}}) {
        SCOPED_TRACE(testing::Message() << "batches of " << size << (in_place ? ", in place" : ""));
        const talus::test::PointsOut other = run(size, in_place);
        EXPECT_EQ(other.s, whole.s);
        EXPECT_EQ(other.c, whole.c);
        EXPECT_EQ(other.D, whole.D);
    }
}

} // namespace
