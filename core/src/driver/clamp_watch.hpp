// Material torn off a clamp: a `fixed` face holds the material at the face
// (docs/theory.md, "Boundaries"), and a point that began a distance s from
// it can move by at most about s times its stretch, so a point that began
// within h/4 of the face and has moved more than h/2 has strained by more
// than 2 next to the clamp: the clamp no longer holds it (with quadratic
// B-splines only the layer within h/2 of the face sees the clamp's node).
// A run says so once per face, with where and when, at the output times.
#pragma once

#include <talus/mpm/simulation.hpp>

#include <array>
#include <ostream>

namespace talus {

class ClampWatch {
  public:
    explicit ClampWatch(const Scenario &scenario) : sc_(scenario) {}
    // Collective (on every rank): looks at the particles now and writes a
    // warning to `log` (rank 0's) for each fixed face that loses material
    // for the first time.
    void look(const Simulation &sim, std::ostream &log);

  private:
    const Scenario &sc_;
    std::array<bool, 6> told_{};
};

} // namespace talus
