// The kinematics of a block of material points, across the vector lanes.
//
// The per-point work (F, J, rho, strain increment, the Hughes-Winget
// rotation of the start stress) is a few dozen multiplies and adds and two
// divisions on values that sit 9 or 6 doubles apart in the particle and
// ABI arrays. Point by point it is scalar code bound by its operation count
// and its divisions; the compiler does not vectorise it across points by
// itself (it finds no vector type for the 9-double groups). Here N
// consecutive points are loaded into the N lanes of a vector (one lane per
// point), computed together and stored back to their places: N points for
// the cost of about one, less the loads and stores
// (bench/results/2026-11-24-material-block-and-what-was-tried-epyc-zen4.md).
//
// This file is compiled without contraction of multiplies and adds into
// fused multiply-adds (-ffp-contract=off, core/CMakeLists.txt): every lane
// then rounds as the scalar code does, whatever the instruction set, so the
// packs, the scalar remainder and dilation_sums (which recomputes J) agree
// to the last bit, and so do runs on machines with different vector widths.
#include "method/kinematics.hpp"

#include "kernels/lanes.hpp"

#include <algorithm>
#include <cstring>
#include <utility>

namespace talus {

namespace {

// F at the end of the step, F1 = (I + dt L) F0 (eq. 39), and its
// determinant J. L is row-major 3x3; in plane strain only the in-plane
// block of F changes. T: double, or a vector of doubles (one point a lane).
template <int D, class T, class LT>
[[gnu::always_inline]] inline void deformation(const T (&F0)[9], const LT (&L)[9], double dt,
                                               T (&F1)[9], T &J) {
    if constexpr (D == 2) {
        const T a00 = 1.0 + dt * L[0], a01 = dt * L[1], a10 = dt * L[3], a11 = 1.0 + dt * L[4];
        F1[0] = a00 * F0[0] + a01 * F0[3];
        F1[1] = a00 * F0[1] + a01 * F0[4];
        F1[3] = a10 * F0[0] + a11 * F0[3];
        F1[4] = a10 * F0[1] + a11 * F0[4];
        F1[2] = F1[5] = F1[6] = F1[7] = T{};
        F1[8] = F0[8];
        J = (F1[0] * F1[4] - F1[1] * F1[3]) * F1[8];
    } else {
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                F1[3 * i + j] = F0[3 * i + j] + dt * (L[3 * i] * F0[j] + L[3 * i + 1] * F0[3 + j] +
                                                      L[3 * i + 2] * F0[6 + j]);
        J = F1[0] * (F1[4] * F1[8] - F1[5] * F1[7]) - F1[1] * (F1[3] * F1[8] - F1[5] * F1[6]) +
            F1[2] * (F1[3] * F1[7] - F1[4] * F1[6]);
    }
}

// One point, scalar: the reference the packs reproduce, and the points
// that do not fill a pack. False if the point inverted (its J is kept, so
// that the error shows the value that failed; nothing else is written).
template <int D, bool Rotate>
[[gnu::always_inline]] inline bool one_point(ParticleSet &s, std::size_t p, std::size_t k,
                                             const Gradients &Lg, double dt,
                                             const BlockIncrement &out, double *divv) {
    double F0[9], L[9], F1[9];
    s.F_of(p, F0);
    std::memcpy(out.F_start + 9 * k, F0, sizeof F0);
    Lg.copy(k, L);
    double J;
    deformation<D>(F0, L, dt, F1, J);
    s.J[p] = J;
    if (!(J > 0.0)) [[unlikely]]
        return false;
    s.set_F(p, F1);
    if constexpr (D == 2) std::memcpy(out.F_end + 9 * k, F1, sizeof F1);
    out.rho[k] = s.rho0 / J;
    double *de = out.de + 6 * k;
    strain_increment(L, dt, de);
    if (divv) divv[k] = L[0] + L[4] + L[8];
    double *sig = out.stress_start + 6 * k;
    std::memcpy(sig, &s.stress[6 * p], 6 * sizeof(double));
    if constexpr (Rotate) hughes_winget(L, dt, sig);
    out.work_start[k] = stress_work(sig, de);
    // x - x is 0 for a finite x and NaN otherwise; so is the sum.
    double nonfinite = (J - J) + (out.rho[k] - out.rho[k]);
    for (int c = 0; c < 6; ++c)
        nonfinite += (de[c] - de[c]) + (sig[c] - sig[c]);
    if (!(nonfinite == 0.0)) *out.finite = false;
    return true;
}

// The block in packs of N points, the rest point by point. A pack with an
// inverted point, or (plane strain) a spin off the plane, goes point by
// point too: nothing of it is stored before those tests.
template <int N, int D, bool Rotate>
[[gnu::always_inline]] inline std::size_t block_packs(ParticleSet &s, std::size_t begin,
                                                      std::size_t count, const Gradients &L,
                                                      double dt, const BlockIncrement &out) {
    using V = typename Lanes<N>::V;
    double *divv = s.has_divv ? &s.divv[begin] : nullptr;
    const double rho0 = s.rho0;
    // Lanes of ones where a pack had a value that is not finite (one_point).
    V nonfinite{};
    std::size_t k = 0;
    auto by_point = [&](std::size_t from, std::size_t to) __attribute__((always_inline)) {
        for (std::size_t j = from; j < to; ++j)
            if (!one_point<D, Rotate>(s, begin + j, j, L, dt, out, divv)) return j;
        return to;
    };
    for (; k + N <= count; k += N) {
        const std::size_t p = begin + k;
        const double *Lk = L.from(k).L;
        V Lv[9], F0[9], F1[9];
        if (L.point == 1) // columns: a vector load per component
            for (std::size_t c = 0; c < 9; ++c)
                load_vector<N>(Lk + c * L.component, Lv[c]);
        else if (L.point == 9 && L.component == 1)
            load_points<N>(Lk, Lv);
        else
            for (std::size_t c = 0; c < 9; ++c)
                load_lanes<N>(Lk + c * L.component, L.point, Lv[c]);
        const V zero{}, one = zero + 1.0;
        if constexpr (D == 3) {
            load_points_copying<N>(&s.F[9 * p], out.F_start + 9 * k, F0);
        } else { // the in-plane block, whole for the model (ParticleSet::F)
            V f[4];
            load_points<N>(&s.F[4 * p], f);
            F0[0] = f[0], F0[1] = f[1], F0[3] = f[2], F0[4] = f[3];
            F0[2] = F0[5] = F0[6] = F0[7] = zero;
            F0[8] = one;
            store_points<N>(out.F_start + 9 * k, F0);
        }
        V J;
        deformation<D>(F0, Lv, dt, F1, J);
        // An inverted point (J <= 0 or NaN), or (plane strain, rotated
        // stress) a spin off the plane: the pack goes point by point. Lanes
        // of ones where one holds (lanes.hpp, any_lane).
        V odd = J > zero ? zero : one;
        if constexpr (Rotate && D == 2)
            for (int c : {2, 5, 6, 7})
                odd += Lv[c] == zero ? zero : one;
        const bool one_by_one = any_lane<N>(odd);
        V sig[6];
        load_points<N>(&s.stress[6 * p], sig);
        if constexpr (Rotate)
            if (!one_by_one) hughes_winget_lanes<D == 3>(Lv, dt, sig);
        if (one_by_one) [[unlikely]] {
            const std::size_t done = by_point(k, k + N);
            if (done < k + N) return done;
            continue;
        }
        std::memcpy(&s.J[p], &J, sizeof J);
        const V rho = rho0 / J;
        std::memcpy(out.rho + k, &rho, sizeof rho);
        if constexpr (D == 3) {
            store_points<N>(&s.F[9 * p], F1); // over F0, copied to out.F_start
        } else {
            const V f[4] = {F1[0], F1[1], F1[3], F1[4]};
            store_points<N>(&s.F[4 * p], f);
            store_points<N>(out.F_end + 9 * k, F1);
        }
        V de[6];
        strain_increment(Lv, dt, de);
        store_points<N>(out.de + 6 * k, de);
        V w;
        stress_work(sig, de, w);
        std::memcpy(out.work_start + k, &w, sizeof w);
        if (divv) {
            const V dv = Lv[0] + Lv[4] + Lv[8];
            std::memcpy(divv + k, &dv, sizeof dv);
        }
        store_points<N>(out.stress_start + 6 * k, sig);
        V t = (J - J) + (rho - rho);
        for (int c = 0; c < 6; ++c)
            t += (de[c] - de[c]) + (sig[c] - sig[c]);
        nonfinite += t == zero ? zero : one;
    }
    if (any_lane<N>(nonfinite)) *out.finite = false;
    return by_point(k, count);
}

// Strain-increment models get the objectively rotated start stress;
// finite-strain models own their objectivity (material_abi.h).
template <int N>
[[gnu::always_inline]] inline std::size_t block_of(ParticleSet &s, std::size_t begin,
                                                   std::size_t count, const Gradients &L, double dt,
                                                   const BlockIncrement &out) {
    const bool rotate = !s.finite_strain;
    if (s.dim == 2)
        return rotate ? block_packs<N, 2, true>(s, begin, count, L, dt, out)
                      : block_packs<N, 2, false>(s, begin, count, L, dt, out);
    return rotate ? block_packs<N, 3, true>(s, begin, count, L, dt, out)
                  : block_packs<N, 3, false>(s, begin, count, L, dt, out);
}

// One version per instruction set (isa.hpp), with its vector width.
std::size_t block_generic(ParticleSet &s, std::size_t begin, std::size_t count, const Gradients &L,
                          double dt, const BlockIncrement &out) {
    return block_of<2>(s, begin, count, L, dt, out);
}
#if TALUS_HAS_ISA_VERSIONS
TALUS_TARGET_AVX2 std::size_t block_avx2(ParticleSet &s, std::size_t begin, std::size_t count,
                                         const Gradients &L, double dt, const BlockIncrement &out) {
    return block_of<4>(s, begin, count, L, dt, out);
}
TALUS_TARGET_AVX512 std::size_t block_avx512(ParticleSet &s, std::size_t begin, std::size_t count,
                                             const Gradients &L, double dt,
                                             const BlockIncrement &out) {
    return block_of<8>(s, begin, count, L, dt, out);
}
#endif

// The end stress's half of the stress work (stress_work_block), in packs
// of N points with the arithmetic of one point at a time.
template <int N>
[[gnu::always_inline]] inline void work_packs(ParticleSet &s, std::size_t begin, std::size_t count,
                                              const double *de, const double *work_start) {
    using V = typename Lanes<N>::V;
    std::size_t k = 0;
    for (; k + N <= count; k += N) {
        const std::size_t p = begin + k;
        V sig[6], d[6], J, vol0, w0, work;
        load_points<N>(&s.stress[6 * p], sig);
        load_points<N>(de + 6 * k, d);
        load_vector<N>(&s.J[p], J);
        load_vector<N>(&s.vol0[p], vol0);
        load_vector<N>(work_start + k, w0);
        load_vector<N>(&s.work[p], work);
        V w1;
        stress_work(sig, d, w1);
        work += 0.5 * J * vol0 * w0;
        work += 0.5 * J * vol0 * w1;
        store_vector<N>(&s.work[p], work);
    }
    for (; k < count; ++k) {
        const std::size_t p = begin + k;
        s.work[p] += 0.5 * s.J[p] * s.vol0[p] * work_start[k];
        s.work[p] += 0.5 * s.J[p] * s.vol0[p] * stress_work(&s.stress[6 * p], de + 6 * k);
    }
}

void work_generic(ParticleSet &s, std::size_t begin, std::size_t count, const double *de,
                  const double *work_start) {
    work_packs<2>(s, begin, count, de, work_start);
}
#if TALUS_HAS_ISA_VERSIONS
TALUS_TARGET_AVX2 void work_avx2(ParticleSet &s, std::size_t begin, std::size_t count,
                                 const double *de, const double *work_start) {
    work_packs<4>(s, begin, count, de, work_start);
}
TALUS_TARGET_AVX512 void work_avx512(ParticleSet &s, std::size_t begin, std::size_t count,
                                     const double *de, const double *work_start) {
    work_packs<8>(s, begin, count, de, work_start);
}
#endif

} // namespace

void stress_work_block(ParticleSet &s, std::size_t begin, std::size_t count, const double *de,
                       const double *work_start, Isa isa) {
#if TALUS_HAS_ISA_VERSIONS
    if (isa == Isa::avx512) return work_avx512(s, begin, count, de, work_start);
    if (isa == Isa::avx2) return work_avx2(s, begin, count, de, work_start);
#else
    (void)isa; // every instruction set runs the generic version
#endif
    work_generic(s, begin, count, de, work_start);
}

std::size_t kinematics_block(ParticleSet &s, std::size_t begin, std::size_t count,
                             const Gradients &L, double dt, const BlockIncrement &out, Isa isa) {
#if TALUS_HAS_ISA_VERSIONS
    if (isa == Isa::avx512) return block_avx512(s, begin, count, L, dt, out);
    if (isa == Isa::avx2) return block_avx2(s, begin, count, L, dt, out);
#else
    (void)isa; // every instruction set runs the generic version
#endif
    return block_generic(s, begin, count, L, dt, out);
}

std::optional<Inversion> dilation_sums(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                                       double dt, DilationCells &cells) {
    par::FirstFailure<Inversion> inverted;
    const int dim = geo.dim;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        par::for_each(s.n, [&](std::size_t p) {
            double F0[9], L[9], F_end[9];
            s.F_of(p, F0);
            std::memcpy(L, &s.L[9 * p], sizeof L);
            // The arithmetic of kinematics_block, which recomputes J: both
            // see the same value.
            if (dim == 2)
                deformation<2>(F0, L, dt, F_end, s.J[p]);
            else
                deformation<3>(F0, L, dt, F_end, s.J[p]);
            if (!(s.J[p] > 0.0)) inverted.record({si, p});
            s.divv[p] = L[0] + L[4] + L[8];
        });
    }
    if (const Inversion *first = inverted.first()) return *first;
    std::fill(cells.div.begin(), cells.div.end(), 0.0);
    std::fill(cells.vol.begin(), cells.vol.end(), 0.0);
    for (auto &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            const std::size_t c = cell_of(geo, s, p);
            const double V = s.J[p] * s.vol0[p];
            cells.div[c] += s.divv[p] * V;
            cells.vol[c] += V;
        }
    return std::nullopt;
}

} // namespace talus
