// The material update (seed 000 phase 3, the constitutive part): every
// point's stress and state advanced by its material's plugin through the
// C ABI, in batches of points of one material spread over the threads.
#pragma once

#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/particles.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace talus {

// One plugin call that failed: where, the plugin's answer, and the failing
// point's inputs as the plugin received them (copied before the call, which
// may have written over them).
struct MaterialFailure {
    std::size_t set = 0, begin = 0, count = 0;
    double t = 0.0, dt = 0.0;
    MaterialInstance::Result result;
    std::array<double, 6> stress_in{}; // the failing point's, when result.point >= 0
    std::vector<double> state_in;
    bool before(const MaterialFailure &o) const {
        return set != o.set ? set < o.set : begin < o.begin;
    }
};

// Who to name if a plugin crashes (crash_report.hpp): plain C strings that
// outlive the run.
struct MaterialNames {
    std::vector<const char *> material; // per set
    std::vector<const char *> group;    // per group
};

class MaterialUpdate {
  public:
    MaterialUpdate(MaterialNames names, int batch_size);

    // Calls each point's plugin over [t, t + dt] (strain increment, F,
    // density as the kinematics left them), then the
    // second half of the stress work; swaps F_new into F. `step` is the
    // step being computed (0: the initial state). Returns the first failure
    // (by set and batch), after which no set's F is swapped.
    std::optional<MaterialFailure> run(std::vector<ParticleSet> &sets, double t, double dt,
                                       long step);
    // Plugin cut-step requests honoured by sub-stepping so far.
    long cut_steps() const { return cut_steps_; }

  private:
    struct Scratch {
        std::vector<double> stress0, state0;
        long cuts = 0;
    };
    bool call(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count, double t,
              double dt, long step, double fraction, Scratch &scr, MaterialFailure &failure);
    MaterialNames names_;
    std::size_t batch_;
    std::vector<Scratch> scratch_;
    long cut_steps_ = 0;
};

} // namespace talus
