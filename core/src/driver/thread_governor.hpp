// The thread count of each step, chosen from the steps' measured wall
// times: on a machine where another process takes a core, a thread that
// loses it holds the others at every barrier of the step, and a model whose
// steps are shorter than a scheduler's time slice then runs slower on two
// threads than on one (docs/performance.md, "Synchronisation, and a busy
// core"). The run's results do not depend on the thread count (the P2G
// colours and the per-thread partials are merged in a fixed order,
// docs/theory.md, "Parallel execution"), so the count can change between
// any two steps without changing a bit.
//
// The policy is a measured A/B. Steps are timed in windows of at least
// `window_seconds` and `window_steps` steps; the first step after a change
// of count is not counted (caches refill on the cores that take the
// work). Every `interval` windows at the chosen count, one window runs at
// a nearby count of the ladder (all threads, all but one, then halves
// down to one; one and two rungs either way, in turn). That count is taken
// when its steps are faster than the chosen count's last 4 windows by
// `margin`; a probe already slower after `window_steps` steps ends
// there. A probe that loses doubles the interval, up to
// `longest_interval`, so that on a steady machine the probes cost under a
// percent. A change brings it back to `first_interval`, so that the run
// follows the machine's load, except a change back to the count left at
// the previous change, which doubles that count's interval: a lucky
// window then does not make the run flip back and forth.
//
// Policy only: the caller times the steps and applies threads().
#pragma once

#include <array>
#include <vector>

namespace talus {

class ThreadGovernor {
  public:
    struct Settings {
        double window_seconds = 0.05;
        int window_steps = 2;
        int first_interval = 4;
        int longest_interval = 128;
        double margin = 0.10;
    };

    // Counts from 1 to max_threads (at least 1); starts at max_threads.
    explicit ThreadGovernor(int max_threads, Settings settings);
    explicit ThreadGovernor(int max_threads) : ThreadGovernor(max_threads, Settings{}) {}

    // The count for the next step.
    int threads() const { return running_; }
    // The step just taken, at threads(), took this many seconds of wall
    // time. May change threads().
    void took(double seconds);

    // For the run's report: steps taken at each count (index = count) and
    // how often the chosen count changed.
    const std::vector<long> &steps_at() const { return steps_at_; }
    int max_threads() const { return ladder_.back(); }
    long changes() const { return changes_; }

  private:
    void start_window();
    int next_probe(); // a rung of the ladder near the chosen one
    void adopt_probe();
    void end_probe();
    void remember(double seconds, long steps);

    Settings set_;
    std::vector<int> ladder_; // ascending
    std::vector<long> steps_at_;
    int chosen_ = 1;  // index into ladder_
    int running_ = 1; // the count of the current window
    bool probing_ = false;
    int probe_turn_ = 0;
    bool warm_up_ = false; // the next step is not counted
    double window_time_ = 0.0;
    int window_count_ = 0;
    // The chosen count's last windows (the probes' baseline).
    struct Window {
        double seconds = 0.0;
        long steps = 0;
    };
    static constexpr int kRecent = 4;
    std::array<Window, kRecent> recent_{};
    int next_recent_ = 0;
    double baseline_ = 0.0; // the chosen count's seconds per step, for the probe
    int windows_at_chosen_ = 0;
    int interval_;
    int left_before_ = -1;    // the rung the last change left
    int interval_before_ = 0; // the interval it had then
    long changes_ = 0;
};

} // namespace talus
