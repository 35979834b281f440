// The block kinematics (core/src/mpm/method/kinematics.cpp), which computes N
// points at once across the vector lanes:
//
// - against the definitions, point by point, computed here independently:
//   F1 = (I + dt L) F0 (seed 000 eq. 39), J = det F1, rho = rho0 / J
//   (eq. 41), the strain increment dt sym(L) with engineering shears
//   (eq. 42), div v = tr L, and the start stress turned by the
//   Hughes-Winget rotation Q = (I - A)^-1 (I + A), A = dt skew(L) / 2, from
//   a general matrix inverse. Each value is a sum of at most a few dozen
//   products of numbers of order one (F, dt L) or of the stress scale:
//   1e-13 of that scale bounds the different order of the operations with
//   a wide margin (a few hundred ulps), as in test_stress_rotation.cpp;
// - every instruction set against the scalar code, bit for bit: each lane
//   does the operations of the scalar code in its order, without fused
//   multiply-adds (the file is compiled with -ffp-contract=off), so the
//   width of the vectors, the packing and the remainder cannot change a
//   bit. Runs on different machines depend on this;
// - an inverted point: the points before it done, its J kept, nothing
//   after it touched.
#include "isas.hpp"
#include "kernels/isa.hpp"
#include "method/kinematics.hpp"

#include <talus/sdk/voigt.hpp>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace {

using talus::Isa;
using talus::ParticleSet;

struct Block {
    ParticleSet s;
    std::vector<double> L, F_start, F_end, stress, de, rho, work;
    Block(int dim, bool finite_strain, std::size_t n) {
        s.dim = dim;
        s.finite_strain = finite_strain;
        s.has_L = s.has_dx = s.has_C = s.has_lp = false;
        s.has_divv = true;
        s.rho0 = 2000.0;
        s.resize(n);
        L.assign(9 * n, 0.0);
        F_start.assign(9 * n, -1.0);
        F_end.assign(9 * n, -1.0);
        stress.assign(6 * n, -1.0);
        de.assign(6 * n, -1.0);
        rho.assign(n, -1.0);
        work.assign(n, -1.0);
    }
    // The gradients as the particles keep them (rows), as the fused G2P
    // leaves them (columns: a copy of L by component), or L's first for all.
    enum class Layout { rows, columns, same };
    talus::Gradients gradients(Layout layout) {
        if (layout == Layout::same) return talus::Gradients::same(L.data());
        if (layout == Layout::rows) return talus::Gradients::rows(L.data());
        columns.assign(9 * s.n, 0.0);
        for (std::size_t p = 0; p < s.n; ++p)
            for (std::size_t c = 0; c < 9; ++c)
                columns[c * s.n + p] = L[9 * p + c];
        return talus::Gradients::columns(columns.data(), s.n);
    }
    std::size_t run(Isa isa, Layout layout = Layout::rows) {
        return talus::kinematics_block(s, 0, s.n, gradients(layout), dt,
                                       {F_start.data(), s.dim == 2 ? F_end.data() : nullptr,
                                        stress.data(), de.data(), rho.data(), work.data(), &finite},
                                       isa);
    }
    // Point by point: a block of one point never fills a pack, so this is
    // the scalar code.
    std::size_t run_one_by_one(Layout layout = Layout::rows) {
        const talus::Gradients all = gradients(layout);
        for (std::size_t p = 0; p < s.n; ++p)
            if (talus::kinematics_block(s, p, 1, all.from(p), dt,
                                        {F_start.data() + 9 * p,
                                         s.dim == 2 ? F_end.data() + 9 * p : nullptr,
                                         stress.data() + 6 * p, de.data() + 6 * p, rho.data() + p,
                                         work.data() + p, &finite},
                                        Isa::generic) != 1)
                return p;
        return s.n;
    }
    std::vector<double> columns;
    double dt = 0.05;
    bool finite = true;
};

// Random points: F near the identity, L of order one (dt L of order 0.05),
// stresses of order 1e5. Every eighth point has no spin (L symmetric) and
// in 3D every fifth spins about z alone: the rotation's three cases, mixed
// within a pack. off_plane: in 2D every ninth point's gradient gets an
// out-of-plane part too (which the solver never makes), so that its pack
// goes point by point.
Block random_block(int dim, bool finite_strain, std::size_t n, unsigned seed,
                   bool off_plane = false) {
    Block b(dim, finite_strain, n);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (std::size_t p = 0; p < n; ++p) {
        double F[9];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const bool in = i < dim && j < dim;
                F[3 * i + j] = (i == j ? 1.0 : 0.0) + (in ? 0.2 * u(rng) : 0.0);
                b.L[9 * p + 3 * i + j] = in ? u(rng) : 0.0;
            }
        b.s.set_F(p, F);
        double *L = &b.L[9 * p];
        if (p % 8 == 3)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < i; ++j)
                    L[3 * i + j] = L[3 * j + i];
        if (dim == 3 && p % 5 == 1) L[2] = L[6] = L[5] = L[7] = 0.0;
        if (dim == 2 && off_plane && p % 9 == 4) L[5] = u(rng);
        for (int k = 0; k < 6; ++k)
            b.s.stress[6 * p + k] = 1e5 * u(rng);
        b.s.J[p] = b.s.divv[p] = -7.0;
    }
    return b;
}

Eigen::Matrix3d mat(const double *a) {
    return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(a);
}

// Particle p's F, the full 3x3 (ParticleSet::F keeps plane strain's
// in-plane block).
Eigen::Matrix3d F_of(const ParticleSet &s, std::size_t p) {
    double F[9];
    s.F_of(p, F);
    return mat(F);
}

} // namespace

TEST(Kinematics, BlockMatchesTheDefinitions) {
    for (int dim : {2, 3})
        for (bool finite : {false, true}) {
            Block b = random_block(dim, finite, 37, 11);
            const Block start = random_block(dim, finite, 37, 11);
            ASSERT_EQ(b.run(Isa::generic), 37u);
            for (std::size_t p = 0; p < 37; ++p) {
                const Eigen::Matrix3d F0 = F_of(start.s, p), L = mat(&b.L[9 * p]);
                const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
                const Eigen::Matrix3d F1 = (I + b.dt * L) * F0;
                const std::string where = "dim " + std::to_string(dim) + ", point " +
                                          std::to_string(p) + (finite ? ", finite strain" : "");
                EXPECT_LT((F_of(b.s, p) - F1).cwiseAbs().maxCoeff(), 1e-13) << where;
                // The start F as it was, and in plane strain the end F
                // whole, for the model, the particle's to the bit.
                EXPECT_EQ(mat(&b.F_start[9 * p]), F0) << where;
                if (dim == 2) {
                    EXPECT_EQ(mat(&b.F_end[9 * p]), F_of(b.s, p)) << where;
                }
                EXPECT_NEAR(b.s.J[p], F1.determinant(), 1e-13) << where;
                EXPECT_NEAR(b.rho[p], b.s.rho0 / F1.determinant(), 1e-13 * b.s.rho0) << where;
                const Eigen::Matrix3d E = 0.5 * b.dt * (L + L.transpose());
                const double expect_de[6] = {E(0, 0),       E(1, 1),       E(2, 2),
                                             2.0 * E(0, 1), 2.0 * E(1, 2), 2.0 * E(0, 2)};
                for (int k = 0; k < 6; ++k)
                    EXPECT_NEAR(b.de[6 * p + k], expect_de[k], 1e-13) << where << ", de " << k;
                EXPECT_NEAR(b.s.divv[p], L.trace(), 1e-13) << where;
                // Strain-increment models get the rotated start stress;
                // finite-strain models their own.
                Eigen::Matrix3d A;
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        A(i, j) = 0.25 * b.dt * (L(i, j) - L(j, i));
                const Eigen::Matrix3d Q = finite ? I : Eigen::Matrix3d((I - A).inverse() * (I + A));
                talus::sdk::Vec6 s0;
                for (int k = 0; k < 6; ++k)
                    s0[k] = start.s.stress[6 * p + k];
                const talus::sdk::Vec6 expect = talus::sdk::matrix_to_stress(
                    Q * talus::sdk::stress_to_matrix(s0) * Q.transpose());
                for (int k = 0; k < 6; ++k)
                    EXPECT_NEAR(b.stress[6 * p + k], expect[k], 1e-13 * 1e5)
                        << where << ", stress " << k;
            }
        }
}

TEST(Kinematics, EveryInstructionSetGivesTheScalarBits) {
    // Counts below, at and past a pack, and a plugin batch; every layout of
    // the gradients (the same L for all points is the initial state's),
    // the scalar reference always from the rows: the layouts give the
    // same bits too.
    using Layout = Block::Layout;
    for (int dim : {2, 3})
        for (bool finite : {false, true})
            for (std::size_t n : {1u, 7u, 8u, 13u, 128u})
                for (Layout layout : {Layout::rows, Layout::columns, Layout::same})
                    for (bool off_plane : {false, true}) {
                        Block ref = random_block(dim, finite, n, 5, off_plane);
                        ASSERT_EQ(ref.run_one_by_one(layout == Layout::same ? Layout::same
                                                                            : Layout::rows),
                                  n);
                        for (Isa isa : runnable_isas()) {
                            Block b = random_block(dim, finite, n, 5, off_plane);
                            ASSERT_EQ(b.run(isa, layout), n);
                            const std::string where = std::string(talus::isa_name(isa)) + ", dim " +
                                                      std::to_string(dim) + ", n " +
                                                      std::to_string(n) + ", layout " +
                                                      std::to_string(static_cast<int>(layout)) +
                                                      (off_plane ? ", off the plane" : "");
                            auto same = [&](const double *a, const double *c, std::size_t m) {
                                return std::memcmp(a, c, m * sizeof(double)) == 0;
                            };
                            EXPECT_TRUE(same(b.s.F.data(), ref.s.F.data(), b.s.F_size() * n))
                                << where;
                            EXPECT_TRUE(same(b.F_start.data(), ref.F_start.data(), 9 * n)) << where;
                            EXPECT_TRUE(same(b.F_end.data(), ref.F_end.data(), 9 * n)) << where;
                            EXPECT_TRUE(same(b.de.data(), ref.de.data(), 6 * n)) << where;
                            EXPECT_TRUE(same(b.rho.data(), ref.rho.data(), n)) << where;
                            EXPECT_TRUE(same(b.work.data(), ref.work.data(), n)) << where;
                            EXPECT_TRUE(same(b.s.J.data(), ref.s.J.data(), n)) << where;
                            EXPECT_TRUE(same(b.s.divv.data(), ref.s.divv.data(), n)) << where;
                            EXPECT_TRUE(same(b.stress.data(), ref.stress.data(), 6 * n)) << where;
                        }
                    }
}

TEST(Kinematics, AnInvertedPointStopsTheBlockThere) {
    for (int dim : {2, 3})
        for (Isa isa : runnable_isas()) {
            const std::size_t n = 20, bad = 11;
            Block b = random_block(dim, false, n, 9);
            const Block start = random_block(dim, false, n, 9);
            // 1 + dt L_xx = -2 and no other gradient: F1's first row is
            // -2 times F0's, so J = -2 det F0 < 0.
            double *L = &b.L[9 * bad];
            for (int k = 0; k < 9; ++k)
                L[k] = 0.0;
            L[0] = -3.0 / b.dt;
            ASSERT_EQ(b.run(isa), bad) << talus::isa_name(isa);
            Block ref = random_block(dim, false, bad, 9); // the points before it alone
            ASSERT_EQ(ref.run(Isa::generic), bad);
            EXPECT_EQ(0, std::memcmp(b.stress.data(), ref.stress.data(), 6 * bad * sizeof(double)));
            EXPECT_EQ(
                0, std::memcmp(b.s.F.data(), ref.s.F.data(), b.s.F_size() * bad * sizeof(double)));
            EXPECT_LT(b.s.J[bad], 0.0); // kept: the error message shows it
            for (std::size_t p = bad; p < n; ++p)
                EXPECT_EQ(F_of(b.s, p), F_of(start.s, p))
                    << "point " << p << " of " << talus::isa_name(isa);
            // The particles' stress is the plugin's to write: never touched.
            EXPECT_EQ(
                0, std::memcmp(b.s.stress.data(), start.s.stress.data(), 6 * n * sizeof(double)));
            for (std::size_t p = bad + 1; p < n; ++p)
                EXPECT_EQ(b.s.J[p], -7.0) << "point " << p << " of " << talus::isa_name(isa);
        }
}

// What the material update tells the plugin (TALUS_BATCH_INPUTS_FINITE):
// the block's inputs are finite for ordinary points, and not when a start
// stress is infinite or NaN, or when J is so small that the density
// overflows, whether the point is in a pack or in the scalar remainder.
TEST(Kinematics, ANonFiniteInputIsReported) {
    const double inf = std::numeric_limits<double>::infinity();
    for (int dim : {2, 3})
        for (Isa isa : runnable_isas())
            for (std::size_t at : {2u, 12u}) { // a pack's lane, the remainder
                const std::string where = std::string(talus::isa_name(isa)) + ", dim " +
                                          std::to_string(dim) + ", point " + std::to_string(at);
                Block ok = random_block(dim, false, 13, 3);
                ASSERT_EQ(ok.run(isa), 13u);
                EXPECT_TRUE(ok.finite) << where;
                for (double bad : {inf, std::numeric_limits<double>::quiet_NaN()}) {
                    Block b = random_block(dim, false, 13, 3);
                    b.s.stress[6 * at + 1] = bad;
                    ASSERT_EQ(b.run(isa), 13u);
                    EXPECT_FALSE(b.finite) << where << ", stress " << bad;
                }
                // J = 1e-316 (subnormal, positive: not an inversion), so
                // rho0 / J overflows.
                Block tiny = random_block(dim, false, 13, 3);
                double F[9] = {};
                for (int d = 0; d < dim; ++d)
                    F[4 * d] = dim == 2 ? 1e-158 : 1e-105;
                if (dim == 2) F[8] = 1.0;
                tiny.s.set_F(at, F);
                std::fill(&tiny.L[9 * at], &tiny.L[9 * at] + 9, 0.0);
                ASSERT_EQ(tiny.run(isa), 13u) << where;
                EXPECT_GT(tiny.s.J[at], 0.0) << where;
                EXPECT_FALSE(tiny.finite) << where << ", density";
            }
}

// The end stress's half of the stress work (stress_work_block): against its
// definition, work + V/2 (w_start + sigma_end : de) with V = J vol0 and the
// shears engineering, computed here with Eigen's double contraction; and
// every instruction set against the scalar code (a block of one point)
// bit for bit, at counts below, at and past a pack and a plugin batch.
// Each increment is the sum of a few products of order 1e5 * 0.05 * V: 1e-13
// of that scale bounds the different order of the operations; the sum's
// last rounding is at most an ulp of the accumulated work (|work| <= 10 +
// the increment), which 1e-15 * 10 covers.
TEST(Kinematics, StressWorkBlockMatchesItsDefinitionOnEveryInstructionSet) {
    for (std::size_t n : {1u, 7u, 8u, 13u, 128u}) {
        auto make = [&] {
            Block b = random_block(3, false, n, 17);
            EXPECT_EQ(b.run(Isa::generic), n);
            std::mt19937_64 rng(23);
            std::uniform_real_distribution<double> u(-1.0, 1.0);
            for (std::size_t p = 0; p < n; ++p) {
                b.s.vol0[p] = 1e-3 * (1.5 + u(rng));
                b.s.work[p] = 10.0 * u(rng);
                for (int k = 0; k < 6; ++k)
                    b.s.stress[6 * p + k] = 1e5 * u(rng); // the end stress
            }
            return b;
        };
        Block ref = make();
        const Block start = make();
        for (std::size_t p = 0; p < n; ++p)
            talus::stress_work_block(ref.s, p, 1, ref.de.data() + 6 * p, ref.work.data() + p,
                                     Isa::generic);
        for (std::size_t p = 0; p < n; ++p) {
            const double *s = &start.s.stress[6 * p], *de = &start.de[6 * p];
            Eigen::Matrix3d S, E;
            S << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
            E << de[0], de[3] / 2, de[5] / 2, de[3] / 2, de[1], de[4] / 2, de[5] / 2, de[4] / 2,
                de[2];
            const double V = start.s.J[p] * start.s.vol0[p];
            const double expect =
                start.s.work[p] + 0.5 * V * (start.work[p] + (S.cwiseProduct(E)).sum());
            EXPECT_NEAR(ref.s.work[p], expect, 1e-13 * 1e5 * 0.05 * V + 1e-15 * 10.0)
                << "n " << n << ", point " << p;
        }
        for (Isa isa : runnable_isas()) {
            Block b = make();
            talus::stress_work_block(b.s, 0, n, b.de.data(), b.work.data(), isa);
            EXPECT_EQ(0, std::memcmp(b.s.work.data(), ref.s.work.data(), n * sizeof(double)))
                << talus::isa_name(isa) << ", n " << n;
        }
    }
}
