#include "method/move_particles.hpp"

#include "kernels/lanes.hpp"
#include "parallel/parallel.hpp"

#include <talus/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <utility>

namespace talus {

bool Domain::contains(const ParticleSet &s, std::size_t p, int dim) const {
    bool in = true;
    for (std::size_t d = 0; d < static_cast<std::size_t>(dim); ++d) {
        const double x = s.x[d][p];
        in = in && x >= lo[d] && x <= hi[d] && std::isfinite(x);
    }
    return in;
}

using Partial = StepEndBlocks::Partial;

void Partial::saw(std::size_t from, const std::uint32_t *cell, std::size_t k, std::uint32_t far) {
    if (k == 0) return;
    long down = 0;
    if (last != kNone && from == last + 1 && Ordering::far_below(cell[0], last_cell, far)) ++down;
    for (std::size_t j = 1; j < k; ++j)
        down += Ordering::far_below(cell[j], cell[j - 1], far) ? 1 : 0;
    descents += down;
    if (first == kNone) {
        first = from;
        first_cell = cell[0];
    }
    last = from + k - 1;
    last_cell = cell[k - 1];
}

void Partial::merge(const Partial &o, std::uint32_t far) {
    speed = std::max(speed, o.speed);
    depth = std::max(depth, o.depth);
    outside += o.outside;
    moved += o.moved;
    held += o.held;
    descents += o.descents;
    for (std::size_t d = 0; d < 3; ++d) {
        cell_lo[d] = std::min(cell_lo[d], o.cell_lo[d]);
        cell_hi[d] = std::max(cell_hi[d], o.cell_hi[d]);
    }
    if (o.first == kNone) return;
    if (last != kNone && o.first == last + 1 && Ordering::far_below(o.first_cell, last_cell, far))
        ++descents;
    if (first == kNone) {
        first = o.first;
        first_cell = o.first_cell;
    }
    last = o.last;
    last_cell = o.last_cell;
}

void StepEndBlocks::begin(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                          const Domain &domain, Ordering &order, PositionStep step,
                          std::size_t block, Isa isa) {
    sets_ = &sets;
    geo_ = geo;
    domain_ = domain;
    order_ = &order;
    add_ = step == PositionStep::add_dx;
    isa_ = isa;
    block_ = std::max<std::size_t>(1, block);
    misfiled_.store(false, std::memory_order_relaxed);
    marks_.resize(sets.size());
    partials_.resize(sets.size());
    for (std::size_t si = 0; si < sets.size(); ++si) {
        marks_[si] = order.marks(si, sets[si].n);
        // Every block is written by its pass: no reset needed, only the size.
        partials_[si].resize((sets[si].n + block_ - 1) / block_);
    }
}

namespace {

// The step's end for the points of a block from `begin`, in packs of N,
// one point a vector lane (N = 2, 4, 8 on the generic, AVX2, AVX-512
// builds; N = 1 for the block's last few): each point's position moved
// (or x + dx), put back onto a closed face it went through, its cell and
// slab marked, and the block's maxima and counts gathered in r. Returns how
// many points it did (a multiple of N), r continuing from where it was.
//
// The grid's normal velocity at a closed face is zero (clamped basis), so
// the motion from the grid cannot carry a particle through it by more than
// the round-off of the position sum (or a step above the stability limit);
// what does is put back onto the face (and counted), so that "outside"
// means through a free face.
//
// Written once for every width, the results do not depend on N: every lane
// does its arithmetic (the sums of v^2 in the same order, this file
// compiled without fused multiply-adds), and the rest are maxima, counts
// and integers. The cells are computed in doubles (exact: whole numbers
// below 2^53) and converted to int32 at the end, which every target has in
// vector form (the 64-bit conversions need AVX-512DQ).
template <int N, int D, bool Add>
[[gnu::always_inline]] inline std::size_t end_points(ParticleSet &s, const Ordering::Marks mark,
                                                     const GridGeometry &geo, const Domain &domain,
                                                     const Ordering &order, std::size_t begin,
                                                     std::size_t count, Partial &r) {
    using V = typename Lanes<N>::V;
    typedef std::int32_t I32 __attribute__((vector_size(N * sizeof(std::int32_t))));
    if (count < N) return 0;
    // Every test is a compare of doubles selecting doubles, and the counts
    // are sums of ones in doubles (exact below 2^53): the compiler builds the
    // lanes of an integer mask one by one from scalar compares. An open
    // face's bound is an infinity, which nothing passes (nor NaN).
    constexpr double inf = std::numeric_limits<double>::infinity();
    V lo[D], hi[D], stop_lo[D], stop_hi[D], origin[D], last_cell[D];
    double *x[D];
    const double *dx[D], *v[D];
    for (int d = 0; d < D; ++d) {
        const std::size_t dd = static_cast<std::size_t>(d);
        lo[d] = V{} + domain.lo[dd];
        hi[d] = V{} + domain.hi[dd];
        stop_lo[d] = V{} + (domain.closed_lo[dd] ? domain.lo[dd] : -inf);
        stop_hi[d] = V{} + (domain.closed_hi[dd] ? domain.hi[dd] : inf);
        origin[d] = V{} + geo.origin[dd];
        last_cell[d] = V{} + static_cast<double>(geo.cells[dd] - 1);
        x[d] = s.x[dd].data();
        dx[d] = Add ? s.dx[dd].data() : nullptr;
        v[d] = s.v[dd].data();
    }
    const double inv_h = geo.inv_h;
    const int axis = order.axis();
    const V last_slab = V{} + static_cast<double>(order.n_slabs() - 1);
    const double *c = s.c.data();
    V speeds = V{} + r.speed;
    V depth = V{} + r.depth;
    V outside{}, held{}, moved{};
    // The arms of every select are vectors: with a scalar arm the compiler
    // builds the result lane by lane, through branches.
    const V zero{}, one = zero + 1.0;
    // The cells' range per axis, lane by lane (whole numbers in doubles).
    V cell_lo[D], cell_hi[D];
    for (int d = 0; d < D; ++d) {
        cell_lo[d] = zero + static_cast<double>(geo.cells[static_cast<std::size_t>(d)]);
        cell_hi[d] = zero - 1.0;
    }
    std::size_t k = 0;
    for (; k + N <= count; k += N) {
        const std::size_t p = begin + k;
        V out{}, v2{}, ci{}, sl{};
        double stride = 1.0;
        for (int d = 0; d < D; ++d) {
            V xd, vd;
            load_vector<N>(x[d] + p, xd);
            load_vector<N>(v[d] + p, vd);
            if constexpr (Add) {
                V step;
                load_vector<N>(dx[d] + p, step);
                xd = xd + step;
            }
            // Through a closed face: back onto it, counted, the overshoot
            // kept (only one of the two can hold). Selects of one condition
            // each: nested ones sharing their conditions the compiler builds
            // lane by lane. Where the scalar loop takes 0 as the overshoot
            // (inside, or at an open face), these are negative, -inf or NaN,
            // none of which the maximum (from 0) takes.
            held += xd < stop_lo[d] ? one : zero;
            held += xd > stop_hi[d] ? one : zero;
            const V under = stop_lo[d] - xd, over = xd - stop_hi[d];
            depth = depth < under ? under : depth;
            depth = depth < over ? over : depth;
            xd = xd < stop_lo[d] ? stop_lo[d] : xd;
            xd = xd > stop_hi[d] ? stop_hi[d] : xd;
            store_vector<N>(x[d] + p, xd);
            // Sums, not a select of a select: the compiler folds that into an
            // AND of two masks, which it builds lane by lane without AVX-512DQ.
            out += xd >= lo[d] ? zero : one;
            out += xd <= hi[d] ? zero : one;
            v2 += vd * vd;
            // GridGeometry::clamped_cell: NaN and below 0 to 0, at or past
            // the last cell to it, else truncated.
            V xi = (xd - origin[d]) * inv_h;
            xi = xi >= zero ? xi : zero;
            xi = xi >= last_cell[d] ? last_cell[d] : xi;
            const V cd = __builtin_convertvector(__builtin_convertvector(xi, I32), V);
            cell_lo[d] = cd < cell_lo[d] ? cd : cell_lo[d];
            cell_hi[d] = cd > cell_hi[d] ? cd : cell_hi[d];
            ci += cd * stride;
            stride *= static_cast<double>(geo.cells[static_cast<std::size_t>(d)]);
            if (d == axis) {
                // Ordering::slab_of_cell; kWidth is a power of two, so the
                // quotient is exact and truncating it is the integer division.
                static_assert((Ordering::kWidth & (Ordering::kWidth - 1)) == 0);
                const V q = __builtin_convertvector(
                    __builtin_convertvector(cd * (1.0 / Ordering::kWidth), I32), V);
                sl = q < last_slab ? q : last_slab;
            }
        }
        outside += out > zero ? one : zero;
        // The square roots as one vector instruction (this file is compiled
        // without errno for sqrt, which kept them one by one: N scalar
        // roots a pack); correctly rounded either way.
        // The maximum lane by lane as std::max takes it (a NaN never
        // enters), the lanes' maxima taken after the loop: one dependent
        // select a pack instead of N. The speeds are positive or +0
        // (c >= 0, a root >= +0), so the order of the maxima cannot change
        // the result. (Skipping the packs that cannot pass the maximum so
        // far was slower: in a block of nearly equal wave speeds many can.)
        V root;
        for (int i = 0; i < N; ++i)
            root[i] = std::sqrt(v2[i]);
        V cv;
        load_vector<N>(c + p, cv);
        const V speed = cv + root;
        speeds = speeds < speed ? speed : speeds;
        I32 old_slab;
        std::memcpy(&old_slab, mark.slab + p, sizeof old_slab);
        moved += sl == __builtin_convertvector(old_slab, V) ? zero : one;
        const I32 new_slab = __builtin_convertvector(sl, I32);
        std::memcpy(mark.slab + p, &new_slab, sizeof new_slab);
        // The cell as a uint32 (below 2^32: Marks): shifted into int32's
        // range for the conversion and back by its top bit.
        const I32 shifted = __builtin_convertvector(ci - 2147483648.0, I32);
        const I32 cell = shifted ^ static_cast<std::int32_t>(0x80000000u);
        std::memcpy(mark.cell + p, &cell, sizeof cell);
    }
    for (int i = 0; i < N; ++i)
        r.speed = std::max(r.speed, speeds[i]);
    for (int d = 0; d < D; ++d)
        for (int i = 0; i < N; ++i) {
            const std::size_t dd = static_cast<std::size_t>(d);
            r.cell_lo[dd] = std::min(r.cell_lo[dd], static_cast<int>(cell_lo[d][i]));
            r.cell_hi[dd] = std::max(r.cell_hi[dd], static_cast<int>(cell_hi[d][i]));
        }
    for (int i = 0; i < N; ++i) {
        r.depth = std::max(r.depth, depth[i]);
        r.outside += static_cast<long>(outside[i]);
        r.held += static_cast<long>(held[i]);
        r.moved += static_cast<long>(moved[i]);
    }
    // Descents in the cell order, from the cells just written.
    r.saw(begin, mark.cell + begin, k, order.far());
    return k;
}

template <int N, int D, bool Add>
[[gnu::always_inline]] inline void end_block_lanes(ParticleSet &s, const Ordering::Marks mark,
                                                   const GridGeometry &geo, const Domain &domain,
                                                   const Ordering &order, std::size_t begin,
                                                   std::size_t count, Partial &r) {
    const std::size_t k = end_points<N, D, Add>(s, mark, geo, domain, order, begin, count, r);
    end_points<1, D, Add>(s, mark, geo, domain, order, begin + k, count - k, r);
}

// One version per instruction set (isa.hpp), with its vector width.
template <int D, bool Add>
void end_generic(ParticleSet &s, const Ordering::Marks mark, const GridGeometry &geo,
                 const Domain &domain, const Ordering &order, std::size_t begin, std::size_t count,
                 Partial &r) {
    end_block_lanes<2, D, Add>(s, mark, geo, domain, order, begin, count, r);
}
template <int D, bool Add>
TALUS_TARGET_AVX2 void end_avx2(ParticleSet &s, const Ordering::Marks mark, const GridGeometry &geo,
                                const Domain &domain, const Ordering &order, std::size_t begin,
                                std::size_t count, Partial &r) {
    end_block_lanes<4, D, Add>(s, mark, geo, domain, order, begin, count, r);
}
template <int D, bool Add>
TALUS_TARGET_AVX512 void end_avx512(ParticleSet &s, const Ordering::Marks mark,
                                    const GridGeometry &geo, const Domain &domain,
                                    const Ordering &order, std::size_t begin, std::size_t count,
                                    Partial &r) {
    end_block_lanes<8, D, Add>(s, mark, geo, domain, order, begin, count, r);
}

} // namespace

void StepEndBlocks::block(std::size_t set, std::size_t begin, std::size_t count) {
    if (begin % block_ != 0 || count > block_) [[unlikely]] {
        misfiled_.store(true, std::memory_order_relaxed);
        return;
    }
    ParticleSet &s = (*sets_)[set];
    Partial r;
    auto run = [&]<int D, bool Add>() {
        const Ordering::Marks mark = marks_[set];
        if constexpr (TALUS_HAS_ISA_VERSIONS) {
            if (isa_ == Isa::avx512)
                return end_avx512<D, Add>(s, mark, geo_, domain_, *order_, begin, count, r);
            if (isa_ == Isa::avx2)
                return end_avx2<D, Add>(s, mark, geo_, domain_, *order_, begin, count, r);
        }
        end_generic<D, Add>(s, mark, geo_, domain_, *order_, begin, count, r);
    };
    if (geo_.dim == 2)
        add_ ? run.template operator()<2, true>() : run.template operator()<2, false>();
    else
        add_ ? run.template operator()<3, true>() : run.template operator()<3, false>();
    partials_[set][begin / block_] = r;
}

StepEnd StepEndBlocks::finish() {
    if (misfiled_.load(std::memory_order_relaxed))
        throw Error(fmt::format("internal error: the step's end was given a block that does not "
                                "start at a multiple of its block size ({} particles)",
                                block_));
    Partial total;
    for (const std::vector<Partial> &set : partials_) {
        Partial part;
        for (const Partial &b : set)
            part.merge(b, order_->far());
        // Sets are counted apart (no descent across two sets' arrays): the
        // set's range is forgotten before it joins the total.
        part.first = part.last = Partial::kNone;
        total.merge(part, order_->far());
    }
    order_->marked(total.moved, static_cast<double>(total.descents));
    StepEnd end{total.speed, total.held, total.depth, total.outside};
    end.cell_lo = total.cell_lo;
    end.cell_hi = total.cell_hi;
    return end;
}

StepEnd move_particles(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                       const Domain &domain, Ordering &order, PositionStep step,
                       StepEndBlocks &blocks, Isa isa) {
    constexpr std::size_t kBlock = 1024;
    blocks.begin(sets, geo, domain, order, step, kBlock, isa);
    for (std::size_t si = 0; si < sets.size(); ++si) {
        const std::size_t n = sets[si].n;
        par::for_each_block((n + kBlock - 1) / kBlock, [&](std::size_t b) {
            blocks.block(si, b * kBlock, std::min(kBlock, n - b * kBlock));
        });
    }
    return blocks.finish();
}

Leaving collect_leaving(std::vector<ParticleSet> &sets, const Domain &domain, int dim, bool remove,
                        const std::vector<std::string> &group_names) {
    Leaving out;
    for (ParticleSet &s : sets) {
        std::size_t keep = 0;
        for (std::size_t p = 0; p < s.n; ++p) {
            if (domain.contains(s, p, dim)) {
                s.move(p, keep++);
                continue;
            }
            ++out.count;
            if (out.first.size() < 10)
                out.first.push_back(fmt::format(
                    "particle {} of group '{}' at ({:.6g}, {:.6g}{})", s.id[p],
                    group_names[static_cast<std::size_t>(s.group[p])], s.x[0][p], s.x[1][p],
                    dim == 3 ? fmt::format(", {:.6g}", s.x[2][p]) : std::string()));
            if (!remove) s.move(p, keep++); // kept for the report and the output
        }
        if (remove) s.resize(keep);
    }
    return out;
}

} // namespace talus
