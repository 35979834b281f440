// The material update (seed 000 phase 3): per block of points of one
// material, the kinematics from each point's velocity gradient into
// per-thread scratch, the plugin call through the C ABI (the end stress
// over the particle's, the start stress as the model gets it and the end
// state in scratch), and the commit of the state. One pass over the
// points; the strain increment, density and start F and stress of a step
// never live in the particle arrays.
#pragma once

#include "method/kinematics.hpp"
#include "parallel/parallel.hpp"
#include "state/grid.hpp"

#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/material_hook.hpp>
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

// What one material update covers.
struct Increment {
    double t = 0.0, dt = 0.0;
    long step = 0; // the step being computed (0: the initial state)
    // With cell-averaged dilation: the cells' sums (dilation_sums) and the
    // grid that locates the points' cells.
    const DilationCells *dilation = nullptr;
    const GridGeometry *geo = nullptr;
};

// The first failures of an update pass, the same whatever the thread count:
// an inverted point (its block's plugin is not called) and a failed call.
struct UpdateFailures {
    par::FirstFailure<Inversion> inverted;
    par::FirstFailure<MaterialFailure> material;
};

class MaterialUpdate {
  public:
    // `characteristic_length`: what the plugins see as each point's length
    // (the grid's cell size; talus_batch.characteristic_length); `isa`:
    // the instruction set of the kinematics (kinematics_block).
    // `hook`: SolverOptions::material_hook, or null.
    MaterialUpdate(MaterialNames names, int batch_size, double characteristic_length, Isa isa,
                   MaterialBlockHook hook = nullptr);

    // The set-up call (talus_model.init_state, or update with dt = 0) for
    // points [begin, begin + count) of set s at time t: particles that
    // appear, or change material, in the middle of a run.
    void start(std::vector<ParticleSet> &sets, std::size_t set, std::size_t begin,
               std::size_t count, double t, UpdateFailures &failures);

    // Points per block (the plugin's batch).
    std::size_t block_size() const { return batch_; }
    // Grows the per-thread scratch for these sets and the current thread
    // count; before any parallel use of block() or gradient_buffer().
    void prepare(const std::vector<ParticleSet> &sets);

    // Every point of every set over `inc`, from its stored velocity
    // gradient (ParticleSet::L), or with `stored_L` false from L = 0 (the
    // initial state: with dt = 0 the plugins see a zero increment).
    void run(std::vector<ParticleSet> &sets, const Increment &inc, bool stored_L,
             UpdateFailures &failures);
    // Points [begin, begin + count) of set s, count <= block_size(), with
    // velocity gradients L (kinematics.hpp, Gradients): kinematics, the
    // plugin call (sub-stepped on a cut-step request), then the state and
    // the stress work committed. Called from any thread.
    void block(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count,
               const Gradients &L, const Increment &inc, UpdateFailures &failures);
    // The calling thread's buffer for a block's gradients, by columns
    // (Gradients::columns): component c of point k at c * block_size() + k;
    // zero where never written.
    double *gradient_buffer();

    // Plugin cut-step requests honoured by sub-stepping so far.
    long cut_steps() const { return cut_steps_; }
    void set_cut_steps(long n) { cut_steps_ = n; } // a restored run's count
    // Adds up the threads' cut steps since the last call.
    void collect();

  private:
    // One call's inputs and where its outputs go: the particle arrays and
    // block scratch, or a part of a cut step in scratch.
    struct Inputs {
        const double *stress, *state, *F_start, *F_end, *de, *rho;
        const double *rotation; // null unless the model wants it
        // Every value above finite (densities also positive), as the
        // kinematics found them (TALUS_BATCH_INPUTS_FINITE); never for the
        // parts of a cut step, whose densities come from interpolated F.
        bool finite = false;
    };
    struct Outputs {
        double *stress, *state;
    };
    // The buffers of one level of cut-step splitting: the part's kinematics
    // and two output buffers the parts alternate between.
    struct Level {
        std::vector<double> F_start, F_end, de, rho, stress[2], state[2];
        std::vector<double> identity; // the rotation of every part but the first
    };
    // Per thread, sized once by prepare(): no allocation in a step.
    struct Scratch {
        std::vector<double> L;                            // a fused G2P's gradients
        std::vector<double> F_start, de, rho, work_start; // the block's kinematics
        std::vector<double> F_end;        // plane strain: the whole F at the end (ParticleSet::F)
        std::vector<double> rotation;     // its increment's rotations, when asked
        std::vector<double> length;       // the characteristic length, per point
        std::vector<double> stress_start; // the start stress as the model gets it
        std::vector<double> state;        // the end state, before commit
        std::deque<Level> levels; // grown at the end while deeper levels run: references hold
        long cuts = 0;
    };
    // Puts back the F points [begin, begin + count) had at the start of
    // the step (from the block's F_start) after a failed step.
    static void restore_F(ParticleSet &s, std::size_t begin, std::size_t count,
                          const double *F_start);
    bool advance(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count, double t,
                 double dt, long step, double fraction, std::size_t depth, const Inputs &in,
                 const Outputs &out, Scratch &scr, MaterialFailure &failure);
    MaterialNames names_;
    std::size_t batch_;
    double length_;
    Isa isa_;
    MaterialBlockHook hook_;
    std::vector<Scratch> scratch_;
    long cut_steps_ = 0;
};

} // namespace talus
