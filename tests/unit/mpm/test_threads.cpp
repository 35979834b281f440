// The parallel cycle is deterministic: P2G processes slabs of one colour at
// a time and each slab in memory order, so every node sums its
// contributions in the same order whatever the number of threads. Two
// threads must reproduce one thread bit for bit.
#include "parallel/parallel.hpp"
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <omp.h>

#include <atomic>
#include <vector>

namespace {

// Two runs' particles, bit for bit.
void expect_same_particles(const talus::ParticleSet &a, const talus::ParticleSet &b, int dim) {
    ASSERT_EQ(a.n, b.n);
    for (std::size_t d = 0; d < static_cast<std::size_t>(dim); ++d) {
        EXPECT_EQ(a.x[d], b.x[d]);
        EXPECT_EQ(a.v[d], b.v[d]);
    }
    EXPECT_EQ(a.stress, b.stress);
    EXPECT_EQ(a.F, b.F);
    EXPECT_EQ(a.state, b.state);
}

} // namespace

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
    EXPECT_EQ(one->sim->time(), two->sim->time());
    expect_same_particles(one->sim->sets()[0], two->sim->sets()[0], 3);
}

// The plugin's batch (the material update's block of points) is also the
// block of the fused pass's step's end, whose partial results are filed by
// block: a batch size that does not divide the pass's chunks must give the
// same run as the default, bit for bit (each point's update does not
// depend on its batch, max(c + |v|) and the counts not on the blocks).
TEST(Threads, TheBatchSizeDoesNotChangeTheRun) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, particles_per_cell: 2, velocity: [0.8, -0.4],\n"
        "      shape: {sphere: {center: [0.6, 0.5], radius: 0.3}}}\n"
        "boundaries: {y-: {friction: 0.3}}\ngravity: [0, -9.81]\n"
        "solver: {transfer: {type: flip, alpha: 0.95}}\ntime: {end: 1}\n";
    const int before = omp_get_max_threads();
    omp_set_num_threads(2);
    auto run = [&](int batch) {
        auto s = talus::test::sim_from_text(yaml);
        talus::SolverOptions opt;
        opt.batch_size = batch;
        s->sim = std::make_unique<talus::Simulation>(s->scenario, opt);
        for (int k = 0; k < 40; ++k)
            s->sim->step(1.0); // crosses a re-sort (every 25)
        return s;
    };
    auto ref = run(128);
    for (const int batch : {100, 7, 1}) {
        auto other = run(batch);
        SCOPED_TRACE(testing::Message() << "batch " << batch);
        // Many blocks, and chunks that 100 and 7 do not divide.
        ASSERT_GT(ref->sim->sets()[0].n, 1000u);
        EXPECT_EQ(ref->sim->time(), other->sim->time());
        expect_same_particles(ref->sim->sets()[0], other->sim->sets()[0], 2);
    }
    omp_set_num_threads(before);
}

// The thread governor (RunOptions::adapt_threads) may change the count
// between any two steps: a run whose count changes every step, through
// the re-sort, must give the one-thread run's bits (per-thread scratch
// sized at the start must serve any count up to it).
TEST(Threads, ChangingTheCountBetweenStepsChangesNoBit) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
        "materials:\n  m: {model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3, friction_angle: 30, cohesion: 100}\n"
        "groups:\n  a: {material: m, particles_per_cell: 2, velocity: [0.8, -0.4],\n"
        "      shape: {sphere: {center: [0.6, 0.5], radius: 0.3}}}\n"
        "boundaries: {y-: {friction: 0.3}}\ngravity: [0, -9.81]\n"
        "solver: {transfer: {type: flip, alpha: 0.95}}\ntime: {end: 1}\n";
    const int before = omp_get_max_threads();
    auto run = [&](bool alternate) {
        omp_set_num_threads(alternate ? 2 : 1);
        auto s = talus::test::sim_from_text(yaml);
        for (int k = 0; k < 40; ++k) {
            if (alternate) omp_set_num_threads(k % 3 == 0 ? 1 : 2);
            s->sim->step(1.0); // crosses a re-sort (every 25)
        }
        return s;
    };
    auto one = run(false);
    auto mixed = run(true);
    omp_set_num_threads(before);
    EXPECT_EQ(one->sim->time(), mixed->sim->time());
    expect_same_particles(one->sim->sets()[0], mixed->sim->sets()[0], 2);
}

// The quiescence test's kinetic energy ratio (stages: `until`) is a sum
// over the particles: the same bits whatever the thread count, or a run
// whose governor changes the count (or a restart on another count) could
// end a stage a step apart, and report another ratio, from the same state.
TEST(Threads, TheKineticEnergyRatioIsTheSameWithEveryCount) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.02}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, particles_per_cell: 3, velocity: [0.8, -0.4],\n"
        "      shape: {sphere: {center: [0.6, 0.37], radius: 0.35}}}\n"
        "boundaries: {y-: {friction: 0.3}}\ngravity: [0, -9.81]\ntime: {end: 1}\n";
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    auto s = talus::test::sim_from_text(yaml);
    for (int k = 0; k < 300; ++k)
        s->sim->step(1.0); // into the impact: stresses and velocities of every size
    // Enough particles for several of the sum's chunks.
    ASSERT_GT(s->sim->sets()[0].n, 8000u);
    const double one = s->sim->kinetic_energy_ratio();
    ASSERT_GT(one, 0.0);
    ASSERT_LT(one, 1e6); // a strained body, not one at rest or stress-free
    for (const int threads : {2, 3}) {
        omp_set_num_threads(threads);
        EXPECT_EQ(s->sim->kinetic_energy_ratio(), one) << threads << " threads";
    }
    omp_set_num_threads(before);
}

// A thread count beyond kMaxThreads is refused before any parallel loop
// starts a team of them (100,000 threads crashed inside libgomp's team
// start), whether asked for in SolverOptions or by OMP_NUM_THREADS, whose
// value omp_set_num_threads stands in for here.
TEST(Threads, ACountBeyondTheLimitIsRefusedBeforeTheRun) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, particles_per_cell: 2,\n"
        "      shape: {box: {min: [0.2, 0.2], max: [0.8, 0.6]}}}\ntime: {end: 1}\n";
    const int before = omp_get_max_threads();
    auto s = talus::test::sim_from_text(yaml);
    talus::SolverOptions opt;
    opt.threads = talus::kMaxThreads + 1;
    try {
        talus::Simulation sim(s->scenario, opt);
        ADD_FAILURE() << "no error for " << opt.threads << " threads";
    } catch (const talus::Error &e) {
        EXPECT_NE(std::string(e.what()).find("threads asked for: at most 4096"), std::string::npos)
            << e.what();
    }
    EXPECT_EQ(omp_get_max_threads(), before); // nothing was set
    omp_set_num_threads(talus::kMaxThreads + 1);
    try {
        talus::Simulation sim(s->scenario, talus::SolverOptions{});
        ADD_FAILURE() << "no error for OpenMP's default of " << talus::kMaxThreads + 1;
    } catch (const talus::Error &e) {
        EXPECT_NE(std::string(e.what()).find("OMP_NUM_THREADS asks for 4097 threads"),
                  std::string::npos)
            << e.what();
    }
    omp_set_num_threads(before);
}

// The dynamic loops' shares (par::Shares): every item handed out exactly
// once, whether the team has as many threads as there are shares or fewer
// (the others' shares are then taken from their backs), for empty, tiny
// and uneven counts.
TEST(Threads, TheSharesHandOutEveryItemOnce) {
    for (const int shares : {1, 2, 3, 5})
        for (const int team : {1, 2})
            for (const std::uint64_t count : {0u, 1u, 2u, 7u, 1000u}) {
                SCOPED_TRACE(::testing::Message() << shares << " shares, a team of " << team << ", "
                                                  << count << " items");
                std::vector<std::atomic<int>> taken(count);
                talus::par::Shares s(count, shares);
#pragma omp parallel num_threads(team)
                if (omp_get_thread_num() < shares)
                    s.run(omp_get_thread_num(), [&](std::uint64_t item) {
                        ASSERT_LT(item, count);
                        ++taken[item];
                    });
                for (std::uint64_t k = 0; k < count; ++k)
                    EXPECT_EQ(taken[k].load(), 1) << "item " << k;
            }
}

// The fused pass's loop (par::for_each_chunk, dynamic): every element in
// exactly one chunk, each chunk starting at a multiple of the chunk size,
// with two threads.
TEST(Threads, ADynamicChunkLoopCoversEveryElementOnce) {
    const int before = talus::par::max_threads();
    talus::par::set_threads(2);
    for (const std::size_t n : {0u, 1u, 511u, 512u, 513u, 100000u}) {
        SCOPED_TRACE(::testing::Message() << n << " elements");
        std::vector<std::atomic<int>> seen(n);
        talus::par::for_each_chunk(
            n,
            [&](std::size_t begin, std::size_t end) {
                EXPECT_EQ(begin % 512, 0u);
                EXPECT_LE(end, n);
                for (std::size_t i = begin; i < end; ++i)
                    ++seen[i];
            },
            talus::par::Schedule::dynamic, 512);
        for (std::size_t i = 0; i < n; ++i)
            ASSERT_EQ(seen[i].load(), 1) << "element " << i;
    }
    talus::par::set_threads(before);
}
