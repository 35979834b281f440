// The run loop's steps at the thread count the ThreadGovernor chooses from
// their measured wall times (thread_governor.hpp): on one rank with more
// than one thread, unless the user fixed the count. The step itself knows
// nothing of it; the count changes between steps, which changes no bit.
#pragma once

#include "thread_governor.hpp"

#include <talus/mpm/simulation.hpp>

#include <iosfwd>
#include <optional>
#include <vector>

namespace talus {

class GovernedSteps {
  public:
    // Governs when `adapt` is set, the run is on one rank and has more than
    // one thread to choose from.
    GovernedSteps(bool adapt, const Comm &comm);
    // Gives the process back the threads the run began with, whatever
    // count it ended on.
    ~GovernedSteps();
    GovernedSteps(const GovernedSteps &) = delete;
    GovernedSteps &operator=(const GovernedSteps &) = delete;

    // One step of at most max_dt, timed, then the count for the next.
    void step(Simulation &sim, double max_dt);

    // Steps taken at each count (index = count; empty when not governed)
    // and how often the count changed.
    const std::vector<long> &steps_at() const;
    long changes() const { return governor_ ? governor_->changes() : 0; }
    // A line for the log when the count changed: the run's speed depends
    // on it. (Probes alone, a few steps each on fewer threads, are not
    // worth one.)
    void report(std::ostream &log) const;

  private:
    std::optional<ThreadGovernor> governor_;
};

} // namespace talus
