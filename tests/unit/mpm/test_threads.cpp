// The parallel cycle is deterministic: P2G processes slabs of one colour at
// a time and each slab in memory order, so every node sums its
// contributions in the same order whatever the number of threads. Two
// threads must reproduce one thread bit for bit.
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

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
