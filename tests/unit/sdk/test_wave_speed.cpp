// talus::sdk::wave_speeds, the elastic wave speeds of a chunk of points,
// against the scalar formula it replaces in a model's quick pass: the same
// bits for every point (a division and a square root, each correctly
// rounded in IEEE arithmetic whether done one or two at a time), for every
// chunk length (the pairs and the odd point left over), and the same
// answers to bad densities as std::sqrt (NaN, never a silent number).
#include <talus/sdk/wave_speed.hpp>

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace {

// The bits of x: NaN compares equal to a NaN of the same payload.
std::uint64_t bits(double x) { return std::bit_cast<std::uint64_t>(x); }

TEST(WaveSpeeds, EveryPointHasTheScalarFormulasBits) {
    std::mt19937 gen(11);
    // Densities over the whole range a solver meets (gas-like to
    // compressed rock) and moduli from soft soil to steel.
    std::uniform_real_distribution<double> log_rho(0.0, 4.5), log_m(3.0, 12.0);
    for (std::size_t n = 0; n <= 9; ++n)
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
}

TEST(WaveSpeedsWithBadDensities, GiveWhatTheScalarFormulaGives) {
    // A NaN or negative density gives NaN, a zero one infinity, as
    // std::sqrt(m / rho) does: the host's screen then stops the run.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double rho[] = {nan, 2000.0, -1.0, 0.0, 2000.0};
    double c[5];
    talus::sdk::wave_speeds(1e8, rho, c, 5);
    EXPECT_TRUE(std::isnan(c[0]));
    EXPECT_EQ(c[1], std::sqrt(1e8 / 2000.0));
    EXPECT_TRUE(std::isnan(c[2]));
    EXPECT_TRUE(std::isinf(c[3]));
    EXPECT_EQ(c[4], std::sqrt(1e8 / 2000.0));
}

} // namespace
