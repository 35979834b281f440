// talus::sdk::symmetric_eigen against matrices built from known principal
// values and directions (A = R diag(l) R^T), and against Eigen's iterative
// solver on random matrices: values, residual and orthonormality at every
// spacing of the values, including the double and triple ones where the
// characteristic cubic alone loses half the digits.
#include <talus/sdk/spectral.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <utility>
#include <vector>

namespace {

using talus::sdk::Mat3;
using V3 = Eigen::Vector3d;
constexpr double kEps = std::numeric_limits<double>::epsilon();
// A backward-stable decomposition has errors of a few round-offs of |A|
// (Golub & Van Loan, sec. 8.1); the construction of A = R diag(l) R^T adds
// as many to the reference. 20 eps leaves room for both and is still ten
// million times below the 1e-8 the closed-form cubic reaches at a double
// value (the failure this solver is built to avoid).
constexpr double kTol = 20.0 * kEps;

Mat3 random_rotation(std::mt19937 &gen) {
    std::normal_distribution<double> n;
    Eigen::Quaterniond q(n(gen), n(gen), n(gen), n(gen));
    q.normalize();
    return q.toRotationMatrix();
}

// n symmetric matrices with entries uniform in [-1e4, 1e4].
std::vector<Mat3> random_symmetric(std::mt19937 &gen, int n) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<Mat3> m;
    for (int k = 0; k < n; ++k) {
        Mat3 a;
        for (int i = 0; i < 3; ++i)
            for (int j = i; j < 3; ++j)
                a(i, j) = a(j, i) = 1e4 * u(gen);
        m.push_back(a);
    }
    return m;
}

// Checks the decomposition of a against the descending values l (exact up
// to a's construction).
void expect_decomposition(const Mat3 &a, const V3 &l) {
    const talus::sdk::SymmetricEigen e = talus::sdk::symmetric_eigen(a);
    // The largest entry, not the norm, whose squares underflow at 1e-250.
    const double scale = a.cwiseAbs().maxCoeff();
    EXPECT_GE(e.values[0], e.values[1]);
    EXPECT_GE(e.values[1], e.values[2]);
    EXPECT_LE((e.values - l).cwiseAbs().maxCoeff(), kTol * scale)
        << "values " << e.values.transpose() << " expected " << l.transpose();
    EXPECT_LE((e.compose(e.values) - a).cwiseAbs().maxCoeff(), kTol * scale);
    EXPECT_LE((e.vectors.transpose() * e.vectors - Mat3::Identity()).norm(), kTol);
    // The Voigt form holds the same six components (a few round-offs: the
    // products are summed in another order).
    EXPECT_LE((e.compose_stress(e.values) - talus::sdk::matrix_to_stress(e.compose(e.values)))
                  .cwiseAbs()
                  .maxCoeff(),
              kTol * scale);
    // Each column belongs to its value: A v = l v.
    for (int k = 0; k < 3; ++k)
        EXPECT_LE((a * e.vectors.col(k) - e.values[k] * e.vectors.col(k)).cwiseAbs().maxCoeff(),
                  kTol * scale);
}

TEST(SymmetricEigen, KnownValuesAtEverySpacing) {
    std::mt19937 gen(7);
    // Two values from 1 apart (relative) to equal, each with the third
    // above or below, a stress-like scale, and a large mean beside a small
    // deviator (a geostatic stress).
    for (double gap : {1.0, 1e-1, 1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 1e-13, 0.0})
        for (int trial = 0; trial < 500; ++trial) {
            const Mat3 r = random_rotation(gen);
            V3 l;
            switch (trial % 4) {
            case 0: l = V3(2.3e5, -1e5, -1e5 * (1.0 + gap)); break;
            case 1: l = V3(1e5 * (1.0 + gap), 1e5, -2.3e5); break;
            case 2: l = V3(-1.5e6, -3e6, -3e6 * (1.0 + gap)); break;
            default: l = V3(-1e6 + 1e3 * (1.0 + gap), -1e6 + 1e3, -1e6); break;
            }
            std::sort(l.data(), l.data() + 3, std::greater<>());
            expect_decomposition(r * l.asDiagonal() * r.transpose(), l);
        }
}

// Plane matrices (entries (0, 2) and (1, 2) exactly zero: a plane-strain
// stress) take the closed form of the in-plane block. A rotation about z
// keeps them plane; the out-of-plane value goes above, between, below and
// onto the in-plane ones, at every spacing of those.
TEST(SymmetricEigen, PlaneMatricesAtEverySpacing) {
    std::mt19937 gen(5);
    std::uniform_real_distribution<double> angle(-3.2, 3.2);
    for (double gap : {1.0, 1e-1, 1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 1e-13, 0.0})
        for (int trial = 0; trial < 500; ++trial) {
            const Mat3 r = Eigen::AngleAxisd(angle(gen), V3::UnitZ()).toRotationMatrix();
            const double p1 = -1e5, p2 = -1e5 * (1.0 + gap);
            const double z[] = {2e5, -1.00000001e5, -3e5, p1, p2, -1e5 + 1e-3};
            const double l3 = z[trial % 6];
            V3 l(p1, p2, l3);
            Mat3 a = r * V3(p1, p2, 0.0).asDiagonal() * r.transpose();
            a(2, 2) = l3;
            a(0, 2) = a(2, 0) = a(1, 2) = a(2, 1) = 0.0; // exactly plane
            std::sort(l.data(), l.data() + 3, std::greater<>());
            expect_decomposition(a, l);
        }
    // The in-plane block out of [1e-150, 1e150] is scaled.
    for (double s : {1e-250, 1e-170, 1e170, 1e250}) {
        const Mat3 r = Eigen::AngleAxisd(0.3, V3::UnitZ()).toRotationMatrix();
        Mat3 a = r * V3(2.0 * s, s * (1.0 + 1e-9), 0.0).asDiagonal() * r.transpose();
        a(2, 2) = 0.5 * s;
        a(0, 2) = a(2, 0) = a(1, 2) = a(2, 1) = 0.0;
        expect_decomposition(a, V3(2.0, 1.0 + 1e-9, 0.5) * s);
    }
    // NaN in any in-plane entry or the out-of-plane one gives NaN out.
    for (const auto &[i, j] : {std::pair{0, 0}, {1, 1}, {0, 1}, {2, 2}}) {
        Mat3 a = Eigen::Vector3d(3.0, 1.0, 2.0).asDiagonal();
        a(0, 1) = a(1, 0) = 0.5;
        a(i, j) = a(j, i) = std::numeric_limits<double>::quiet_NaN();
        const talus::sdk::SymmetricEigen e = talus::sdk::symmetric_eigen(a);
        EXPECT_TRUE(e.values.hasNaN()) << i << j;
        EXPECT_TRUE(e.compose(V3::Ones()).hasNaN()) << i << j;
    }
}

TEST(SymmetricEigen, MatchesTheIterativeSolverOnRandomMatrices) {
    std::mt19937 gen(11);
    std::normal_distribution<double> n;
    for (int trial = 0; trial < 5000; ++trial) {
        Mat3 b;
        for (int i = 0; i < 9; ++i)
            b.data()[i] = n(gen);
        const Mat3 a = (b + b.transpose()) * 1e5;
        const Eigen::SelfAdjointEigenSolver<Mat3> ref(a);
        const V3 l(ref.eigenvalues()[2], ref.eigenvalues()[1], ref.eigenvalues()[0]);
        expect_decomposition(a, l);
    }
}

TEST(SymmetricEigen, DiagonalIsotropicAndZeroMatrices) {
    // Already diagonal, in every order: the values sorted, the vectors the
    // axes (up to sign).
    const V3 d(3.0, -1.0, 2.0);
    int perm[3] = {0, 1, 2};
    do {
        const V3 l(d[perm[0]], d[perm[1]], d[perm[2]]);
        const Mat3 a = l.asDiagonal();
        expect_decomposition(a, V3(3.0, 2.0, -1.0));
    } while (std::next_permutation(perm, perm + 3));
    // q I has any basis: the solver returns the axes.
    for (double q : {0.0, -4.5e6, 1e-300}) {
        const talus::sdk::SymmetricEigen e = talus::sdk::symmetric_eigen(q * Mat3::Identity());
        EXPECT_EQ(e.values, V3::Constant(q));
        EXPECT_EQ(e.vectors, Mat3::Identity());
    }
}

TEST(SymmetricEigen, ExtremeScalesAreScaledNotOverflowed) {
    // Beyond [1e-60, 1e60] the squares of squares would under- or overflow
    // without the scaling.
    std::mt19937 gen(3);
    for (double s : {1e-250, 1e-70, 1e70, 1e250}) {
        const Mat3 r = random_rotation(gen);
        const V3 l = V3(2.0, 1.0 + 1e-9, 1.0) * s;
        expect_decomposition(r * l.asDiagonal() * r.transpose(), l);
    }
}

TEST(SymmetricEigen, NaNInGivesNaNOut) {
    // NaN in any entry of an isotropic matrix (where the largest entry of
    // A - q I would be 0 without it), of a general one and of a plane one
    // (where NaN at (2, 2) leaves the in-plane block finite: only the
    // place no value takes carries it out).
    Mat3 general, plane;
    general << 3.0, 0.5, -0.25, 0.5, 1.0, 0.75, -0.25, 0.75, 2.0;
    plane << 3.0, 0.5, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 2.0;
    for (const Mat3 &base : {Mat3(2.0 * Mat3::Identity()), general, plane})
        for (int i = 0; i < 3; ++i)
            for (int j = i; j < 3; ++j) {
                Mat3 a = base;
                a(i, j) = a(j, i) = std::numeric_limits<double>::quiet_NaN();
                const talus::sdk::SymmetricEigen e = talus::sdk::symmetric_eigen(a);
                EXPECT_TRUE(e.values.hasNaN()) << base << "\n" << i << j;
                EXPECT_TRUE(e.compose(V3::Ones()).hasNaN()) << base << "\n" << i << j;
            }
}

// symmetric_eigen_pair decomposes two matrices in the two lanes of one
// vector: each lane must be the single decomposition bit for bit (a model's
// point may be decomposed in a pair or alone, depending on its batch), also
// when only one lane needs the scaling, is a multiple of the identity or
// holds NaN, which must not reach the other lane.
TEST(SymmetricEigen, PairLanesAreTheSingleDecompositionBitForBit) {
    std::mt19937 gen(11);
    std::vector<Mat3> m = random_symmetric(gen, 200);
    const Mat3 r = random_rotation(gen);
    m.push_back(r * V3(2.0, 1.0, 1.0).asDiagonal() * r.transpose()); // a double value
    m.push_back(1e-70 * m[0]);                                       // scaled up
    m.push_back(1e70 * m[1]);                                        // scaled down
    m.push_back(-3.5 * Mat3::Identity());
    m.push_back(Mat3::Zero());
    Mat3 nan = m[2];
    nan(0, 2) = nan(2, 0) = std::numeric_limits<double>::quiet_NaN();
    m.push_back(nan);
    Mat3 plane = m[5]; // the closed form of the in-plane block
    plane(0, 2) = plane(2, 0) = plane(1, 2) = plane(2, 1) = 0.0;
    m.push_back(plane);
    Mat3 plane_nan = plane;
    plane_nan(0, 1) = plane_nan(1, 0) = std::numeric_limits<double>::quiet_NaN();
    m.push_back(plane_nan);
    auto same = [](const talus::sdk::SymmetricEigen &a, const talus::sdk::SymmetricEigen &b) {
        return std::memcmp(a.values.data(), b.values.data(), sizeof(double) * 3) == 0 &&
               std::memcmp(a.vectors.data(), b.vectors.data(), sizeof(double) * 9) == 0;
    };
    // Every matrix beside every special one, and the random ones in pairs.
    const std::size_t specials = 8;
    for (std::size_t i = 0; i < m.size(); ++i)
        for (std::size_t j = 0; j < m.size(); ++j) {
            if (i < m.size() - specials && j < m.size() - specials && j != i + 1) continue;
            talus::sdk::SymmetricEigen a, b;
            talus::sdk::symmetric_eigen_pair(m[i], m[j], a, b);
            EXPECT_TRUE(same(a, talus::sdk::symmetric_eigen(m[i]))) << i << " beside " << j;
            EXPECT_TRUE(same(b, talus::sdk::symmetric_eigen(m[j]))) << j << " beside " << i;
            EXPECT_EQ(a.values.hasNaN(), m[i].hasNaN()) << i << " beside " << j;
            EXPECT_EQ(b.values.hasNaN(), m[j].hasNaN()) << j << " beside " << i;
        }
    // And the pair's lanes are decompositions (the single one's accuracy
    // is tested above; this catches a pair that gives both lanes one
    // matrix's result). kTol is relative to the largest entry, here 1e4.
    talus::sdk::SymmetricEigen a, b;
    talus::sdk::symmetric_eigen_pair(m[3], m[4], a, b);
    EXPECT_LE((a.compose(a.values) - m[3]).cwiseAbs().maxCoeff(), kTol * 1e4);
    EXPECT_LE((b.compose(b.values) - m[4]).cwiseAbs().maxCoeff(), kTol * 1e4);
}

// symmetric_eigen_group and symmetric_eigen_lanes: every matrix of a group
// of 1 to 8 is the single decomposition bit for bit, whichever path took
// it (the AVX-512 lanes where this processor has them and the group has
// four general matrices or more, else the pairs; the test runs both),
// beside special matrices (scaled, multiples of the identity, NaN, plane,
// equal values) in any lane.
TEST(SymmetricEigen, GroupsAreTheSingleDecompositionBitForBit) {
    std::mt19937 gen(17);
    const std::vector<Mat3> pool = random_symmetric(gen, 400);
    const Mat3 r = random_rotation(gen);
    std::vector<Mat3> special{r * V3(2.0, 1.0, 1.0).asDiagonal() * r.transpose(), 1e-70 * pool[0],
                              1e70 * pool[1], -3.5 * Mat3::Identity(), Mat3::Zero()};
    Mat3 nan = pool[2];
    nan(0, 2) = nan(2, 0) = std::numeric_limits<double>::quiet_NaN();
    special.push_back(nan);
    Mat3 plane = pool[3];
    plane(0, 2) = plane(2, 0) = plane(1, 2) = plane(2, 1) = 0.0;
    special.push_back(plane);
    // Values 0, 2, 2 of a general matrix, the two equal ones exact: the
    // order's ties.
    Mat3 tie;
    tie << 1.0, 0.0, 1.0, 0.0, 2.0, 0.0, 1.0, 0.0, 1.0;
    special.push_back(tie);
    Mat3 nan_diagonal = pool[4];
    nan_diagonal(1, 1) = std::numeric_limits<double>::quiet_NaN();
    special.push_back(nan_diagonal);
    auto same = [](const talus::sdk::SymmetricEigen &a, const talus::sdk::SymmetricEigen &b) {
        return std::memcmp(a.values.data(), b.values.data(), sizeof(double) * 3) == 0 &&
               std::memcmp(a.vectors.data(), b.vectors.data(), sizeof(double) * 9) == 0;
    };
    bool &octet = talus::sdk::detail::octet_enabled();
    const bool has_octet = octet;
    std::size_t next = 0;
    for (const bool use_octet : {true, false}) {
        octet = use_octet && has_octet;
        for (std::size_t n = 1; n <= talus::sdk::kEigenGroup; ++n)
            for (int trial = 0; trial < 40; ++trial) {
                Mat3 m[talus::sdk::kEigenGroup];
                for (std::size_t k = 0; k < n; ++k)
                    m[k] = pool[next++ % pool.size()];
                // One special matrix in a lane that moves with the trial.
                if (trial % 2 == 1)
                    m[static_cast<std::size_t>(trial) % n] =
                        special[static_cast<std::size_t>(trial / 2) % special.size()];
                talus::sdk::SymmetricEigen e[talus::sdk::kEigenGroup];
                talus::sdk::symmetric_eigen_group(m, e, n);
                // The same as lanes: lanes from n on repeat lane n - 1.
                talus::sdk::EigenLanes lanes;
                talus::sdk::symmetric_eigen_lanes(m, n, lanes);
                for (std::size_t k = 0; k < talus::sdk::kEigenGroup; ++k) {
                    const std::size_t src = std::min(k, n - 1);
                    const talus::sdk::SymmetricEigen one = talus::sdk::symmetric_eigen(m[src]);
                    talus::sdk::SymmetricEigen lane;
                    lanes.get(k, lane);
                    EXPECT_TRUE(same(lane, one)) << "lanes of " << n << ", lane " << k
                                                 << (octet ? " (AVX-512)" : " (pairs)");
                    if (k >= n) continue;
                    EXPECT_TRUE(same(e[k], one)) << "group of " << n << ", lane " << k
                                                 << (octet ? " (AVX-512)" : " (pairs)");
                    EXPECT_EQ(e[k].values.hasNaN(), m[k].hasNaN()) << n << " " << k;
                }
            }
    }
    octet = has_octet;
    // And a lane's result is its own matrix's (kTol relative to 1e4).
    Mat3 m[8];
    for (std::size_t k = 0; k < 8; ++k)
        m[k] = pool[k];
    talus::sdk::SymmetricEigen e[8];
    talus::sdk::symmetric_eigen_group(m, e, 8);
    for (std::size_t k = 0; k < 8; ++k)
        EXPECT_LE((e[k].compose(e[k].values) - m[k]).cwiseAbs().maxCoeff(), kTol * 1e4) << k;
    if (!has_octet) std::printf("note: no AVX-512 here; the groups ran as pairs only\n");
}

// Compilers without vector extensions run the same source over doubles:
// that instance must give the lane pair's bits (both are IEEE operations
// in one order; the tests are built without fused multiply-adds).
TEST(SymmetricEigen, TheScalarInstanceGivesTheLanePairsBits) {
    std::mt19937 gen(13);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int k = 0; k < 500; ++k) {
        Mat3 a;
        for (int i = 0; i < 3; ++i)
            for (int j = i; j < 3; ++j)
                a(i, j) = a(j, i) = (k % 50 == 0 ? 1e70 : 1e3) * u(gen);
        const talus::sdk::detail::Unordered<double> s = talus::sdk::detail::unordered_eigen<double>(
            a(0, 0), a(1, 1), a(2, 2), a(0, 1), a(0, 2), a(1, 2));
        talus::sdk::SymmetricEigen scalar;
        talus::sdk::detail::order_lane(s.q, s.scale, s.l, s.vec, scalar);
        const talus::sdk::SymmetricEigen pair = talus::sdk::symmetric_eigen(a);
        EXPECT_EQ(0, std::memcmp(scalar.values.data(), pair.values.data(), sizeof(double) * 3))
            << k;
        EXPECT_EQ(0, std::memcmp(scalar.vectors.data(), pair.vectors.data(), sizeof(double) * 9))
            << k;
    }
}

TEST(SymmetricEigen, CubicRootIsSmithsFormula) {
    // The quintic start and Halley step against 2 cos(acos(s) / 3), within
    // two ulps of the root (at most 2).
    for (int i = 0; i <= 20000; ++i) {
        const double s = i / 20000.0;
        const double ref = 2.0 * std::cos(std::acos(s) / 3.0);
        EXPECT_NEAR(talus::sdk::detail::largest_cubic_root(s), ref, 4.0 * kEps) << "s = " << s;
    }
}

} // namespace
