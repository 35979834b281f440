// talus::sdk::isotropic_hooke, Hooke's law over a chunk of points, against
// the formula written out point by point (sigma_end = sigma_start + lambda
// tr(de) I + 2 G de, tensor shear stress, engineering shear strain): the same
// bits for every value, for every chunk length (the pairs and the point
// left over), with and without the AVX form, in place (s1 = s0) and not,
// and nothing written past the chunk.
#include <talus/sdk/hooke.hpp>

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
    talus::sdk::test::with_each_form("AVX pairs", "point by point", f);
}

// The law as a model author writes it for one point.
void reference(double lambda, double G, const double *s0, const double *de, double *s1) {
    const double lam_tr = lambda * (de[0] + de[1] + de[2]);
    for (int i = 0; i < 3; ++i) {
        s1[i] = s0[i] + (lam_tr + 2.0 * G * de[i]);
        s1[i + 3] = s0[i + 3] + G * de[i + 3];
    }
}

TEST(IsotropicHooke, EveryValueHasTheFormulasBits) {
    with_each_form([] {
        std::mt19937 gen(5);
        // Stresses of soil to rock (signed, 1 Pa to 100 MPa), increments of
        // 1e-9 to 1e-2, moduli of soft soil to steel; some exact zeros.
        std::uniform_real_distribution<double> log_s(0.0, 8.0), log_e(-9.0, -2.0), log_m(5.0, 11.5),
            u(0.0, 1.0);
        auto signed_value = [&](double magnitude) {
            if (u(gen) < 0.05) return 0.0;
            return u(gen) < 0.5 ? -magnitude : magnitude;
        };
        for (std::size_t n = 0; n <= 13; ++n)
            for (int trial = 0; trial < 100; ++trial) {
                const double lambda = std::pow(10.0, log_m(gen)), G = std::pow(10.0, log_m(gen));
                std::vector<double> s0(6 * n), de(6 * n), want(6 * n);
                for (std::size_t j = 0; j < 6 * n; ++j) {
                    s0[j] = signed_value(std::pow(10.0, log_s(gen)));
                    de[j] = signed_value(std::pow(10.0, log_e(gen)));
                }
                for (std::size_t k = 0; k < n; ++k)
                    reference(lambda, G, &s0[6 * k], &de[6 * k], &want[6 * k]);
                std::vector<double> s1(6 * n + 1, -7.0);
                talus::sdk::isotropic_hooke(lambda, G, s0.data(), de.data(), s1.data(), n);
                for (std::size_t j = 0; j < 6 * n; ++j)
                    ASSERT_EQ(bits(s1[j]), bits(want[j]))
                        << "n " << n << " point " << j / 6 << " component " << j % 6;
                EXPECT_EQ(s1[6 * n], -7.0) << "written past the chunk, n " << n;
                // In place: the stress array updated over itself.
                talus::sdk::isotropic_hooke(lambda, G, s0.data(), de.data(), s0.data(), n);
                for (std::size_t j = 0; j < 6 * n; ++j)
                    ASSERT_EQ(bits(s0[j]), bits(want[j])) << "in place, n " << n << " value " << j;
            }
    });
}

TEST(IsotropicHooke, ANonFiniteIncrementReachesOnlyItsPointsStress) {
    // A NaN in one point's increment makes that point's stress NaN (its
    // normal components through the trace, or one shear component), and
    // leaves its neighbour in the pair alone: the host's screen then names
    // the right point.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    with_each_form([&] {
        for (std::size_t at = 0; at < 12; ++at) {
            double s0[12], de[12], s1[12];
            for (std::size_t j = 0; j < 12; ++j) {
                s0[j] = 1e3 * static_cast<double>(j + 1);
                de[j] = 1e-4;
            }
            de[at] = nan;
            talus::sdk::isotropic_hooke(3e7, 2e7, s0, de, s1, 2);
            const std::size_t point = at / 6, c = at % 6;
            for (std::size_t j = 0; j < 12; ++j) {
                const bool hit = j / 6 == point && (c < 3 ? j % 6 < 3 : j % 6 == c);
                EXPECT_EQ(std::isnan(s1[j]), hit) << "NaN at " << at << ", value " << j;
            }
        }
    });
}

} // namespace
