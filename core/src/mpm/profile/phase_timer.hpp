// The wall time of one phase call, added to that phase's total on leaving
// the scope: what Simulation::phase_seconds reports (`talus run`'s profile
// line, talus_bench).
#pragma once

#include <chrono>

namespace talus {

class PhaseTimer {
  public:
    explicit PhaseTimer(double &total) : total_(total) {}
    ~PhaseTimer() {
        total_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
    }
    PhaseTimer(const PhaseTimer &) = delete;
    PhaseTimer &operator=(const PhaseTimer &) = delete;

  private:
    double &total_;
    std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

} // namespace talus
