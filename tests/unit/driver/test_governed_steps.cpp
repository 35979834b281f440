// The run loop's governed steps (governed_steps.hpp): the thread count
// chosen between steps, outside Simulation::step.
#include "governed_steps.hpp"
#include "solver_helpers.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <sstream>

namespace {

const char *const kBlock =
    "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
    "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
    "poisson_ratio: 0.3}\n"
    "groups:\n  a: {material: m, particles_per_cell: 2,\n"
    "      shape: {box: {min: [0.2, 0.2], max: [0.8, 0.6]}}}\n"
    "boundaries: {y-: {friction: 0}}\ngravity: [0, -9.81]\ntime: {end: 1}\n";

// A governed run counts every step at the count it ran on and gives the
// process its threads back at the end, whatever count it finished on.
TEST(GovernedSteps, AccountForEveryStepAndGiveTheThreadsBack) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(2);
    {
        auto s = talus::test::sim_from_text(kBlock);
        talus::GovernedSteps steps(/*adapt=*/true, s->sim->comm());
        for (int k = 0; k < 300; ++k)
            steps.step(*s->sim, 1.0);
        EXPECT_EQ(s->sim->steps(), 300);
        ASSERT_EQ(steps.steps_at().size(), 3u); // counts 0, 1, 2
        EXPECT_EQ(steps.steps_at()[0], 0);
        EXPECT_EQ(steps.steps_at()[1] + steps.steps_at()[2], 300);
        // Force the last count to one: the destructor must restore two.
        omp_set_num_threads(1);
    }
    EXPECT_EQ(omp_get_max_threads(), 2);
    omp_set_num_threads(before);
}

// Not asked to, or with one thread only, nothing is governed: the steps
// are the Simulation's own, the count is left alone and nothing reported.
TEST(GovernedSteps, LeaveTheCountAloneWhenNotAsked) {
    const int before = omp_get_max_threads();
    for (const bool adapt : {false, true}) {
        omp_set_num_threads(adapt ? 1 : 2);
        auto s = talus::test::sim_from_text(kBlock);
        talus::GovernedSteps steps(adapt, s->sim->comm());
        for (int k = 0; k < 20; ++k)
            steps.step(*s->sim, 1.0);
        EXPECT_EQ(s->sim->steps(), 20);
        EXPECT_TRUE(steps.steps_at().empty()) << adapt;
        EXPECT_EQ(omp_get_max_threads(), adapt ? 1 : 2);
        std::ostringstream log;
        steps.report(log);
        EXPECT_EQ(log.str(), "");
    }
    omp_set_num_threads(before);
}

} // namespace
