// The solver against references no one here wrote (tests/data/README.md):
// the vibrating bar's closed form, the single-point oscillator's closed form,
// and a peer code's two-disk energies.
#include "solver_helpers.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

using talus::test::advance;
using talus::test::data_dir;
using talus::test::read_numeric_csv;
using talus::test::sim_from_config;
using talus::test::totals;

namespace {

// Times where a sampled signal crosses zero (linear interpolation).
std::vector<double> zero_crossings(const std::vector<double> &t, const std::vector<double> &v) {
    std::vector<double> z;
    for (std::size_t i = 1; i < v.size(); ++i)
        if ((v[i - 1] > 0.0 && v[i] <= 0.0) || (v[i - 1] < 0.0 && v[i] >= 0.0))
            z.push_back(t[i - 1] + (t[i] - t[i - 1]) * v[i - 1] / (v[i - 1] - v[i]));
    return z;
}

struct Oscillation {
    double period = 0.0, amplitude = 0.0;
};

Oscillation measure(const std::vector<double> &t, const std::vector<double> &v) {
    const std::vector<double> z = zero_crossings(t, v);
    Oscillation o;
    if (z.size() >= 2) o.period = 2.0 * (z.back() - z.front()) / static_cast<double>(z.size() - 1);
    for (double x : v)
        o.amplitude = std::max(o.amplitude, std::abs(x));
    return o;
}

Oscillation bar_reference() {
    const auto ref = read_numeric_csv(data_dir() / "bar1d_continuum_L25_E100_rho1.csv");
    std::vector<double> t, v;
    for (const auto &r : ref) {
        t.push_back(r[0]);
        v.push_back(r[1]);
    }
    return measure(t, v);
}

// The bar's centre-of-mass velocity over two periods (20 s), sampled every
// 0.05 s.
Oscillation centre_of_mass_oscillation(talus::Simulation &sim) {
    std::vector<double> t, v;
    for (double target = 0.0; target <= 20.0 + 1e-9; target += 0.05) {
        advance(sim, target);
        const auto tot = totals(sim);
        t.push_back(sim.time());
        v.push_back(tot.p[0] / tot.mass);
    }
    return measure(t, v);
}

// The bar of configs/verification/bar_vibration.yaml under a scheme and transfer.
Oscillation run_bar(const std::string &scheme, const std::string &transfer = "flip") {
    auto s = talus::test::make_sim([&] {
        std::ifstream in(talus::test::source_dir() / "configs/verification/bar_vibration.yaml");
        std::stringstream ss;
        ss << in.rdbuf();
        std::string text = ss.str();
        const auto at = text.find("scheme: musl");
        text.replace(at, 12, "scheme: " + scheme);
        const auto tr = text.find("transfer: flip");
        text.replace(tr, 14, "transfer: " + transfer);
        return talus::yaml::load_string(text, "bar_vibration.yaml");
    }());
    return centre_of_mass_oscillation(*s->sim);
}

} // namespace

// First mode of the fixed-free bar (13 cells, linear shape functions). The
// semi-discrete frequency of 13 lumped-mass elements is higher than the
// continuum's by (k h)^2 / 24 ~ 6e-4 and the explicit integration and the
// one-point quadrature move it by a few 1e-3 more: the 0.5 % on the
// period and 1 % on the amplitude of v_cm are the bounds.
TEST(Verification, BarVibrationPeriodAndAmplitudeEveryScheme) {
    const Oscillation ref = bar_reference();
    ASSERT_NEAR(ref.period, 10.0, 0.01);          // the file is the closed form
    ASSERT_NEAR(ref.amplitude, 0.2 / M_PI, 1e-7); // v_cm(0) = 0.1 * 2 / pi
    for (const char *scheme : {"musl", "usl", "usf", "usavg"}) {
        const Oscillation o = run_bar(scheme);
        EXPECT_NEAR(o.period, ref.period, 0.005 * ref.period) << scheme;
        EXPECT_NEAR(o.amplitude, ref.amplitude, 0.01 * ref.amplitude) << scheme;
    }
    // The affine transfers (PIC plus an affine field: APIC's C = B D^-1, the
    // Taylor transfer's C = grad v) on the same bar, USL: same bounds.
    for (const char *transfer : {"apic", "tpic"}) {
        const Oscillation o = run_bar("usl", transfer);
        EXPECT_NEAR(o.period, ref.period, 0.005 * ref.period) << transfer;
        EXPECT_NEAR(o.amplitude, ref.amplitude, 0.01 * ref.amplitude) << transfer;
    }
}

// One point in one cell, MUSL (symplectic for this system: the strain comes
// from the remapped, updated velocity). The exact solution is continuous in
// time; the explicit update lags it by half a step, 0.1 * omega dt / 2 =
// 3.1e-3 in v and 0.016 * 0.031 = 5e-4 in x, and the period error
// (omega dt)^2 / 24 adds 1e-3 over 10 periods: 4e-3 in v and 2e-3 in x
// bound the difference for the whole run.
TEST(Verification, SinglePointOscillatorFollowsTheExactSolution) {
    auto s = sim_from_config("configs/verification/single_point_oscillator.yaml");
    s->scenario.solver.scheme = talus::Scheme::musl;
    s->sim = std::make_unique<talus::Simulation>(s->scenario);
    const auto ref = read_numeric_csv(data_dir() / "bar1d_single_point_E4pi2.csv");
    ASSERT_GT(ref.size(), 1000u);
    double ev = 0.0, ex = 0.0;
    for (std::size_t k = 1; k <= 1000; ++k) {
        advance(*s->sim, ref[k][0]);
        const talus::ParticleSet &p = s->sim->sets()[0];
        ev = std::max(ev, std::abs(p.v[0][0] - ref[k][1]));
        ex = std::max(ex, std::abs(p.x[0][0] - ref[k][2]));
    }
    EXPECT_LT(ev, 4e-3);
    EXPECT_LT(ex, 2e-3);
}

// USL on the same system is not symplectic: with the left node fixed, one
// step maps (v, sigma) by [[1, -dt/m], [E dt, 1 - 2 E dt^2 / m]] (V = 1,
// L = 1), of determinant 1 - omega^2 dt^2, so the energy shrinks by that
// factor per step and the velocity amplitude at step n is
// 0.1 (1 - omega^2 dt^2)^(n/2). The check is of the scheme's known
// dissipation, at the last velocity peak, to 3 % (the volume update J and
// the peak read at whole steps).
TEST(Verification, SinglePointUslLosesEnergyAsTheTheoryPredicts) {
    auto s = sim_from_config("configs/verification/single_point_oscillator.yaml");
    const double w2dt2 = 4.0 * M_PI * M_PI * 1e-4;
    double peak = 0.0;
    long peak_step = 0;
    advance(*s->sim, 9.0);
    advance(*s->sim, 10.0, [&] {
        const double v = std::abs(s->sim->sets()[0].v[0][0]);
        if (v > peak) {
            peak = v;
            peak_step = s->sim->steps();
        }
    });
    const double predicted = 0.1 * std::pow(1.0 - w2dt2, 0.5 * static_cast<double>(peak_step));
    EXPECT_NEAR(peak, predicted, 0.03 * predicted);
}

// Two elastic disks (Sulsky et al. 1994) against a peer MPM code run with the
// same set-up (USL, FLIP, linear shape functions).
TEST(Verification, TwoDisksAgainstThePeer) {
    auto s = sim_from_config("configs/verification/two_disks.yaml");
    const auto ref = read_numeric_csv(data_dir() / "two_disks_energy_nguyen_mpmat_usl.csv");
    // Initial kinetic energy is sum m v^2 / 2: every particle has |v|^2 = 0.02.
    const auto t0 = totals(*s->sim);
    EXPECT_NEAR(t0.ke, 0.5 * t0.mass * 0.02, 1e-14 * t0.ke);
    EXPECT_NEAR(t0.ke, ref[0][1], 1e-12 * ref[0][1]); // same particle count as the peer: 416
    double ke_min = 1e300, t_min = 0.0, worst_p = 0.0;
    // This run too may blow up after the collision (see the end energy
    // below); what it saw until then is checked.
    bool blew_up = false;
    try {
        advance(*s->sim, 3.0, [&] {
            const auto t = totals(*s->sim);
            if (t.ke < ke_min) {
                ke_min = t.ke;
                t_min = s->sim->time();
            }
            worst_p = std::max({worst_p, std::abs(t.p[0]), std::abs(t.p[1])});
        });
    } catch (const talus::Error &) {
        blew_up = true;
    }
    // Momentum is zero to round-off: the disks' momenta cancel and internal
    // forces sum to zero; 1e-12 of one disk's momentum (13) is round-off.
    EXPECT_LT(worst_p, 1e-12 * 13.0);
    double ref_min = 1e300, ref_tmin = 0.0;
    for (const auto &r : ref)
        if (r[1] < ref_min) {
            ref_min = r[1];
            ref_tmin = r[0];
        }
    // The kinetic-energy minimum of the collision: value within 5 % and time
    // within 0.03 s (30 steps). The contact with linear shape functions
    // amplifies round-off (runs differing in the last bit before contact
    // differ by 1e-4 after it), so the two codes agree to about 1 %, not
    // better; 5 % leaves room for that chaos and nothing more.
    EXPECT_NEAR(ke_min, ref_min, 0.05 * ref_min);
    EXPECT_NEAR(t_min, ref_tmin, 0.03);
    // End-of-run total energy. The peer ends 3.0 % below the start. After
    // the collision the energy is chaotic: runs whose dt differs by 1e-12
    // relative, or whose sums are merely reordered or fused (FMA), end
    // 0.05 % to 17 % from the peer, some above the start energy, and with
    // FMA 2 of 9 such runs blow up (a particle inverts near t = 2.8 s: the
    // cell-crossing instability of linear shape functions as the disks
    // separate). The two codes' energies are also 6 % apart at t = 2.0 s
    // (the peer loses more in the collision), so the 1 % agreement at the
    // end that this test once asserted for a single run was chance. What
    // holds for the median of an ensemble of nine such runs (a blown-up run
    // counted as the worst outcome, +inf, not dropped) is that the energy
    // decreases, as the peer's, and ends within 5 % of the peer's (the
    // tolerance of the collision's minimum above; measured 0.2-1.1 %).
    const auto end_total = [](const talus::Simulation &sim) {
        const talus::Diagnostics d = sim.diagnostics();
        return d.kinetic_energy + d.stress_work;
    };
    std::vector<double> ends;
    ends.push_back(blew_up ? std::numeric_limits<double>::infinity() : end_total(*s->sim));
    for (int k = 1; k <= 8; ++k) {
        auto e = sim_from_config("configs/verification/two_disks.yaml", [k](talus::Scenario &sc) {
            sc.solver.dt = 0.001 * (1.0 + 1e-12 * k);
        });
        try {
            advance(*e->sim, 3.0);
            ends.push_back(end_total(*e->sim));
        } catch (const talus::Error &) {
            ends.push_back(std::numeric_limits<double>::infinity());
        }
    }
    std::nth_element(ends.begin(), ends.begin() + 4, ends.end());
    const double median = ends[4];
    EXPECT_NEAR(median, ref.back()[3], 0.05 * ref.back()[3]);
    EXPECT_LT(median, ref[0][3]);
}

namespace {

// The fixed-free bar of the test above (L = 25, E = 100, rho = 1, first mode
// v = 0.1 sin(pi x / 2L), closed-form period 4L/c = 10 s) on n cells with
// the given kernel, 2 x 2 particles per cell, USL, dt = 0.1 h / c: a strip
// one cell high between roller faces, in a grid two cells longer than the
// bar (its free end moves 0.16 m). Returns the measured period.
double bar_period(int n, const std::string &shape) {
    const double L = 25.0, h = L / n;
    auto s = talus::test::sim_from_text(fmt::format(
        "talus: 1\ndimension: 2\ngrid: {{origin: [0, 0], size: [{G}, {h}], cell: {h}}}\n"
        "materials:\n  bar: {{model: linear_elastic, density: 1, youngs_modulus: 100, "
        "poisson_ratio: 0}}\n"
        "groups:\n  bar: {{material: bar, shape: {{box: {{min: [0, 0], max: [{L}, {h}]}}}}}}\n"
        "boundaries: {{x-: fixed, y-: roller, y+: roller}}\n"
        "solver: {{shape: {shape}, dt: {dt}}}\ntime: {{end: 20}}\n",
        fmt::arg("L", L), fmt::arg("G", L + 2 * h), fmt::arg("h", h), fmt::arg("shape", shape),
        fmt::arg("dt", 0.01 * h)));
    for (auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p)
            set.v[0][p] = 0.1 * std::sin(M_PI * set.x[0][p] / (2.0 * L));
    return centre_of_mass_oscillation(*s->sim).period;
}

} // namespace

// The default kernel (quadratic B-spline) is clamped at the faces, so the
// fixed end is at x = 0 and the bar converges at second order in h: the
// period error falls by about 4 each time h halves. (With the uniform
// B-spline and the face nodes fixed, the clamp acted a third of a cell
// inside the domain and the error was first order: 2.7 % at 13 cells, 1.3 %
// at 26.)
//
// Measured: quadratic 0.36 %, 0.095 %, 0.024 % (orders 1.9, 2.0); cubic 0.56
// %, 0.17 %, 0.054 % (orders 1.7, 1.7). The bounds: an observed order of at
// least 1.5 at each refinement (first order gives 1.0; 1.5 leaves room for
// the pre-asymptotic coarse grid and nothing for first order), and under 1
// % at 13 cells (the uniform kernel's 2.7 % fails it).
TEST(Verification, BarConvergesAtSecondOrderWithBSplines) {
    for (const char *shape : {"bspline2", "bspline3"}) {
        std::vector<double> err;
        for (int n : {13, 26, 52})
            err.push_back(std::abs(bar_period(n, shape) - 10.0) / 10.0);
        EXPECT_LT(err[0], 0.01) << shape;
        EXPECT_GT(std::log2(err[0] / err[1]), 1.5) << shape;
        EXPECT_GT(std::log2(err[1] / err[2]), 1.5) << shape;
    }
}

// A cantilever clamped by the fixed face x = 0 under its own weight, small
// deflection (linear elastic, E = 1e8 Pa, nu = 0.3, rho = 1000, L = 0.5 m,
// t = 0.1 m, plane strain): gravity is applied at t = 0 and nothing damps,
// so the tip oscillates about the static deflection; its mean over one
// period of the first mode is that deflection. Timoshenko beam theory:
// w = q L^4 / (8 E' I) + q L^2 / (2 k G A), q = rho g t, E' = E / (1 - nu^2),
// I = t^3 / 12, A = t, k = 5/6. h = t/4, 2 x 2 particles per cell.
TEST(Verification, CantileverIsClampedAtTheFace) {
    const double E = 1e8, nu = 0.3, rho = 1000, g = 9.81, L = 0.5, t = 0.1;
    const double Ep = E / (1 - nu * nu), G = E / (2 * (1 + nu)), I = t * t * t / 12,
                 q = rho * g * t;
    const double w = q * std::pow(L, 4) / (8 * Ep * I) + q * L * L / (2 * 5.0 / 6.0 * G * t);
    // First bending mode, Euler-Bernoulli: omega = 1.8751^2 sqrt(E' I / (rho A L^4)).
    const double T1 = 2 * M_PI / (1.8751 * 1.8751 * std::sqrt(Ep * I / (rho * t * std::pow(L, 4))));
    for (const char *shape : {"bspline2", "bspline3", "linear"}) {
        SCOPED_TRACE(shape);
        auto s = talus::test::sim_from_text(fmt::format(
            "talus: 1\ndimension: 2\ngrid: {{origin: [0, 0], size: [1.0, 0.5], cell: 0.025}}\n"
            "materials:\n  m: {{model: linear_elastic, density: {rho}, youngs_modulus: {E}, "
            "poisson_ratio: {nu}}}\n"
            "groups:\n  beam: {{material: m, shape: {{box: {{min: [0, 0.2], max: [{L}, "
            "0.3]}}}}}}\n"
            "boundaries: {{x-: fixed}}\ngravity: [0, -{g}]\n"
            "solver: {{shape: {shape}, scheme: {scheme}}}\ntime: {{end: 1}}\n",
            fmt::arg("rho", rho), fmt::arg("E", E), fmt::arg("nu", nu), fmt::arg("L", L),
            fmt::arg("g", g), fmt::arg("shape", shape),
            fmt::arg("scheme", std::string(shape) == "linear" ? "musl" : "usl")));
        // The tip: the particles of the last column (x = L - h/4).
        double sum = 0.0, time = 0.0, root = 0.0;
        while (s->sim->time() < T1) {
            s->sim->step(T1 - s->sim->time());
            double u = 0.0;
            int k = 0;
            for (const auto &set : s->sim->sets())
                for (std::size_t p = 0; p < set.n; ++p) {
                    if (set.x0[0][p] > L - 0.025 / 2) {
                        u += set.x[1][p] - set.x0[1][p];
                        ++k;
                    }
                    if (set.x0[0][p] < 0.025 / 2)
                        root = std::max(root, std::abs(set.x[1][p] - set.x0[1][p]));
                }
            sum += s->sim->last_dt() * u / k;
            time += s->sim->last_dt();
        }
        // Measured +4.9 % (quadratic), +4.8 % (cubic), -1.8 % (linear).
        // Beam theory leaves out the clamp's own flexibility (the root
        // section warps and the wall region strains), a few percent at L/t
        // = 5, and 2 x 2 particles per cell add their share: 7 % bounds it.
        // The uniform B-splines, clamping a third of a cell outside the
        // face, gave +13 % and +17 %.
        EXPECT_NEAR(-sum / time, w, 0.07 * w);
        // The root column (x = h/4) barely moves: under 2 % of the tip.
        EXPECT_LT(root, 0.02 * w);
    }
}

namespace {

// Tip deflection of Euler's elastica: a cantilever of length L clamped at
// s = 0, carrying a vertical dead load P at s = L, bends as
// theta'' = -(P / EI) cos(theta), theta(0) = 0, theta'(L) = 0 (the moment
// vanishes at the tip); the deflection is the integral of sin(theta).
// Shooting on theta'(0) by bisection with RK4 (2000 steps: the solution is
// smooth, the error ~1e-13). For P L^2 / EI = 2 it gives 0.49346 L, the
// value tabulated by Bisshopp & Drucker (1945), checked below.
double elastica_tip_deflection(double P_over_EI, double L) {
    const int n = 2000;
    const double ds = L / n;
    auto shoot = [&](double k0, double &deflection) {
        double th = 0.0, k = k0, w = 0.0;
        auto rhs = [&](double a, double b, double out[3]) {
            out[0] = b;
            out[1] = -P_over_EI * std::cos(a);
            out[2] = std::sin(a);
        };
        for (int i = 0; i < n; ++i) {
            double k1[3], k2[3], k3[3], k4[3];
            rhs(th, k, k1);
            rhs(th + 0.5 * ds * k1[0], k + 0.5 * ds * k1[1], k2);
            rhs(th + 0.5 * ds * k2[0], k + 0.5 * ds * k2[1], k3);
            rhs(th + ds * k3[0], k + ds * k3[1], k4);
            th += ds / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]);
            k += ds / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]);
            w += ds / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]);
        }
        deflection = w;
        return k; // theta'(L)
    };
    // theta'(0) = P x_tip / EI lies in [0, P L / EI]; theta'(L) rises with it.
    double lo = 0.0, hi = P_over_EI * L, w = 0.0;
    for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        (shoot(mid, w) < 0.0 ? lo : hi) = mid;
    }
    shoot(0.5 * (lo + hi), w);
    return w;
}

} // namespace

TEST(Verification, ElasticaMatchesTheTabulatedValue) {
    // Bisshopp & Drucker (1945), Table 1: P L^2 / EI = 2 -> 0.4935 L (4 digits).
    EXPECT_NEAR(elastica_tip_deflection(2.0, 1.0), 0.4935, 1e-4);
    // Small loads: the linear cantilever, P L^3 / (3 EI). The elastica
    // differs from it by -1.0e-9 here (the rotation's own stiffening, of
    // relative order alpha^2; computed independently); 1e-8 allows that
    // and fails a solver off by 1 % of the deflection.
    EXPECT_NEAR(elastica_tip_deflection(0.003, 1.0), 0.001, 1e-8);
}

// A load held on a cantilever through large rotations, under every scheme
// (issue 6 point 14). USF and MUSL used to advance F with one grid velocity
// field and move the particles with another (the updated one, v~): under a
// held load the two drifted apart and the beam crept without end (tip
// deflection 0.49, 0.57, 0.71, 0.90 m over successive 4 s windows of a
// similar beam clamped by a particle fixity, USF and PIC, while USL settled
// at 0.49). Now every
// scheme moves its particles with the field that advances their F
// (docs/theory.md, "Kinematic consistency").
//
// The beam: L = 1 m, t = 0.1 m, h = t/3, 3 x 3 particles per cell (2 x 2
// leaves a bent beam a few percent too flexible: docs/scenario-reference.md),
// neo_hookean (E = 1 MPa, nu = 0), clamped at a `fixed` face, a dead load
// PL^2/EI = 2 on its last particle column from t = 0. PIC damps the motion,
// so the beam comes to rest at the discrete equilibrium.
// One test per scheme, so that ctest runs them side by side.
class HeldTipLoad : public ::testing::TestWithParam<const char *> {};

TEST_P(HeldTipLoad, SettlesUnderTheScheme) {
    const double E = 1e6, t = 0.1, L = 1.0, h = t / 3, EI = E * t * t * t / 12;
    const double P = 2.0 * EI / (L * L); // per unit depth
    const double x_load = L - h / 6;     // the last particle column
    const int across = 9;                // its particles
    const double reference = elastica_tip_deflection(P / EI, x_load);
    {
        const char *scheme = GetParam();
        auto s = talus::test::sim_from_text(fmt::format(
            "talus: 1\ndimension: 2\ngrid: {{origin: [0, 0], size: [1.2, 1.2], cell: {h}}}\n"
            "materials:\n  m: {{model: neo_hookean, density: 1000, youngs_modulus: {E}, "
            "poisson_ratio: 0}}\n"
            "groups:\n  beam: {{material: m, particles_per_cell: 3, shape: {{box: {{min: [0, "
            "1.0], max: [{L}, 1.1]}}}}}}\n"
            "boundaries: {{x-: fixed}}\n"
            "loads:\n  - {{group: beam, box: {{min: [{xl}, 0], max: [2, 2]}}, point: [0, "
            "-{f}]}}\n"
            "solver: {{scheme: {scheme}, transfer: pic}}\ntime: {{end: 12}}\n",
            fmt::arg("h", h), fmt::arg("E", E), fmt::arg("L", L), fmt::arg("xl", x_load - h / 12),
            fmt::arg("f", P / across), fmt::arg("scheme", scheme)));
        // Mean over [8, 10] and [10, 12] s (about 4 periods of the first
        // mode each, which PIC has damped by then) of the last column's mean
        // deflection (found by x0 at every step: the solver reorders
        // particles in memory).
        double sum[2] = {0, 0}, span[2] = {0, 0};
        while (s->sim->time() < 12.0 * (1 - 1e-12)) {
            s->sim->step(12.0 - s->sim->time());
            const double now = s->sim->time(), dt = s->sim->last_dt();
            if (now <= 8.0) continue;
            double u = 0.0;
            int n = 0;
            for (const auto &set : s->sim->sets())
                for (std::size_t p = 0; p < set.n; ++p)
                    if (set.x0[0][p] > x_load - h / 12) {
                        u += set.x0[1][p] - set.x[1][p];
                        ++n;
                    }
            ASSERT_EQ(n, across);
            const int k = now <= 10.0 ? 0 : 1;
            sum[k] += dt * u / n;
            span[k] += dt;
        }
        const double early = sum[0] / span[0], late = sum[1] / span[1];
        // At rest where the elastica puts it: measured +2.3 % (USL, USAVG)
        // and +1.3 % (USF, MUSL). Left out of the reference: shear,
        // 3 EI / (k G A x^2) = +0.6 % at L/t = 10 (Timoshenko); the particle
        // quadrature, +0.8 % at 3 x 3 against 4 x 4 per cell (USL, measured);
        // the grid at h = t/3, about +0.5 % (4 x 4 less shear). 3 % bounds
        // their sum.
        EXPECT_NEAR(late, reference, 0.03 * reference);
        // And it stays there: the change over the last 2 s is under 1 % of
        // the deflection (measured 0.0013 m for USF and MUSL, still closing
        // in on their equilibrium; 1e-5 m for USL). Before the fix, USF and
        // MUSL moved 0.044 m over those 2 s and were 15 % past the elastica.
        EXPECT_LT(std::abs(late - early), 0.01 * reference);
    }
}

INSTANTIATE_TEST_SUITE_P(Verification, HeldTipLoad,
                         ::testing::Values("usl", "usf", "musl", "usavg"),
                         [](const ::testing::TestParamInfo<const char *> &param) {
                             return std::string(param.param);
                         });

// The CPDI paper's large-deformation benchmark (Sadeghirad, Brannon &
// Burghardt 2011): a 4 m x 1 m Neo-Hookean cantilever released under its own
// weight, against an updated-Lagrangian FEM run (V. P. Nguyen's MPM/FEM
// MATLAB codes; two meshes, tests/data/cantilever_selfweight_fem_ul_*.csv).
// The FEM records the point (3.93, 0.07) of the beam (a Gauss point of the
// last element of the bottom row), so the particle compared is the one
// there, not the tip's axis, whose sag is 0.4 m larger at the peak.
TEST(Verification, CantileverUnderSelfWeightFollowsTheFiniteElementRun) {
    auto s = talus::test::sim_from_config("configs/verification/cantilever_self_weight.yaml");
    // The particle whose start point is nearest (3.93, 1.07) (the beam lies
    // on y in [1, 2]); found by x0 at every step since the solver reorders
    // particles in memory.
    const double probe[2] = {3.93, 1.07};
    double start[2] = {0, 0}, best = 1e300;
    for (const auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p) {
            const double d = std::hypot(set.x0[0][p] - probe[0], set.x0[1][p] - probe[1]);
            if (d < best) best = d, start[0] = set.x0[0][p], start[1] = set.x0[1][p];
        }
    ASSERT_LT(best, 0.03); // the particle lattice has a spacing of h/3 = 0.042 m
    double peak = 0.0, peak_time = 0.0;
    talus::test::advance(*s->sim, 1.6, [&] {
        double y = 0.0;
        bool found = false;
        for (const auto &set : s->sim->sets())
            for (std::size_t p = 0; p < set.n && !found; ++p)
                if (set.x0[0][p] == start[0] && set.x0[1][p] == start[1]) {
                    y = set.x[1][p];
                    found = true;
                }
        ASSERT_TRUE(found);
        if (y - start[1] < peak) peak = y - start[1], peak_time = s->sim->time();
    });
    for (const char *mesh : {"fine", "12x3"}) {
        SCOPED_TRACE(mesh);
        const auto ref = read_numeric_csv(
            data_dir() / fmt::format("cantilever_selfweight_fem_ul_nguyen_{}.csv", mesh));
        double ref_peak = 0.0, ref_time = 0.0;
        for (const auto &row : ref)
            if (row[0] < 1.6 && row[1] < ref_peak) ref_peak = row[1], ref_time = row[0];
        ASSERT_LT(ref_peak, -3.0); // the file is the one described (peak about -3.23 m)
        // 5 %: the bound, and the FEM's own uncertainty. Its
        // fully integrated 4-node quadrilaterals are stiffer in bending than
        // the converged solution (shear locking), while this MPM run has
        // converged in the grid: the peak is -3.287, -3.301 and -3.304 m at
        // h = 0.25, 0.125 and 0.0625 m (3 particles per cell, measured),
        // 2.2 % past the FEM's -3.230 m, and at the same time (1.06 s).
        EXPECT_NEAR(peak, ref_peak, 0.05 * std::abs(ref_peak));
        EXPECT_NEAR(peak_time, ref_time, 0.05 * ref_time);
    }
}

namespace {

// Fraction of the total energy (kinetic + stress work: elastic here, 0.2 %
// strains) the two disks lose by t = 3 s with the given transfer and cell,
// `usl`, `bspline2`, default cfl.
double two_disks_energy_loss(const std::string &transfer, double h) {
    auto s = talus::test::sim_from_text(fmt::format(
        "talus: 1\ndimension: 2\ngrid: {{origin: [0, 0], size: [1.0, 1.0], cell: {h}}}\n"
        "materials:\n  e: {{model: linear_elastic, density: 1000, youngs_modulus: 1000, "
        "poisson_ratio: 0.3}}\n"
        "groups:\n"
        "  lower: {{material: e, shape: {{sphere: {{center: [0.2, 0.2], radius: 0.2}}}}, "
        "velocity: [0.1, 0.1]}}\n"
        "  upper: {{material: e, shape: {{sphere: {{center: [0.8, 0.8], radius: 0.2}}}}, "
        "velocity: [-0.1, -0.1]}}\n"
        "solver: {{transfer: {tr}, shape: bspline2}}\ntime: {{end: 3}}\n",
        fmt::arg("h", h), fmt::arg("tr", transfer)));
    const double e0 = totals(*s->sim).ke;
    advance(*s->sim, 3.0);
    const talus::Diagnostics d = s->sim->diagnostics();
    return 1.0 - (d.kinetic_energy + d.stress_work) / e0;
}

} // namespace

// APIC and TPIC keep the affine part of the velocity across the transfer,
// so they lose only the non-affine part at each step (docs/theory.md,
// "Energy under the four velocity transfers"): a consistent transfer whose
// loss vanishes as h does, and far below PIC's, which drops everything
// but the grid's interpolant. Measured at the default cfl: APIC 29.5 % at
// h = 0.05 and 15.0 % at 0.025 (ratio 0.51, first order), TPIC 29.6 % and
// 15.3 %; PIC 59.2 % and 48.5 % (ratio 0.82). The bounds: a ratio under
// 0.65 (first order gives 0.5 and a non-converging transfer about 1; 0.65
// leaves room for the pre-asymptotic coarse grid) and a loss under 0.6 of
// PIC's at the same grid.
TEST(Verification, TwoDisksAffineTransfersConvergeWithTheGrid) {
    const double pic_coarse = two_disks_energy_loss("pic", 0.05);
    const double pic_fine = two_disks_energy_loss("pic", 0.025);
    for (const char *tr : {"apic", "tpic"}) {
        SCOPED_TRACE(tr);
        const double coarse = two_disks_energy_loss(tr, 0.05);
        const double fine = two_disks_energy_loss(tr, 0.025);
        EXPECT_GT(fine, 0.0); // they do lose energy: the bound below is not vacuous
        EXPECT_LT(fine / coarse, 0.65);
        EXPECT_LT(coarse, 0.6 * pic_coarse);
        EXPECT_LT(fine, 0.6 * pic_fine);
    }
}

namespace {

// Every particle's position, velocity and stress, by id.
std::map<std::int64_t, std::vector<double>> particle_table(const talus::Simulation &sim) {
    std::map<std::int64_t, std::vector<double>> t;
    for (const talus::ParticleSet &s : sim.sets())
        for (std::size_t p = 0; p < s.n; ++p) {
            std::vector<double> row;
            for (int d = 0; d < 2; ++d) {
                row.push_back(s.x[d][p]);
                row.push_back(s.v[d][p]);
            }
            for (int k = 0; k < 6; ++k)
                row.push_back(s.stress[6 * p + k]);
            t[s.id[p]] = row;
        }
    return t;
}

} // namespace

// The bar's first mode given by one expression of position
// (bar_vibration_expression.yaml) against the 13 per-cell groups it replaces
// (bar_vibration.yaml, whose velocities were sampled at the cell centres
// outside Talus). The particles are the same, in the same order; the
// velocities differ by the rounding of sin's argument (x from the lattice,
// not the generator's (k + 1/2) h), a few 1e-17 m/s, and the summation
// order of the grid differs with the groups. The linear elastic system is
// stable, so such differences stay round-off: 1e-13 of the amplitude (0.1
// m/s, 0.26 m, 0.4 Pa) over the 1040 steps of two periods is 100 times the
// largest difference measured (3e-15), and a velocity off by one cell's
// sample (0.012 m/s) would exceed it by 10^10.
TEST(Verification, BarFirstModeByExpressionEqualsPerCellGroups) {
    auto cells = sim_from_config("configs/verification/bar_vibration.yaml");
    auto expr = sim_from_config("configs/verification/bar_vibration_expression.yaml");
    ASSERT_EQ(cells->sim->sets()[0].n, 13u);
    ASSERT_EQ(expr->sim->sets()[0].n, 13u);
    const std::vector<double> scale = {25.0, 0.1, 1.0, 0.1, 0.4, 0.4, 0.4, 0.4, 0.4, 0.4};
    auto compare = [&](const char *when) {
        const auto a = particle_table(*cells->sim), b = particle_table(*expr->sim);
        ASSERT_EQ(a.size(), b.size());
        for (const auto &[id, row] : a) {
            const std::vector<double> &other = b.at(id);
            for (std::size_t k = 0; k < row.size(); ++k)
                EXPECT_NEAR(other[k], row[k], 1e-13 * scale[k])
                    << when << ": particle " << id << ", column " << k;
        }
    };
    compare("t = 0");
    advance(*cells->sim, 20.0);
    advance(*expr->sim, 20.0);
    EXPECT_EQ(cells->sim->steps(), expr->sim->steps());
    compare("t = 20 s");
}
