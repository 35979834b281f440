// The parallel cycle is deterministic: P2G processes slabs of one colour at
// a time and each slab in memory order, so every node sums its
// contributions in the same order whatever the number of threads. Two
// threads must reproduce one thread bit for bit.
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>

#include <omp.h>

TEST(Threads, TwoThreadsReproduceOneBitForBit) {
    const std::string yaml =
        "talus: 1\ndimension: 3\ngrid: {origin: [0, 0, 0], size: [1.6, 1.6, 1.6], cell: 0.05}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, particles_per_cell: 2, velocity: [0.5, 0, -0.3],\n"
        "      shape: {sphere: {center: [0.8, 0.8, 0.6], radius: 0.4}}}\n"
        "boundaries: {z-: {friction: 0.3}}\ngravity: [0, 0, -9.81]\n"
        "solver: {transfer: {type: flip, alpha: 0.95}}\ntime: {end: 1}\n";
    auto run = [&](int threads) {
        auto s = talus::test::sim_from_text(yaml);
        omp_set_num_threads(threads);
        for (int k = 0; k < 40; ++k)
            s->sim->step(1.0); // crosses a re-sort (every 25)
        return s;
    };
    const int before = omp_get_max_threads();
    auto one = run(1);
    auto two = run(2);
    omp_set_num_threads(before);
    ASSERT_EQ(one->sim->sets()[0].n, two->sim->sets()[0].n);
    const auto &a = one->sim->sets()[0];
    const auto &b = two->sim->sets()[0];
    EXPECT_EQ(one->sim->time(), two->sim->time());
    for (int d = 0; d < 3; ++d) {
        EXPECT_EQ(a.x[static_cast<std::size_t>(d)], b.x[static_cast<std::size_t>(d)]);
        EXPECT_EQ(a.v[static_cast<std::size_t>(d)], b.v[static_cast<std::size_t>(d)]);
    }
    EXPECT_EQ(a.stress, b.stress);
    EXPECT_EQ(a.F, b.F);
}

// The transfer kernels' versions for each instruction set (isa.hpp) are one
// source compiled for different vector widths: they differ only in the
// rounding of fused multiply-adds and the order of a few sums, so their
// answers agree to round-off on a smooth (non-chaotic) run. Over 40 steps of
// an elastic sphere striking a rough floor (FLIP and APIC, which uses every
// lane of the kernels), the differences measured are 2e-16 m in position,
// 2.4e-15 of the largest velocity and 5e-16 of the largest stress; the
// bounds, 1e-13 of each field's scale, allow a few ulps per step
// accumulated over the steps and nothing like an error in a kernel.
TEST(Threads, EveryKernelInstructionSetGivesTheSameAnswer) {
    const std::string flip =
        "talus: 1\ndimension: 3\ngrid: {origin: [0, 0, 0], size: [1.6, 1.6, 1.6], cell: 0.05}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, particles_per_cell: 2, velocity: [0.5, 0, -0.3],\n"
        "      shape: {sphere: {center: [0.8, 0.8, 0.41], radius: 0.4}}}\n"
        "boundaries: {z-: {friction: 0.3}}\ngravity: [0, 0, -9.81]\n"
        "solver: {transfer: {type: flip, alpha: 0.95}}\ntime: {end: 1}\n";
    std::string apic = flip;
    apic.replace(apic.find("{type: flip, alpha: 0.95}"), 25, "apic");
    auto run = [](const std::string &yaml, const char *isa) {
        setenv("TALUS_KERNEL_ISA", isa, 1);
        auto s = talus::test::sim_from_text(yaml);
        unsetenv("TALUS_KERNEL_ISA");
        for (int k = 0; k < 40; ++k)
            s->sim->step(1.0);
        return s;
    };
    // Largest difference, and largest magnitude of the field in `a`.
    auto worst = [](const auto &a, const auto &b) {
        double diff = 0.0, scale = 0.0;
        for (std::size_t i = 0; i < a.size(); ++i) {
            diff = std::max(diff, std::abs(a[i] - b[i]));
            scale = std::max(scale, std::abs(a[i]));
        }
        return std::pair{diff, scale};
    };
    int compared = 0;
    for (const std::string *yaml : {&flip, static_cast<const std::string *>(&apic)}) {
        auto ref = run(*yaml, "generic");
        for (const char *isa : {"avx2", "avx512"}) {
            std::unique_ptr<talus::test::Sim> other;
            try {
                other = run(*yaml, isa);
            } catch (const talus::Error &) {
                continue; // this CPU or build has no such version
            }
            ++compared;
            const auto &a = ref->sim->sets()[0];
            const auto &b = other->sim->sets()[0];
            ASSERT_EQ(a.n, b.n);
            // Scales: the domain (1.6 m), the fastest velocity component,
            // the largest stress component (the impact's, ~1e4 Pa).
            double dx = 0.0, dv = 0.0, sv = 0.0;
            for (std::size_t d = 0; d < 3; ++d) {
                dx = std::max(dx, worst(a.x[d], b.x[d]).first);
                const auto [dvd, svd] = worst(a.v[d], b.v[d]);
                dv = std::max(dv, dvd);
                sv = std::max(sv, svd);
            }
            const auto [ds, ss] = worst(a.stress, b.stress);
            ASSERT_GT(ss, 1e3); // the sphere is loaded: the check has something to compare
            EXPECT_LE(dx, 1e-13 * 1.6) << isa << " position";
            EXPECT_LE(dv, 1e-13 * sv) << isa << " velocity";
            EXPECT_LE(ds, 1e-13 * ss) << isa << " stress";
        }
    }
    if (compared == 0) GTEST_SKIP() << "only the generic kernels on this machine";
}
