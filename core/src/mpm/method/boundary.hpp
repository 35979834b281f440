// Boundary conditions on a nodal velocity field (seed 004 step 2.4): the
// faces' conditions, prescribed nodal velocities in boxes, and the grid
// side of particle velocity fixities.
#pragma once

#include "state/grid.hpp"

#include <talus/mpm/comm.hpp>
#include <talus/mpm/scenario.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace talus {

class Boundary {
  public:
    // No conditions (a placeholder until the grid is known).
    Boundary() = default;
    // The conditions `c` of a stage that began at t0 (its functions are of
    // the time since). Finds the nodes of each prescribed-velocity box;
    // throws (at the entry's place in the file) if a box holds none, on
    // any of `comm`'s ranks (collective).
    Boundary(const Scenario &sc, const Conditions &c, const Grid &grid, double t0,
             const Comm &comm = Comm::serial());

    // Applies every condition at (the run's) time t to the velocity at
    // `offset` of the node records `field` (Grid::vel at node::velocity(dim)
    // or kEndVelocity, or another field laid out the same way), at the nodes
    // of the grid's active box (Grid::active): the step's kernels read and
    // write no other. `fixity` is Grid::acc: its node::kFixity slot says
    // which fixities reach a node.
    // With Only::bilateral the contact faces (slip, friction) are left
    // alone: the grid update's start velocity where FLIP must carry a
    // wall's impulse to the particles (grid_update.hpp, StartVelocity).
    enum class Only { all, bilateral };
    void apply(const Grid &grid, double *field, std::size_t offset, const double *fixity, double t,
               Only only = Only::all) const;
    // Whether the faces carry all the conditions (no prescribed velocities,
    // no particle fixities): for_each_constrained_node then visits every
    // node a condition reads or changes.
    bool faces_only() const { return prescribed_.empty() && fixities_.empty(); }
    // With faces_only(), the nodes of the active box no condition reads or
    // changes: the box less the layers of the faces that carry a condition
    // (a box again, as those layers are its ends). With
    // for_each_constrained_node they make up the active box.
    SlotBox untouched(const Grid &grid) const;
    // Calls f(slot) for every node of the active box a face condition or a
    // prescribed velocity may change (fixity nodes excluded), some more
    // than once.
    template <class F>
    void for_each_constrained_node(const Grid &grid, F &&f) const {
        for (int face = 0; face < 6; ++face)
            if (faces_[static_cast<std::size_t>(face)].type != FaceType::free)
                for_each_node(grid, grid.face_nodes[static_cast<std::size_t>(face)], f);
        for (const Prescribed &p : prescribed_)
            for (std::uint32_t i : p.nodes)
                if (grid.active().contains(grid.local(i))) f(i);
    }

  private:
    // f(slot) for the nodes of `box` in the active box.
    template <class F>
    static void for_each_node(const Grid &grid, const SlotBox &box, F &&f) {
        box.cut(grid.active()).for_each_slot(grid.geo.extent, f);
    }
    struct Prescribed {
        std::vector<std::uint32_t> nodes;
        ComponentFunctions velocity;
    };
    int dim_ = 2;
    double t0_ = 0.0;
    std::array<FaceCondition, 6> faces_;
    std::vector<Prescribed> prescribed_;
    std::vector<ComponentFunctions> fixities_;
};

} // namespace talus
