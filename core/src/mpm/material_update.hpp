// The material update (seed 000 phase 3, the constitutive part): every
// point's stress and state advanced by its material's plugin through the
// C ABI, in batches of points of one material spread over the threads.
#pragma once

#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/particles.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

namespace talus {

// One plugin call that failed: where, the plugin's answer, and the failing
// point's inputs as the plugin received them (those of the failing part of
// a cut step, which are not the particle's).
struct MaterialFailure {
    std::size_t set = 0, begin = 0, count = 0;
    double t = 0.0, dt = 0.0;
    MaterialInstance::Result result;
    // The failing point's, when result.point >= 0:
    std::array<double, 6> stress_in{}, strain_increment{};
    std::array<double, 9> F_start{}, F_end{};
    double density = 0.0;
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
    // One call's inputs and where its outputs go: the particle arrays, or a
    // part of a cut step in scratch.
    struct Inputs {
        const double *stress, *state, *F_start, *F_end, *de, *rho;
    };
    struct Outputs {
        double *stress, *state;
    };
    // The buffers of one level of cut-step splitting: the part's kinematics
    // and two output buffers the parts alternate between.
    struct Level {
        std::vector<double> F_start, F_end, de, rho, stress[2], state[2];
    };
    // Per thread, grown once to the batch size: no allocation in a step.
    struct Scratch {
        std::vector<double> stress, state; // the batch's outputs before commit
        std::deque<Level> levels; // grown at the end while deeper levels run: references hold
        long cuts = 0;
    };
    bool advance(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count, double t,
                 double dt, long step, double fraction, std::size_t depth, const Inputs &in,
                 const Outputs &out, Scratch &scr, MaterialFailure &failure);
    MaterialNames names_;
    std::size_t batch_;
    std::vector<Scratch> scratch_;
    long cut_steps_ = 0;
};

} // namespace talus
