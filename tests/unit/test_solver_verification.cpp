// The solver against references no one here wrote (tests/data/README.md):
// the vibrating bar's closed form, the single-point oscillator's closed form,
// and a peer code's two-disk energies.
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

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

// The bar's centre-of-mass velocity over two periods.
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
    std::vector<double> t, v;
    for (double target = 0.0; target <= 20.0 + 1e-9; target += 0.05) {
        advance(*s->sim, target);
        const auto tot = totals(*s->sim);
        t.push_back(s->sim->time());
        v.push_back(tot.p[0] / tot.mass);
    }
    return measure(t, v);
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
    advance(*s->sim, 3.0, [&] {
        const auto t = totals(*s->sim);
        const talus::Diagnostics d = s->sim->diagnostics();
        if (t.ke < ke_min) {
            ke_min = t.ke;
            t_min = s->sim->time();
        }
        worst_p = std::max({worst_p, std::abs(t.p[0]), std::abs(t.p[1])});
        (void)d;
    });
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
    // End-of-run total energy: the peer ends 3.0 % below the start; agreement
    // to 1 % of the total (observed 0.2-0.3 %).
    const talus::Diagnostics d = s->sim->diagnostics();
    const double total = d.kinetic_energy + d.strain_energy;
    EXPECT_NEAR(total, ref.back()[3], 0.01 * ref.back()[3]);
    EXPECT_LT(total, ref[0][3]); // it does lose energy, as the peer's does
}
