#include "move_particles.hpp"

#include "parallel.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace talus {

bool Domain::contains(const ParticleSet &s, std::size_t p, int dim) const {
    bool in = true;
    for (std::size_t d = 0; d < static_cast<std::size_t>(dim); ++d) {
        const double x = s.x[d][p];
        in = in && x >= lo[d] && x <= hi[d] && std::isfinite(x);
    }
    return in;
}

namespace {
constexpr std::size_t kNone = static_cast<std::size_t>(-1);
struct Partial {
    double speed = 0.0, depth = 0.0;
    long outside = 0, moved = 0, held = 0, descents = 0;
    // The first and last particle this partial saw, with their cells: a
    // thread's particles are one contiguous range (a static schedule), so
    // descents are counted inside it as the loop runs and across the
    // boundaries between ranges when the partials are merged in thread
    // order, in the same pass (no second loop and its barrier).
    std::size_t first = kNone, last = kNone;
    std::uint32_t first_cell = 0, last_cell = 0;
    void saw(std::size_t p, std::uint32_t cell) {
        if (last != kNone && p == last + 1) {
            if (cell < last_cell) ++descents;
        } else if (first == kNone) {
            first = p;
            first_cell = cell;
        }
        last = p;
        last_cell = cell;
    }
    void merge(const Partial &o) {
        speed = std::max(speed, o.speed);
        depth = std::max(depth, o.depth);
        outside += o.outside;
        moved += o.moved;
        held += o.held;
        descents += o.descents;
        if (o.first == kNone) return;
        if (last != kNone && o.first == last + 1 && o.first_cell < last_cell) ++descents;
        if (first == kNone) {
            first = o.first;
            first_cell = o.first_cell;
        }
        last = o.last;
        last_cell = o.last_cell;
    }
};
} // namespace

StepEnd move_particles(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                       const Domain &domain, Ordering &order, PositionStep step) {
    Partial total;
    const int D = geo.dim;
    const bool add = step == PositionStep::add_dx;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        const Ordering::Marks mark = order.marks(si, s.n);
        // The grid's normal velocity at a closed face is zero (clamped
        // basis), so the motion from the grid cannot carry a particle
        // through it by more than the round-off of the position sum (or a
        // step above the stability limit); what does is put back onto the
        // face (and counted), so that "outside" means through a free face.
        const Partial part = par::reduce<Partial>(s.n, [&](std::size_t p, Partial &r) {
            bool in = true;
            double v2 = 0.0;
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                double x = add ? s.x[dd][p] + s.dx[dd][p] : s.x[dd][p];
                if (domain.closed_lo[dd] && x < domain.lo[dd]) {
                    r.depth = std::max(r.depth, domain.lo[dd] - x);
                    x = domain.lo[dd];
                    ++r.held;
                } else if (domain.closed_hi[dd] && x > domain.hi[dd]) {
                    r.depth = std::max(r.depth, x - domain.hi[dd]);
                    x = domain.hi[dd];
                    ++r.held;
                }
                s.x[dd][p] = x;
                in = in && x >= domain.lo[dd] && x <= domain.hi[dd];
                v2 += s.v[dd][p] * s.v[dd][p];
            }
            r.outside += in ? 0 : 1;
            r.speed = std::max(r.speed, s.c[p] + std::sqrt(v2));
            // The cell, and from it the slab, with one floor per axis.
            std::size_t ci = 0, stride = 1;
            int sl = 0;
            for (int d = 0; d < D; ++d) {
                const int c = geo.cell(d, s.x[static_cast<std::size_t>(d)][p]);
                ci += static_cast<std::size_t>(c) * stride;
                stride *= static_cast<std::size_t>(geo.cells[static_cast<std::size_t>(d)]);
                if (d == order.axis()) sl = order.slab_of_cell(c);
            }
            r.moved += sl != mark.slab[p] ? 1 : 0;
            mark.slab[p] = sl;
            mark.cell[p] = static_cast<std::uint32_t>(ci);
            // Particles in a lower cell than their predecessor in memory.
            r.saw(p, static_cast<std::uint32_t>(ci));
        });
        // Sets are counted apart (no descent across two sets' arrays): the
        // set's range is forgotten before it joins the total.
        Partial counts = part;
        counts.first = counts.last = kNone;
        total.merge(counts);
    }
    order.marked(total.moved, static_cast<double>(total.descents));
    return {total.speed, total.held, total.depth, total.outside};
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
