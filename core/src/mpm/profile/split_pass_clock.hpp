// The time of a pass that does three phases' work block by block (the fused
// USL's G2P, which hands each block to the material update and then to the
// step's end), split into the three phases' shares, so that a profile of
// the fused step reads like one of the split pipeline.
//
// Three reads a block of the processor's cycle counter (ticks.hpp), the
// middle one shared, kept per thread (one cache line each), turned into
// seconds by the pass's own rate of ticks to seconds. Reading the system's
// clock instead would cost a call each, and under a hypervisor a slow one,
// three times for every block of a few hundred points.
#pragma once

#include "method/g2p.hpp"
#include "parallel/parallel.hpp"
#include "profile/ticks.hpp"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace talus {

// HandOff: block_size(), buffer(), and the two phases of a block,
// first(set, begin, count) and second(set, begin, count).
template <class HandOff>
class SplitPassClock final : public GradientBlocks {
  public:
    explicit SplitPassClock(HandOff &hand_off)
        : hand_off_(hand_off), ticks_(static_cast<std::size_t>(par::max_threads())) {}

    std::size_t block_size() const override { return hand_off_.block_size(); }
    double *buffer() override { return hand_off_.buffer(); }
    void take(std::size_t set, std::size_t begin, std::size_t count) override {
        const std::uint64_t t0 = ticks();
        hand_off_.first(set, begin, count);
        const std::uint64_t t1 = ticks();
        hand_off_.second(set, begin, count);
        const std::uint64_t t2 = ticks();
        Ticks &mine = ticks_[static_cast<std::size_t>(par::thread_index())];
        mine.first += ticks_between(t0, t1);
        mine.second += ticks_between(t1, t2);
    }

    // Runs pass(*this) and adds its wall time to the three phases: to
    // `first` and `second` what the blocks took of it (per thread on
    // average), to `pass_phase` the rest.
    template <class Pass>
    void run(Pass &&pass, double &pass_phase, double &first, double &second) {
        const auto s0 = std::chrono::steady_clock::now();
        const std::uint64_t t0 = ticks();
        pass(static_cast<GradientBlocks &>(*this));
        const std::uint64_t t1 = ticks();
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
        const std::uint64_t pass_ticks = ticks_between(t0, t1);
        const double per_tick = pass_ticks > 0 ? seconds / static_cast<double>(pass_ticks) : 0.0;
        const double in_first = average(&Ticks::first) * per_tick,
                     in_second = average(&Ticks::second) * per_tick;
        pass_phase += seconds - in_first - in_second;
        first += in_first;
        second += in_second;
    }

  private:
    struct alignas(64) Ticks {
        std::uint64_t first = 0, second = 0;
    };
    double average(std::uint64_t Ticks::*part) const {
        double sum = 0.0;
        for (const Ticks &t : ticks_)
            sum += static_cast<double>(t.*part);
        return sum / static_cast<double>(ticks_.size());
    }
    HandOff &hand_off_;
    std::vector<Ticks> ticks_;
};

} // namespace talus
