// The last pass of a step (seed 000 phase 4): positions, the faces that
// hold, the leaving check, and what the next step needs from the particles
// (their slabs and cells for the ordering, max(c + |v|) for its dt).
#pragma once

#include "grid.hpp"
#include "ordering.hpp"

#include <talus/mpm/particles.hpp>

#include <array>
#include <string>
#include <vector>

namespace talus {

// The domain's box and which of its faces are closed (any condition but
// free): a closed face is impenetrable.
struct Domain {
    std::array<double, 3> lo{0, 0, 0}, hi{0, 0, 0};
    std::array<bool, 3> closed_lo{false, false, false}, closed_hi{false, false, false};
    bool contains(const ParticleSet &s, std::size_t p, int dim) const;
};

// Whether the G2P pass has moved the particles already (the fused USL
// variant) or left their step in ParticleSet::dx.
enum class PositionStep { add_dx, already_moved };

struct StepEnd {
    double max_speed = 0.0; // max over particles of c + |v|, m/s
    long held = 0;          // positions put back onto a closed face
    double held_depth = 0.0;
    long outside = 0; // particles outside the domain (through a free face)
};

StepEnd move_particles(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                       const Domain &domain, Ordering &order, PositionStep step);

// The particles outside the domain: removed (policy remove) or kept in
// place; the first few described for a report. Returns how many there were.
struct Leaving {
    long count = 0;
    std::vector<std::string> first; // "particle 12 of group 'a' at (x, y)"
};
Leaving collect_leaving(std::vector<ParticleSet> &sets, const Domain &domain, int dim, bool remove,
                        const std::vector<std::string> &group_names);

} // namespace talus
