// talus::sdk::wave_speeds, the elastic wave speeds of a chunk of points,
// against the scalar formula it replaces in a model's quick pass: the same
// bits for every point (a division and a square root, each correctly
// rounded in IEEE arithmetic whether done one, two or four at a time), for
// every chunk length (the quads, the pairs and the points left over), with
// and without the four-lane form, and the same answers to bad densities as
// std::sqrt (NaN, never a silent number).
#include <talus/sdk/wave_speed.hpp>

#include "forms.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace {

using talus::sdk::test::bits;

// Each test body with both forms (forms.hpp).
template <class F>
void with_each_form(F &&f) {
    talus::sdk::test::with_each_form("four lanes", "pairs", f);
}

TEST(WaveSpeeds, EveryPointHasTheScalarFormulasBits) {
    with_each_form([] {
        std::mt19937 gen(11);
        // Densities over the whole range a solver meets (gas-like to
        // compressed rock) and moduli from soft soil to steel.
        std::uniform_real_distribution<double> log_rho(0.0, 4.5), log_m(3.0, 12.0);
        for (std::size_t n = 0; n <= 13; ++n)
            for (int trial = 0; trial < 200; ++trial) {
                const double m = std::pow(10.0, log_m(gen));
                std::vector<double> rho(n), c(n + 1, -1.0);
                for (double &r : rho)
                    r = std::pow(10.0, log_rho(gen));
                talus::sdk::wave_speeds(m, rho.data(), c.data(), n);
                for (std::size_t k = 0; k < n; ++k)
                    ASSERT_EQ(bits(c[k]), bits(std::sqrt(m / rho[k])))
                        << "n " << n << " point " << k << ": " << c[k];
                // Nothing written past the chunk.
                EXPECT_EQ(c[n], -1.0) << "n " << n;
            }
    });
}

TEST(WaveSpeedsWithBadDensities, GiveWhatTheScalarFormulaGives) {
    // A NaN or negative density gives NaN, a zero one infinity, as
    // std::sqrt(m / rho) does: the host's screen then stops the run.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    // Each bad value at each place of a quad and of the pair after it.
    const double bad[] = {nan, -1.0, 0.0};
    with_each_form([&] {
        for (const double b : bad)
            for (std::size_t at = 0; at < 6; ++at) {
                double rho[6], c[6];
                for (double &r : rho)
                    r = 2000.0;
                rho[at] = b;
                talus::sdk::wave_speeds(1e8, rho, c, 6);
                for (std::size_t k = 0; k < 6; ++k) {
                    if (k != at)
                        EXPECT_EQ(c[k], std::sqrt(1e8 / 2000.0)) << "bad " << b << " at " << at;
                    else if (b == 0.0)
                        EXPECT_TRUE(std::isinf(c[k])) << "at " << at;
                    else
                        EXPECT_TRUE(std::isnan(c[k])) << "bad " << b << " at " << at;
                }
            }
    });
}

} // namespace
