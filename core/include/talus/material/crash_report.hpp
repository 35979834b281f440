// Who to blame when a plugin crashes. A plugin runs inside the talus process;
// a segmentation fault (or abort, bus error, illegal instruction, floating-
// point trap) in it would end the run with no word. The plugin loader marks
// every call into a plugin with the model and library, the solver adds which
// material, group, particles and step; a fatal-signal handler prints that
// (async-signal-safe), runs one best-effort last action (the run writes the
// state at that moment), and exits with 128 + the signal number. A plugin
// that calls exit() inside a call is reported the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace talus::crash {

// What the caller of a plugin is doing. Pointers must outlive the call.
// The batch's group and particle ids are read only if a report is written:
// a call costs a few stores, and no load from particle columns that the
// step does not otherwise touch, which would be a cache miss per batch
// (bench/results/2026-11-24-stencil-packs-avx2-kernels-epyc-zen4.md).
struct Task {
    const char *material = nullptr; // scenario material name
    long step = 0;                  // the step being computed (0: initial state)
    // The group of the batch's first particle: group_names[*group].
    const char *const *group_names = nullptr;
    const std::int32_t *group = nullptr;
    // The batch's particle ids, ids[0 .. count).
    const std::int64_t *ids = nullptr;
    std::size_t count = 0;
    // Calls point k of the batch alone (the plugin on the point's inputs,
    // which a call never writes). After a crash or an exit() inside the
    // call, the report runs it for each point in a child process of its
    // own, to name the particle whose input does it; null: the report
    // names the batch.
    void (*run_alone)(const void *context, std::size_t k) = nullptr;
    const void *alone_context = nullptr;
};

// Marks the current thread as inside a call to `model` of `library` (and
// `task`, when given) for its lifetime. Costs a few stores; no allocation.
class PluginCall {
  public:
    PluginCall(const char *model, const char *library) noexcept;
    ~PluginCall();
    PluginCall(const PluginCall &) = delete;
    PluginCall &operator=(const PluginCall &) = delete;
    const char *model() const { return model_; }
    const char *library() const { return library_; }

  private:
    const char *model_, *library_;
    const PluginCall *saved_;
};

// Marks the current thread's plugin calls with `task` for its lifetime.
class TaskScope {
  public:
    explicit TaskScope(const Task *task) noexcept;
    ~TaskScope();
    TaskScope(const TaskScope &) = delete;
    TaskScope &operator=(const TaskScope &) = delete;

  private:
    const Task *saved_;
};

// The exit status after a plugin called exit() inside a call (EX_SOFTWARE
// of sysexits.h: the software failed, not the input).
inline constexpr int kExitInPluginCall = 70;

// What the current thread's plugin call is doing, for a plugin's log
// message: "material 'soil', group 'slope', particles 0..63, in step 12";
// empty outside a solver's task. Not for a signal handler (it allocates).
std::string current_task();

// ---- Calls that do not return ----
// Each thread's plugin calls are counted where a signal handler can read
// them (a slot per thread, written by its own thread only), so that a run
// asked to stop can tell the user when a call it waits for does not end.

// Async-signal-safe: notes how many calls each thread has begun.
void mark_calls() noexcept;
// Async-signal-safe: writes to stderr a line for each thread still inside
// the call it was in at mark_calls(), "talus: a thread has been inside one
// call of model 'm' from lib (material 'x') since then", each line after
// `lead`; returns how many.
int report_calls_since_mark(const char *lead) noexcept;

// Installs the fatal-signal handlers and the guard against exit() inside a
// plugin call (process-wide; once is enough).
void install_handlers();

// On several MPI ranks: the report begins "talus: rank R of N:".
void set_rank(int rank, int ranks) noexcept;

// The one thing to try after the report, e.g. writing the state. It runs
// inside the signal handler, so it may fail or hang: it gets a time limit,
// and a second fault inside it ends the process at once. nullptr clears it.
using LastAction = void (*)(void *context);
void set_last_action(LastAction action, void *context) noexcept;

} // namespace talus::crash
