// What the solver passes a plugin beyond the 1.0 batch (ABI 1.1): the step,
// each particle's id, the characteristic length (the cell size), the
// increment's rotation, and the set-up call through init_state; and that a
// model declared not reentrant runs with two threads. The fixture
// fixture_abi11_c copies what it is given into its state.
#include "solver_helpers.hpp"

#include <talus/mpm/stress_rotation.hpp>

#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <string>

namespace {

std::string material(const std::string &extra = "") {
    return "plugins: ['" + talus::test::fixture("abi11_c").string() +
           "']\n"
           "materials:\n  m: {model: abi11_model, density: 1000, stiffness: 1.0e5, weights: [0.5, "
           "0.5], label: sandy, n_extra: 2, initial_state: {extra: [3, 4]}" +
           extra + "}\n";
}

double state_of(const talus::ParticleSet &s, std::size_t p, std::size_t k) {
    return s.state[s.state_size * p + k];
}

} // namespace

TEST(PluginContext, StepIdLengthAndSetUpReachTheModel) {
    const std::string yaml = "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: "
                             "0.1}\n" +
                             material() +
                             "groups:\n  a: {material: m, particles_per_cell: 2,\n"
                             "      shape: {box: {min: [0.2, 0.0], max: [0.8, 0.5]}}}\n"
                             "boundaries: {y-: fixed}\ngravity: [0, -9.81]\n"
                             "time: {end: 1}\n";
    const int before = omp_get_max_threads();
    omp_set_num_threads(2);
    auto s = talus::test::sim_from_text(yaml);
    // A compression wave from the floor crosses the block within these
    // steps, so every particle strains in the last one.
    constexpr long steps = 40;
    for (long k = 0; k < steps; ++k)
        s->sim->step(1.0); // the stable step (two threads: the calls overlap
                           // unless the host serialises them)
    omp_set_num_threads(before);
    const talus::ParticleSet &set = s->sim->sets().at(0);
    ASSERT_EQ(set.state_size, 7u); // 5 scalars + extra (n_extra = 2)
    ASSERT_GT(set.n, 0u);
    for (std::size_t p = 0; p < set.n; ++p) {
        ASSERT_EQ(state_of(set, p, 0), static_cast<double>(steps)) << "particle " << p;
        ASSERT_EQ(state_of(set, p, 1), static_cast<double>(set.id[p])) << "particle " << p;
        ASSERT_EQ(state_of(set, p, 2), 0.1) << "particle " << p;
        ASSERT_EQ(state_of(set, p, 4), 6.0) << "particle " << p; // init_state: 1 + strlen(sandy)
        ASSERT_EQ(state_of(set, p, 5), 3.0) << "particle " << p; // the YAML's initial_state
        ASSERT_EQ(state_of(set, p, 6), 4.0) << "particle " << p;
    }
}

// A disc in rigid rotation under APIC: the nodal velocities are the rigid
// field exactly (APIC transfers affine fields exactly) and so is every
// particle's velocity gradient, up to round-off. The rotation the model is
// given is then Hughes-Winget's for the spin w over dt: a rotation by theta
// with tan(theta / 2) = w dt / 2, whose Q[1][0] is sin(theta).
TEST(PluginContext, TheIncrementsRotationReachesTheModel) {
    const double w = 2.0;
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 2], cell: 0.1}\n" + material() +
        "groups:\n  a: {material: m, particles_per_cell: 2, angular_velocity: 2.0,\n"
        "      shape: {sphere: {center: [1, 1], radius: 0.5}}}\n"
        "solver: {transfer: apic}\ntime: {end: 1}\n";
    auto s = talus::test::sim_from_text(yaml);
    s->sim->step(1.0);
    const double dt = s->sim->last_dt();
    const double t = w * dt / 2.0;
    const double expected = 2.0 * t / (1.0 + t * t);
    const talus::ParticleSet &set = s->sim->sets().at(0);
    for (std::size_t p = 0; p < set.n; ++p)
        // The gradient is a sum over 9 nodes of velocities of order w r:
        // round-off of a few 1e-16 relative to w, far inside 1e-10.
        ASSERT_NEAR(state_of(set, p, 3), expected, 1e-10 * expected) << "particle " << p;
    // What talus_batch.rotation is defined to be, from the same spin.
    const double L[9] = {0, -w, 0, w, 0, 0, 0, 0, 0};
    double Q[9];
    talus::hughes_winget_rotation(L, dt, Q);
    EXPECT_NEAR(Q[3], expected, 1e-15);
    EXPECT_NEAR(Q[0] * Q[0] + Q[3] * Q[3], 1.0, 1e-15); // orthogonal
}

// ABI 1.2: the solver says its inputs are finite (TALUS_BATCH_INPUTS_FINITE)
// on every call of a step, and not on the set-up call. The fixture fails a
// call where that is not so, and checks the inputs it is told are finite.
// Two threads, a block that strains (gravity on a floor), both a fused and
// a split pipeline (USL; MUSL with its separate material update).
TEST(PluginContext, StepCallsSayTheirInputsAreFinite) {
    for (const char *scheme : {"usl", "musl"}) {
        SCOPED_TRACE(scheme);
        const std::string yaml =
            "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
            "plugins: ['" +
            talus::test::fixture("wants_finite").string() +
            "']\n"
            "materials:\n  m: {model: wants_finite, density: 1000, youngs_modulus: 1.0e6, "
            "poisson_ratio: 0.3}\n"
            "groups:\n  a: {material: m, particles_per_cell: 2,\n"
            "      shape: {box: {min: [0.2, 0.0], max: [0.8, 0.5]}}}\n"
            "boundaries: {y-: fixed}\ngravity: [0, -9.81]\n"
            "solver: {scheme: " +
            std::string(scheme) + "}\ntime: {end: 1}\n";
        const int before = omp_get_max_threads();
        omp_set_num_threads(2);
        auto s = talus::test::sim_from_text(yaml);
        for (int k = 0; k < 20; ++k)
            ASSERT_NO_THROW(s->sim->step(1.0));
        omp_set_num_threads(before);
    }
}
