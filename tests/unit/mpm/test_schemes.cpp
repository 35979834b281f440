// The schemes (method/schemes.cpp) on a body in free fall, the one motion
// whose discrete trajectory each scheme gives in closed form: the stress
// stays zero (no velocity gradient), every node's acceleration is g, so
// after n steps of dt every particle has v = n dt g whatever the scheme and
// the transfer, and its displacement is the sum of the steps it was moved
// by (docs/theory.md, "Kinematic consistency"):
//   by v~ (USL, MUSL first order):  g dt^2 n (n + 1) / 2;
//   by v (USF):                     g dt^2 n (n - 1) / 2;
//   by (v + v~) / 2 (second order, USAVG): g dt^2 n^2 / 2 = g t^2 / 2.
// USL runs as the fused step, and with cell-averaged dilation as the split
// one. Each value is a sum of n = 100 steps of a few roundings each:
// 1e-12 m of a 0.2 m fall, and 1e-12 m/s of a 1.96 m/s velocity (a sum of
// as many increments g dt), bound it a hundred times over.
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <ostream>
#include <string>

namespace {

struct Scheme {
    std::string solver; // the solver: block's keys
    int kind;           // the displacement over g dt^2: n(n+1)/2, n(n-1)/2, n^2/2
};

void PrintTo(const Scheme &s, std::ostream *os) { *os << "{" << s.solver << "}"; }

class Schemes : public ::testing::TestWithParam<std::tuple<int, Scheme>> {};

TEST_P(Schemes, GiveTheirDiscreteFreeFall) {
    const auto [dim, scheme] = GetParam();
    const double dt = 0.002, g = -9.81;
    const std::string yaml =
        std::string("talus: 1\ndimension: ") + std::to_string(dim) + "\ngrid: {origin: [0, 0" +
        (dim == 3 ? ", 0" : "") + "], size: [2, 8" + (dim == 3 ? ", 2" : "") +
        "], cell: 0.1}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.25}\n"
        "groups:\n  block: {material: m, particles_per_cell: 2, shape: {box: {min: [0.5, 6.0" +
        (dim == 3 ? ", 0.5" : "") + "], max: [1.5, 7.0" + (dim == 3 ? ", 1.5" : "") +
        "]}}}\n"
        "gravity: [0, -9.81" +
        (dim == 3 ? ", 0" : "") + "]\nsolver: {dt: 0.002, " + scheme.solver + "}\ntime: {end: 1}\n";
    auto s = talus::test::sim_from_text(yaml);
    const talus::ParticleSet &ps = s->sim->sets()[0];
    std::vector<double> y0(ps.x[1].begin(), ps.x[1].end());
    const int n = 100;
    for (int k = 0; k < n; ++k)
        s->sim->step(dt);
    const double nn = n;
    const double factor = scheme.kind == 0   ? nn * (nn + 1) / 2
                          : scheme.kind == 1 ? nn * (nn - 1) / 2
                                             : nn * nn / 2;
    for (std::size_t p = 0; p < ps.n; ++p) {
        EXPECT_NEAR(ps.v[1][p], n * dt * g, 1e-12) << scheme.solver << ", particle " << p;
        EXPECT_NEAR(ps.v[0][p], 0.0, 1e-12) << scheme.solver << ", particle " << p;
        EXPECT_NEAR(ps.x[1][p] - y0[p], g * dt * dt * factor, 1e-12)
            << scheme.solver << ", particle " << p;
        if (::testing::Test::HasFailure()) return;
    }
}

INSTANTIATE_TEST_SUITE_P(
    All, Schemes,
    ::testing::Combine(::testing::Values(2, 3),
                       ::testing::Values(Scheme{"scheme: usl", 0},
                                         Scheme{"scheme: usl, cell_averaged_dilation: true", 0},
                                         Scheme{"scheme: usl, position_update: second_order", 2},
                                         Scheme{"scheme: usl, transfer: pic", 0},
                                         Scheme{"scheme: usl, transfer: apic", 0},
                                         Scheme{"scheme: usf", 1}, Scheme{"scheme: musl", 0},
                                         Scheme{"scheme: musl, position_update: second_order", 2},
                                         Scheme{"scheme: usavg", 2})));

} // namespace
