// The transposes between N points of C consecutive doubles and C vectors of
// N lanes (lanes.hpp, load_points / store_points), which the kinematics'
// packs use for F, L, stress and strain increment. Checked against their
// definition, lane k of vector c <-> base[C k + c], for every width the
// kernels use and every component count (4: plane strain's F), on values whose bits must come
// through unchanged (distinct values, -0, a NaN with a payload, a
// denormal): a transpose only moves values. The 8-lane networks are plain
// vector code, so this runs on any x86-64 (on one without AVX-512 the
// compiler splits the vectors), whatever the machine's kernels are.
#include "kernels/lanes.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace {

std::vector<double> points(int n, int c) {
    std::vector<double> v(static_cast<std::size_t>(n * c));
    for (std::size_t i = 0; i < v.size(); ++i)
        v[i] = 1000.0 * static_cast<double>(i / static_cast<std::size_t>(c)) +
               static_cast<double>(i % static_cast<std::size_t>(c)) + 0.25;
    v[1] = -0.0;
    std::uint64_t payload = 0x7ff8000000001234ull;
    std::memcpy(&v[3], &payload, sizeof payload);
    v[v.size() - 2] = std::numeric_limits<double>::denorm_min();
    return v;
}

template <int N, int C>
void check() {
    using V = typename talus::Lanes<N>::V;
    const std::string where = "N " + std::to_string(N) + ", C " + std::to_string(C);
    const std::vector<double> in = points(N, C);
    V lanes[C];
    talus::load_points<N>(in.data(), lanes);
    for (int c = 0; c < C; ++c)
        for (int k = 0; k < N; ++k) {
            const double got = lanes[c][k];
            EXPECT_EQ(0, std::memcmp(&got, &in[static_cast<std::size_t>(C * k + c)], 8))
                << where << ", lane " << k << " of component " << c;
        }
    std::vector<double> out(in.size(), 7.0);
    talus::store_points<N>(out.data(), lanes);
    EXPECT_EQ(0, std::memcmp(out.data(), in.data(), in.size() * sizeof(double))) << where;
}

} // namespace

TEST(Lanes, PointsToLanesAndBackAreTransposes) {
    check<2, 4>();
    check<4, 4>();
    check<8, 4>();
    check<2, 6>();
    check<2, 9>();
    check<4, 6>();
    check<4, 9>();
    check<8, 6>();
    check<8, 9>();
}

#if TALUS_HAS_SHUFFLEVECTOR
// The 4 x 8 transposes of P2G's records and G2P's sums (lanes_to_quads,
// quads_to_lanes): against their definition, quantity i of point j <->
// out[quad_at(j) + i], with quad_at placing the 8 points' groups of four
// in disjoint places that fill the 32 doubles.
TEST(Lanes, LanesToQuadsAndBackAreTransposes) {
    using V = talus::Lanes<8>::V;
    const std::vector<double> in = points(8, 4); // point j's quantity i at 4 j + i
    V q[4];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 8; ++j)
            std::memcpy(reinterpret_cast<double *>(&q[i]) + j,
                        &in[static_cast<std::size_t>(4 * j + i)], 8);
    std::vector<double> out(32, 7.0);
    talus::lanes_to_quads(q, out.data());
    std::vector<int> hits(32, 0);
    for (std::size_t j = 0; j < 8; ++j)
        for (std::size_t i = 0; i < 4; ++i) {
            const std::size_t at = talus::quad_at(j) + i;
            ASSERT_LT(at, 32u);
            ++hits[at];
            EXPECT_EQ(0, std::memcmp(&out[at], &in[4 * j + i], 8))
                << "quantity " << i << " of point " << j;
        }
    for (int h : hits)
        EXPECT_EQ(h, 1); // every place once: the 8 groups fill the 32
    V back[4];
    talus::quads_to_lanes(out.data(), back);
    EXPECT_EQ(0, std::memcmp(back, q, sizeof q));
}
#endif
