// Snapshot and restore: the state a run continues from (talus/mpm/snapshot.hpp).
#include "simulation_state.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <optional>
#include <type_traits>

namespace talus {

namespace {

template <class T>
constexpr Snapshot::Type type_of() {
    if constexpr (std::is_same_v<T, double>)
        return Snapshot::Type::f64;
    else if constexpr (std::is_same_v<T, std::int64_t>)
        return Snapshot::Type::i64;
    else if constexpr (std::is_same_v<T, std::int32_t>)
        return Snapshot::Type::i32;
    else {
        static_assert(std::is_same_v<T, std::uint32_t>);
        return Snapshot::Type::u32;
    }
}

// A plane-strain F as checkpoint formats 1 and 2 stored it, the whole 3x3,
// made the in-plane block ParticleSet::F keeps (F_xx, F_xy, F_yx, F_yy); taken
// only if the rest is what plane strain leaves it, F_zz = 1 and the others 0,
// exactly. The caller checks the block as it checks any column.
Snapshot::Column plane_F(const Snapshot::Column &c, std::size_t si, const ParticleSet &set) {
    Snapshot::Column out{c.name, c.type, 4, std::vector<std::byte>(set.n * 4 * sizeof(double))};
    for (std::size_t p = 0; p < set.n; ++p) {
        double F[9];
        std::memcpy(F, c.bytes.data() + 9 * sizeof(double) * p, sizeof F);
        for (int a : {2, 5, 6, 7, 8})
            if (F[a] != (a == 8 ? 1.0 : 0.0))
                throw Error(fmt::format(
                    "the snapshot's particle set {} holds an F out of the plane at particle {} "
                    "(component {} is {}, plane strain keeps {}): the checkpoint is damaged",
                    si, set.id[p], a, F[a], a == 8 ? 1 : 0));
        const double block[4] = {F[0], F[1], F[3], F[4]};
        std::memcpy(out.bytes.data() + sizeof block * p, block, sizeof block);
    }
    return out;
}

} // namespace

Snapshot Simulation::snapshot() const {
    const Impl &g = *impl_;
    Snapshot s;
    s.step = g.step;
    s.time = g.time;
    s.last_dt = g.last_dt;
    s.max_speed = g.max_speed;
    s.removed = g.removed;
    s.held_at_faces = g.held_at_faces;
    s.held_depth = g.held_depth;
    s.cut_steps = g.materials.cut_steps();
    s.warned_dt = g.warned_dt;
    s.stage = g.stage;
    s.stage_start = g.stage_start;
    s.gravity_before = g.gravity_before;
    s.hold = g.hold;
    s.below_since = g.below_since;
    s.ratio = g.ratio;
    s.out_of_order = g.order.out_of_order();
    s.slabs_changed = g.order.slabs_changed();
    s.batch_size = g.opt.batch_size;
    s.sort_disorder = g.opt.sort_disorder;
    if (g.comm.distributed()) {
        s.rank = g.comm.rank();
        for (int r = 0; r < g.decomp.ranks(); ++r) {
            const CellBox &b = g.decomp.box(r);
            s.boxes.push_back({b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]});
        }
    }
    for (std::size_t si = 0; si < g.sets.size(); ++si) {
        // for_each_named_column walks a mutable set; nothing is changed.
        auto &set = const_cast<ParticleSet &>(g.sets[si]);
        Snapshot::Set out;
        out.material = set.material;
        out.n = set.n;
        set.for_each_named_column([&](const char *name, auto &col, std::size_t stride) {
            using T = typename std::decay_t<decltype(col)>::value_type;
            Snapshot::Column c{name, type_of<T>(), stride, {}};
            c.bytes.resize(set.n * stride * sizeof(T));
            if (!c.bytes.empty()) std::memcpy(c.bytes.data(), col.data(), c.bytes.size());
            out.columns.push_back(std::move(c));
        });
        out.slab_of = g.order.slabs(si);
        s.sets.push_back(std::move(out));
    }
    return s;
}

void Simulation::Impl::restore_from(const Snapshot &snap) {
    if (snap.sets.size() != sets.size())
        throw Error(fmt::format("the snapshot holds {} particle sets, the scenario makes {}",
                                snap.sets.size(), sets.size()));
    if (snap.stage >= stages.size())
        throw Error(fmt::format("the snapshot is in stage {}, the scenario has {}", snap.stage + 1,
                                stages.size()));
    std::vector<std::vector<std::int32_t>> slabs;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &set = sets[si];
        const Snapshot::Set &in = snap.sets[si];
        if (in.material != set.material)
            throw Error(fmt::format("the snapshot's particle set {} is of material {}, the "
                                    "scenario's of material {}",
                                    si, in.material, set.material));
        set.resize(in.n);
        std::size_t k = 0;
        set.for_each_named_column([&](const char *name, auto &col, std::size_t stride) {
            using T = typename std::decay_t<decltype(col)>::value_type;
            std::optional<Snapshot::Column> converted;
            if (set.dim == 2 && std::strcmp(name, "F") == 0 && k < in.columns.size() &&
                in.columns[k].name == name && in.columns[k].stride == 9 &&
                in.columns[k].type == Snapshot::Type::f64 &&
                in.columns[k].bytes.size() == in.n * 9 * sizeof(double))
                converted = plane_F(in.columns[k], si, set);
            const Snapshot::Column *c = converted               ? &*converted
                                        : k < in.columns.size() ? &in.columns[k]
                                                                : nullptr;
            if (!c || c->name != name || c->type != type_of<T>() || c->stride != stride ||
                c->bytes.size() != in.n * stride * sizeof(T))
                throw Error(fmt::format(
                    "the snapshot's particle set {} does not have the column '{}' the scenario "
                    "needs (of {} values per particle){}",
                    si, name, stride,
                    c ? fmt::format("; it has '{}' there", c->name) : std::string()));
            if (in.n > 0) std::memcpy(col.data(), c->bytes.data(), c->bytes.size());
            // Every value a run holds is finite (a step that makes one
            // otherwise fails), so a checkpoint with one is damaged; and the
            // plugins are told their inputs are finite
            // (TALUS_BATCH_INPUTS_FINITE): the state comes in only from
            // their screened outputs, the scenario, or here.
            if constexpr (std::is_floating_point_v<T>)
                for (std::size_t i = 0; i < in.n * stride; ++i)
                    if (!std::isfinite(col[i]))
                        throw Error(fmt::format(
                            "the snapshot's particle set {} holds a non-finite value ({}) in "
                            "'{}' of particle {}: the checkpoint is damaged",
                            si, col[i], name, set.id[i / stride]));
            ++k;
        });
        if (k != in.columns.size())
            throw Error(fmt::format("the snapshot's particle set {} has {} columns, the scenario "
                                    "needs {}",
                                    si, in.columns.size(), k));
        if (!in.slab_of.empty() && in.slab_of.size() != in.n)
            throw Error(fmt::format("the snapshot's particle set {} has {} ordering marks for {} "
                                    "particles",
                                    si, in.slab_of.size(), in.n));
        slabs.push_back(in.slab_of);
    }
    step = snap.step;
    time = snap.time;
    last_dt = snap.last_dt;
    max_speed = snap.max_speed;
    removed = snap.removed;
    held_at_faces = snap.held_at_faces;
    held_depth = snap.held_depth;
    materials.set_cut_steps(snap.cut_steps);
    warned_dt = snap.warned_dt;
    stage = snap.stage;
    stage_start = snap.stage_start;
    gravity_before = snap.gravity_before;
    const StageSpec &st = stages[stage];
    // Every particle on several ranks: the boundary comes with this rank's
    // box (distribute()).
    if (!(comm.distributed() && snap.boxes.empty()))
        boundary = Boundary(sc, st.conditions, grid, stage_start, comm);
    loads = Loads(sc, st.conditions, gravity_before, stage_start);
    domain = domain_of(sc, st.conditions);
    hold = snap.hold;
    below_since = snap.below_since;
    ratio = snap.ratio;
    order.restore(sets, std::move(slabs), snap.out_of_order, snap.slabs_changed);
}

} // namespace talus
