// The kinematics of a material point over one step, from its velocity
// gradient: F (seed 000 eq. 39), J, density (eq. 41), the strain increment
// (eq. 42), div v, and the objective rotation of the start stress.
#pragma once

#include "kernels/isa.hpp"
#include "parallel/parallel.hpp"
#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/stress_rotation.hpp>

#include <cstddef>
#include <optional>
#include <vector>

namespace talus {

// The strain increment d_eps = dt sym(L) (eq. 42) in Voigt order with
// engineering shears (the ABI's), and the stress's work on it, sigma :
// d_eps, its sum in this order: written once for a double or a vector pack
// of them (T), one point a lane, so that the packs give the scalar bits.
template <class T>
[[gnu::always_inline]] inline void strain_increment(const T *L, double dt, T *de) {
    de[0] = dt * L[0];
    de[1] = dt * L[4];
    de[2] = dt * L[8];
    de[3] = dt * (L[1] + L[3]);
    de[4] = dt * (L[5] + L[7]);
    de[5] = dt * (L[2] + L[6]);
}
template <class T>
[[gnu::always_inline]] inline void stress_work(const T *sig, const T *de, T &w) {
    w = sig[0] * de[0] + sig[1] * de[1] + sig[2] * de[2] + sig[3] * de[3] + sig[4] * de[4] +
        sig[5] * de[5];
}
inline double stress_work(const double *sig, const double *de) {
    double w;
    stress_work(sig, de, w);
    return w;
}

// A particle whose J fell to zero or below: the run cannot go on.
struct Inversion {
    std::size_t set = 0, particle = 0;
    bool before(const Inversion &o) const {
        return set != o.set ? set < o.set : particle < o.particle;
    }
};

// Where a block's kinematics go: the material update's per-thread block
// scratch (nothing of it persists past the step), per point k at 9 k, 6 k
// and k.
struct BlockIncrement {
    // F at the start of the step, 9 per point, row-major: the particle's F
    // is F at the end once the kinematics are done, and this copy (of the
    // points done: the copy is taken as each pack is loaded) is what a
    // retry (cut step) or a failed step's restore starts from.
    double *F_start;
    // Plane strain: F at the end, 9 per point, for the model (the particle
    // keeps only F's in-plane block, ParticleSet::F). In 3D null: the
    // model reads the particle's F.
    double *F_end;
    // The start stress as the model gets it, 6 per point (Voigt): turned by
    // the increment's rotation for strain-increment models, as it was for
    // finite-strain ones. The particle's stress is left alone: the model
    // writes the end stress there.
    double *stress_start;
    double *de; // 6 per point, Voigt with engineering shears
    double *rho;
    // stress_work(start stress, de) per point: the start stress as the
    // model gets it (rotated for strain-increment models), for the first
    // half of the stress work's trapezoid (MaterialUpdate). Computed here,
    // where both are in the vector lanes already.
    double *work_start;
    // Set to false when a value the model gets is not finite: a strain
    // increment, a density, J (and with it F: a J that is finite comes
    // from F_start and F_end that are), the start stress as the model
    // gets it. Left alone otherwise: the caller sets it true first. The
    // material update then tells the plugin whether its inputs are finite
    // (TALUS_BATCH_INPUTS_FINITE, material_abi.h).
    bool *finite;
};

// A block's velocity gradients L (row-major 3x3 per point): component c
// of point k at L[k * point + c * component]. As the particles keep them
// (rows: 9 consecutive doubles a point), as the fused G2P leaves them in
// the material update's block scratch (columns: a component's values for
// the block's points consecutive, so that the kinematics loads N points'
// component in one vector, with no transpose), or one L for every point
// (point stride 0).
struct Gradients {
    const double *L;
    std::size_t point, component;
    static Gradients rows(const double *L) { return {L, 9, 1}; }
    static Gradients columns(const double *L, std::size_t points) { return {L, 1, points}; }
    static Gradients same(const double *L) { return {L, 0, 1}; }
    double at(std::size_t k, std::size_t c) const { return L[k * point + c * component]; }
    // The gradients from point k on.
    Gradients from(std::size_t k) const { return {L + k * point, point, component}; }
    // Point k's L, row-major.
    void copy(std::size_t k, double (&out)[9]) const {
        for (std::size_t c = 0; c < 9; ++c)
            out[c] = at(k, c);
    }
};

// Points [begin, begin + count) of s from their velocity gradients L
// (Gradients): F at the end of the step (eq. 39, in
// the particle and in plane strain in out.F_end, the start F copied to
// out.F_start as it is read), J
// (kept in the particle), rho (eq. 41), the strain increment (eq. 42), div
// v, the start stress as the model gets it (out.stress_start: for
// strain-increment models objectively rotated, Hughes-Winget), and the
// start stress's work on the increment. Returns the block index of the
// first point that inverted (J <= 0), or count; the points before it are
// done, the F of the inverted one and those after it untouched. The rest
// of the stress work is the caller's: it needs the end stress.
//
// Points go through in packs across the vector lanes of instruction set
// `isa` (kinematics.cpp), with the arithmetic of one point at a time:
// the results do not depend on `isa` or on the packing.
std::size_t kinematics_block(ParticleSet &s, std::size_t begin, std::size_t count,
                             const Gradients &L, double dt, const BlockIncrement &out, Isa isa);

// The stress work over the step of points [begin, begin + count) of s
// once the model has written their end stress: work += V/2 (start work +
// stress_work(end stress, de)) with V = J vol0, the trapezoid's two halves
// added one after the other (de and work_start as kinematics_block left
// them, per point k at 6 k and k). In packs across the vector lanes of
// `isa`, with the arithmetic of one point at a time (the stress, 6 values a
// point, is moved into the lanes by transposes). In packs rather than point
// by point after the model's call, for the kinematics' reason: N points for
// about the cost of one
// (bench/results/2026-11-26-xeon-2.1ghz-against-4eb0ad2-small-parts.md).
void stress_work_block(ParticleSet &s, std::size_t begin, std::size_t count, const double *de,
                       const double *work_start, Isa isa);

// Cell-averaged dilation (seed 000 eqs. 47-53): sums per cell, kept between
// steps to avoid reallocating them.
struct DilationCells {
    std::vector<double> div, vol;
};

inline std::size_t cell_of(const GridGeometry &geo, const ParticleSet &s, std::size_t p) {
    const double x[3] = {s.x[0][p], s.x[1][p], geo.dim == 3 ? s.x[2][p] : 0.0};
    return geo.owned_cell_index(x);
}

// The first part of cell-averaged dilation: every point's J at the end of
// the step and div v from its stored L, then each cell's volume-weighted
// sums of div v (eq. 53; the cell is the one containing the point). The
// material update then replaces each point's dilation by its cell's mean
// (dilation_correction). Returns the first inverted point, if any.
std::optional<Inversion> dilation_sums(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                                       double dt, DilationCells &cells);

// Eq. 52: what each normal strain increment in the dim in-plane directions
// gains so that the point's dilation becomes its cell's mean.
inline double dilation_correction(const DilationCells &cells, const GridGeometry &geo,
                                  const ParticleSet &s, std::size_t p, double dt) {
    const std::size_t c = cell_of(geo, s, p);
    return dt * (cells.div[c] / cells.vol[c] - s.divv[p]) / geo.dim;
}

} // namespace talus
