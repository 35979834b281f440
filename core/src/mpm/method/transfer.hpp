// Velocity transfers between particles and grid, as policies the P2G and
// G2P kernels are compiled with:
//   FlipPic: v_p <- sum w v~ + alpha (v_p - sum w v) (seed 000 eq. 36);
//            alpha = 1 is FLIP, 0 is PIC;
//   Apic:    PIC plus the affine matrix C_p = B_p D_p^-1 (Jiang et al. 2015),
//            the velocity gradient for the tent-based kernels;
//   Tpic:    PIC plus the velocity gradient as C_p (Taylor PIC, eq. 29).
// Both affine transfers add m_p C_p (x_i - x_p) to the nodal momentum.
#pragma once

#include <talus/mpm/scenario.hpp>

namespace talus {

struct FlipPic {
    static constexpr bool affine = false;   // C_p in P2G
    static constexpr bool moments = false;  // G2P needs B_p (node offsets)
    static constexpr bool gradient = false; // G2P needs grad v~ for C_p
};
struct Apic {
    static constexpr bool affine = true, moments = true, gradient = true;
    // C = B D^-1 for the B-splines (D_p diagonal), grad v~ for the others.
    template <int D>
    static void affine_matrix(const double (&B)[D][D], const double (&L)[D][D], const double *dinv,
                              bool bspline, double *C) {
        for (int r = 0; r < D; ++r)
            for (int c = 0; c < D; ++c)
                C[3 * r + c] = bspline ? B[r][c] * dinv[c] : L[r][c];
    }
};
struct Tpic {
    static constexpr bool affine = true, moments = false, gradient = true;
    template <int D>
    static void affine_matrix(const double (&)[D][D], const double (&L)[D][D], const double *, bool,
                              double *C) {
        for (int r = 0; r < D; ++r)
            for (int c = 0; c < D; ++c)
                C[3 * r + c] = L[r][c];
    }
};

// Runs f.template operator()<T>() with the run's transfer policy.
template <class F>
void with_transfer(Transfer t, F &&f) {
    switch (t) {
    case Transfer::flip: f.template operator()<FlipPic>(); break;
    case Transfer::apic: f.template operator()<Apic>(); break;
    case Transfer::tpic: f.template operator()<Tpic>(); break;
    }
}

} // namespace talus
