// Damping for quasi-static work: an elastic column under gravity, laterally
// confined by slip walls on a fixed base, released from zero stress, must
// come to rest at the geostatic stress: sigma_v = -rho g depth and, in
// uniaxial strain, sigma_h = K0 sigma_v with K0 = nu / (1 - nu) (both the
// in-plane and the out-of-plane horizontal stress in plane strain).
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace {

struct Column {
    double max_error_v = 0.0, max_error_h = 0.0, speed = 0.0;
    std::size_t checked = 0;
};

// H = 1 m of soil, 4 cells wide, cell 0.05 m, 2 particles per cell and
// direction; rho = 2000, E = 20 MPa, nu = 0.3.
Column settle(const std::string &damping, double end) {
    const double rho = 2000.0, g = 9.81, H = 1.0, nu = 0.3;
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [0.2, 1.2], cell: 0.05}\n"
        "materials:\n  soil: {model: linear_elastic, density: 2000, youngs_modulus: 2.0e7, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  column: {material: soil, shape: {box: {min: [0, 0], max: [0.2, 1.0]}}}\n"
        "boundaries: {x-: slip, x+: slip, y-: fixed}\ngravity: [0, -9.81]\n" +
        damping + "time: {end: 1}\n";
    auto s = talus::test::sim_from_text(yaml);
    talus::test::advance(*s->sim, end);
    const talus::ParticleSet &p = s->sim->sets().at(0);
    Column c;
    const double k0 = nu / (1.0 - nu);
    for (std::size_t i = 0; i < p.n; ++i) {
        c.speed = std::max(c.speed, std::hypot(p.v[0][i], p.v[1][i]));
        // The stress a particle carries is the weight of the soil above its
        // centre. Its depth is measured from its initial position (the
        // column shortens by sigma / E ~ 0.1 %, below the tolerance). The
        // particles within two cells of the free top and of the base are
        // left out: the quadratic B-spline stencil reaches 1.5 cells, so
        // their nodes lie partly outside the body, where the nodal balance
        // is that of a boundary layer, not of the continuum (there the
        // error grows to 2 % at 0.09 m below the top; below it is < 0.2 %).
        const double y0 = p.x0[1][i];
        const double depth = H - y0;
        if (depth < 2 * 0.05 || y0 < 2 * 0.05) continue;
        const double sv = -rho * g * depth;
        const double syy = p.stress[6 * i + 1];
        const double sxx = p.stress[6 * i + 0], szz = p.stress[6 * i + 2];
        c.max_error_v = std::max(c.max_error_v, std::abs(syy - sv) / std::abs(sv));
        c.max_error_h =
            std::max(c.max_error_h, std::max(std::abs(sxx - k0 * sv), std::abs(szz - k0 * sv)) /
                                        std::abs(k0 * sv));
        ++c.checked;
    }
    return c;
}

} // namespace

// Local (Cundall) damping 0.8 brings the column to rest within 1 s (about
// 40 transits of the P-wave, c = 116 m/s, over 2H): stresses within 1 %.
TEST(Damping, LocalDampingBringsAColumnToItsGeostaticStress) {
    const Column c = settle("damping: {type: local, coefficient: 0.8}\n", 1.0);
    EXPECT_GT(c.checked, 200u);
    EXPECT_LT(c.max_error_v, 0.01);
    EXPECT_LT(c.max_error_h, 0.01);
    EXPECT_LT(c.speed, 1e-4); // at rest: the oscillation was ~0.1 m/s
}

// Mass-proportional viscous damping, alpha = 2 zeta omega_1 with the first
// mode omega_1 = pi c / (2 H) ~ 183 rad/s and zeta ~ 0.5: the same state.
TEST(Damping, ViscousDampingBringsAColumnToItsGeostaticStress) {
    const Column c = settle("damping: {type: viscous, coefficient: 180}\n", 1.0);
    EXPECT_GT(c.checked, 200u);
    EXPECT_LT(c.max_error_v, 0.01);
    EXPECT_LT(c.max_error_h, 0.01);
    EXPECT_LT(c.speed, 1e-4);
}

// Without damping the column oscillates about that state: the test above
// fails without the damping it tests.
TEST(Damping, WithoutDampingTheColumnStillOscillates) {
    const Column c = settle("", 1.0);
    // Released from zero stress the undamped column swings about the
    // geostatic state with an amplitude of that state itself (a step load
    // doubles the static response): at t = 1 s the worst particle is off by
    // 105 % (measured), far above the 5 % asserted.
    EXPECT_GT(std::max(c.max_error_v, c.max_error_h), 0.05);
}
