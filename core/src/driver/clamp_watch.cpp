#include "clamp_watch.hpp"

#include <fmt/format.h>

#include <cmath>
#include <string>

namespace talus {

void ClampWatch::look(const Simulation &sim, std::ostream &log) {
    const Conditions &c = sim.stages()[sim.stage()].conditions;
    const double h = sc_.cell;
    const int D = sc_.dim;
    static constexpr const char *kFace[6] = {"x-", "x+", "y-", "y+", "z-", "z+"};
    for (int f = 0; f < 2 * D; ++f) {
        // Every rank takes part in the sums below, so the faces are decided
        // by what all ranks know: the conditions and told_.
        if (told_[static_cast<std::size_t>(f)] ||
            c.faces[static_cast<std::size_t>(f)].type != FaceType::fixed)
            continue;
        const std::size_t axis = static_cast<std::size_t>(f / 2);
        const double face = sc_.origin[axis] + (f % 2 == 0 ? 0.0 : sc_.size[axis]);
        long count = 0;
        double farthest = 0.0;
        std::string example;
        for (const ParticleSet &s : sim.sets())
            for (std::size_t p = 0; p < s.n; ++p) {
                if (std::abs(s.x0[axis][p] - face) > 0.25 * h) continue;
                double moved2 = 0.0;
                for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d)
                    moved2 += (s.x[d][p] - s.x0[d][p]) * (s.x[d][p] - s.x0[d][p]);
                if (moved2 <= 0.25 * h * h) continue;
                ++count;
                const double moved = std::sqrt(moved2);
                if (moved > farthest) {
                    farthest = moved;
                    example =
                        fmt::format("particle {} of group '{}' moved {:.3g} m", s.id[p],
                                    sc_.groups[static_cast<std::size_t>(s.group[p])].name, moved);
                }
            }
        const Comm &comm = sim.comm();
        const long all = comm.distributed() ? comm.sum(count) : count;
        if (all == 0) continue;
        told_[static_cast<std::size_t>(f)] = true;
        if (comm.distributed()) farthest = comm.max(farthest);
        if (comm.rank() != 0) continue;
        log << fmt::format(
            "talus: warning: step {} (t = {:.6g} s): {} particle(s) that began within h/4 of "
            "the fixed face {} have moved more than h/2 (up to {:.3g} m{}): the material next "
            "to the clamp has torn off it, or sheared by more than 200 %; the clamp holds only "
            "the layer next to the face: refine the grid there, clamp by particle_velocities "
            "over a thicker layer, or use the gimp kernel\n",
            sim.steps(), sim.time(), all, kFace[f], farthest,
            example.empty() ? std::string() : "; " + example);
    }
}

} // namespace talus
