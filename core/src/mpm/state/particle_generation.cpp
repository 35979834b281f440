#include "state/particle_generation.hpp"

#include <talus/material/plugin_loader.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace talus {

namespace {

ParticleSet new_set(const Scenario &sc, std::size_t material, ColumnsInUse columns,
                    const MaterialInstance *instance) {
    ParticleSet s;
    const NamedMaterial &m = sc.materials[material];
    s.material = material;
    s.instance = instance;
    s.finite_strain = m.spec.model->finite_strain();
    s.wants_rotation = m.spec.model->wants_rotation();
    s.state_size = m.spec.state.size;
    s.rho0 = m.spec.density;
    s.dim = sc.dim;
    s.has_C = columns.C;
    s.has_divv = columns.divv;
    s.has_L = columns.L;
    s.has_dx = columns.dx;
    s.has_lp = columns.lp;
    return s;
}

// A group's lattice: ppc points per direction per cell at the centres of
// the sub-cells, over its shape's bounding box and one spacing more. Its
// points are numbered row by row (a row: the points along x at one y and
// z), which is the order of the group's particle ids.
struct Lattice {
    std::array<int, 3> lo{0, 0, 0}, hi{0, 1, 1}; // point indices [lo, hi)
    double sub = 0.0;                            // spacing
    std::size_t rows() const {
        return static_cast<std::size_t>(hi[1] - lo[1]) * static_cast<std::size_t>(hi[2] - lo[2]);
    }
};

Lattice lattice_of(const Scenario &sc, const GroupSpec &gs) {
    const int D = sc.dim;
    const Box bb = gs.shape.bounds(D);
    Lattice lat;
    lat.sub = sc.cell / gs.particles_per_cell;
    // A shape reaching more than one lattice spacing past the grid is
    // refused before the search: the search would run over the lattice far
    // beyond the grid (for a shape placed far away, with indices past the
    // range of an int). Within that band the search finds any particle
    // outside the grid.
    for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
        const double g0 = sc.origin[d], g1 = sc.origin[d] + sc.size[d];
        if (!(bb.min[d] >= g0 - lat.sub && bb.max[d] <= g1 + lat.sub))
            throw Error(gs.shape_origin.error(fmt::format(
                "group '{}' reaches outside the grid: its shape spans [{}, {}] m in {}, "
                "the grid [{}, {}] m; enlarge grid.size or move the shape",
                gs.name, bb.min[d], bb.max[d], "xyz"[d], g0, g1)));
    }
    for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
        lat.lo[d] = static_cast<int>(std::floor((bb.min[d] - sc.origin[d]) / lat.sub)) - 1;
        lat.hi[d] = static_cast<int>(std::ceil((bb.max[d] - sc.origin[d]) / lat.sub)) + 1;
    }
    return lat;
}

// Calls f(x) for each point of the shape in part `part` of `parts` of the
// lattice's rows (a contiguous run of rows, in id order). Throws for a
// point of the shape outside the grid.
template <class F>
void for_each_point(const Scenario &sc, const GroupSpec &gs, const Lattice &lat, int part,
                    int parts, F &&f) {
    const int D = sc.dim;
    const std::size_t rows = lat.rows(), ny = static_cast<std::size_t>(lat.hi[1] - lat.lo[1]);
    const std::size_t P = static_cast<std::size_t>(parts), r = static_cast<std::size_t>(part);
    for (std::size_t row = rows * r / P; row < rows * (r + 1) / P; ++row) {
        const int j = lat.lo[1] + static_cast<int>(row % ny);
        const int k = lat.lo[2] + static_cast<int>(row / ny);
        for (int i = lat.lo[0]; i < lat.hi[0]; ++i) {
            const std::array<double, 3> x = {sc.origin[0] + (i + 0.5) * lat.sub,
                                             sc.origin[1] + (j + 0.5) * lat.sub,
                                             D == 3 ? sc.origin[2] + (k + 0.5) * lat.sub : 0.0};
            if (!gs.shape.contains(x.data(), D)) continue;
            for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d)
                if (x[d] < sc.origin[d] || x[d] > sc.origin[d] + sc.size[d])
                    throw Error(gs.shape_origin.error(fmt::format(
                        "group '{}' has particles outside the grid (at {} = {:.6g} m; the "
                        "grid spans [{:.6g}, {:.6g}] m); enlarge grid.size or move the shape",
                        gs.name, "xyz"[d], x[d], sc.origin[d], sc.origin[d] + sc.size[d])));
            f(x);
        }
    }
}

// "(x, y)" or "(x, y, z)", for messages.
std::string position_text(const double *x, int dim) {
    return dim == 3 ? fmt::format("({:g}, {:g}, {:g})", x[0], x[1], x[2])
                    : fmt::format("({:g}, {:g})", x[0], x[1]);
}

// A field's value at x; an expression that fails there or gives no finite
// number is the input's mistake, reported where the expression is.
double field_value(const SpatialField &f, const double *x, const Origin &origin, int dim) {
    if (f.is_constant()) return f.constant();
    double v = 0.0;
    try {
        v = f(x);
    } catch (const ExpressionError &e) {
        throw Error(origin.error(e.what()));
    }
    if (!std::isfinite(v))
        throw Error(origin.error(fmt::format("the expression \"{}\" gives {} at the particle at {}",
                                             f.text(), v, position_text(x, dim))));
    return v;
}

// The stress at t = 0 at height x[D-1]: uniform, or geostatic
// sigma_v = rho g (surface - height), tension positive, sigma_h = K0 sigma_v.
void initial_stress(const Scenario &sc, const GroupSpec &gs, const Box &bounds, double rho0,
                    const Vec3 &gravity, const double *x, double *sig) {
    const int D = sc.dim;
    std::fill_n(sig, 6, 0.0);
    if (gs.stress.kind == InitialStress::Kind::given)
        for (std::size_t k = 0; k < 6; ++k)
            sig[k] = field_value(gs.stress.components[k], x, gs.stress_origin, sc.dim);
    if (gs.stress.kind != InitialStress::Kind::geostatic) return;
    const std::size_t up = static_cast<std::size_t>(D - 1);
    const double surface = gs.stress.surface.value_or(bounds.max[up]);
    const double sv = rho0 * gravity[up] * std::max(0.0, surface - x[up]);
    for (int d = 0; d < 3; ++d)
        sig[d] = d == D - 1 ? sv : gs.stress.k0 * sv;
}

// Particle p of set s at x, of group gi (whose shape's bounding box is bb):
// every column at its initial value.
void place(const Scenario &sc, std::size_t gi, const Box &bb, const std::vector<double> &q_init,
           const Vec3 &gravity, const std::array<double, 3> &x, ParticleSet &s, std::size_t p) {
    const GroupSpec &gs = sc.groups[gi];
    const int D = sc.dim;
    s.group[p] = static_cast<std::int32_t>(gi);
    // v = v0 + w x (x - centre): a rigid motion about the bounding box's centre.
    const Vec3 &w = gs.angular_velocity;
    double r[3] = {0, 0, 0};
    for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d)
        r[d] = x[d] - 0.5 * (bb.min[d] + bb.max[d]);
    const double wxr[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2],
                           w[0] * r[1] - w[1] * r[0]};
    for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
        s.x[d][p] = s.x0[d][p] = x[d];
        s.v[d][p] = field_value(gs.velocity[d], x.data(), gs.velocity_origin, D) + wxr[d];
    }
    // The reader refuses such speeds given as numbers; expressions give
    // theirs only here.
    const double speed = std::hypot(s.v[0][p], s.v[1][p], D == 3 ? s.v[2][p] : 0.0);
    if (!(speed < kSpeedOfLight))
        throw Error((gs.velocity_origin.key.empty() ? gs.origin : gs.velocity_origin)
                        .error(fmt::format(
                            "a speed of {:g} m/s at the particle at {} is not a velocity of a "
                            "continuum (faster than light); check the expression and its units",
                            speed, position_text(x.data(), D))));
    const double V0 = std::pow(sc.cell / gs.particles_per_cell, D);
    s.vol0[p] = V0;
    s.mass[p] = s.rho0 * V0;
    if (s.has_lp) s.lp[p] = 0.5 / gs.particles_per_cell;
    static constexpr double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    s.set_F(p, identity);
    s.J[p] = 1.0;
    initial_stress(sc, gs, bb, s.rho0, gravity, x.data(), &s.stress[6 * p]);
    std::copy(q_init.begin(), q_init.end(), s.state.data() + p * s.state_size);
    for (const GroupSpec::StateValue &sv : gs.initial_state)
        s.state[p * s.state_size + sv.index] = field_value(sv.value, x.data(), gs.state_origin, D);
    if (s.has_C) {
        // The affine transfers start from the rigid motion's exact velocity
        // gradient, skew(w).
        double *C = &s.C[9 * p];
        C[1] = -w[2];
        C[2] = w[1];
        C[3] = w[2];
        C[5] = -w[0];
        C[6] = -w[1];
        C[7] = w[0];
    }
}

} // namespace

std::vector<ParticleSet>
make_sets(const Scenario &sc, ColumnsInUse columns,
          const std::vector<std::unique_ptr<MaterialInstance>> &instances) {
    std::vector<ParticleSet> sets;
    for (std::size_t m : materials_in_use(sc))
        sets.push_back(new_set(sc, m, columns, instances[m].get()));
    return sets;
}

std::size_t set_of_material(const std::vector<ParticleSet> &sets, std::size_t material) {
    for (std::size_t k = 0; k < sets.size(); ++k)
        if (sets[k].material == material) return k;
    throw std::logic_error("no particle set for a material in use");
}

GroupIds group_ids(const Scenario &sc, const Comm &comm) {
    const std::size_t G = sc.groups.size(), P = static_cast<std::size_t>(comm.size());
    const std::size_t me = static_cast<std::size_t>(comm.rank());
    // counts[g P + r]: group g's particles in rank r's rows.
    std::vector<long> counts(G * P, 0);
    together(comm, [&] {
        for (std::size_t g = 0; g < G; ++g) {
            const GroupSpec &gs = sc.groups[g];
            long n = 0;
            for_each_point(sc, gs, lattice_of(sc, gs), comm.rank(), comm.size(),
                           [&](const std::array<double, 3> &) { ++n; });
            counts[g * P + me] = n;
        }
    });
    comm.sum(counts.data(), counts.size());
    GroupIds ids;
    std::int64_t next = 0;
    for (std::size_t g = 0; g < G; ++g) {
        const GroupSpec &gs = sc.groups[g];
        ids.first.push_back(next);
        std::int64_t mine = next;
        for (std::size_t r = 0; r < P; ++r) {
            if (r == me) mine = next;
            next += counts[g * P + r];
        }
        ids.share_first.push_back(mine);
        if (next == ids.first.back())
            fail_together(comm, gs.shape_origin.error(fmt::format(
                                    "group '{}' contains no particle: its shape holds no point "
                                    "of the {}-per-cell lattice (make it larger or raise "
                                    "particles_per_cell)",
                                    gs.name, gs.particles_per_cell)));
    }
    return ids;
}

void add_group(const Scenario &sc, std::size_t gi, const Vec3 &gravity, std::int64_t first_id,
               std::vector<ParticleSet> &sets, const Comm &comm) {
    const GroupSpec &gs = sc.groups[gi];
    const std::size_t up = static_cast<std::size_t>(sc.dim - 1);
    if (gs.stress.kind == InitialStress::Kind::geostatic && !(gravity[up] < 0.0))
        throw Error(gs.stress_origin.error(
            fmt::format("a geostatic initial stress needs gravity pointing down the last "
                        "axis ({}) when the group appears, got {:g} m/s^2 (set gravity:)",
                        sc.dim == 2 ? "y" : "z", gravity[up])));
    ParticleSet &s = sets[set_of_material(sets, gs.material)];
    std::vector<std::array<double, 3>> points;
    for_each_point(sc, gs, lattice_of(sc, gs), comm.rank(), comm.size(),
                   [&](const std::array<double, 3> &x) { points.push_back(x); });
    const std::vector<double> &q_init = sc.materials[gs.material].spec.initial_state;
    const Box bb = gs.shape.bounds(sc.dim);
    const std::size_t first = s.n;
    s.resize(first + points.size());
    for (std::size_t k = 0; k < points.size(); ++k) {
        s.id[first + k] = first_id + static_cast<std::int64_t>(k);
        place(sc, gi, bb, q_init, gravity, points[k], s, first + k);
    }
}

// A load or a fixity that acts on nothing is a mistake in its box or
// group, not a no-op.
void select_particles(const Scenario &sc, const Conditions &c, std::vector<ParticleSet> &sets,
                      std::string_view when, const Comm &comm) {
    const int D = sc.dim;
    std::vector<double> load_used(c.loads.size(), 0.0), fix_used(c.particle_velocities.size(), 0.0);
    for (ParticleSet &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            const double x[3] = {s.x[0][p], s.x[1][p], D == 3 ? s.x[2][p] : 0.0};
            const auto gi = static_cast<std::size_t>(s.group[p]);
            std::uint32_t lm = 0, fm = 0;
            for (std::size_t l = 0; l < c.loads.size(); ++l) {
                const Load &ld = c.loads[l];
                if ((!ld.group || *ld.group == gi) && (!ld.box || ld.box->contains(x, D))) {
                    lm |= 1u << l;
                    load_used[l] = 1.0;
                }
            }
            for (std::size_t f = 0; f < c.particle_velocities.size(); ++f) {
                const ParticleVelocity &pv = c.particle_velocities[f];
                if ((!pv.group || *pv.group == gi) && (!pv.box || pv.box->contains(x, D))) {
                    fm |= 1u << f;
                    fix_used[f] = 1.0;
                }
            }
            s.load_mask[p] = lm;
            s.fix_mask[p] = fm;
        }
    if (comm.distributed()) {
        comm.max(load_used.data(), load_used.size());
        comm.max(fix_used.data(), fix_used.size());
    }
    const std::string what =
        fmt::format("selects no particle (its box and group have no particle in common {})", when);
    for (std::size_t k = 0; k < c.loads.size(); ++k)
        if (load_used[k] == 0.0) fail_together(comm, c.loads[k].origin.error(what));
    for (std::size_t k = 0; k < c.particle_velocities.size(); ++k)
        if (fix_used[k] == 0.0) fail_together(comm, c.particle_velocities[k].origin.error(what));
}

} // namespace talus
