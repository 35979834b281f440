#include "thread_governor.hpp"

#include <algorithm>

namespace talus {

ThreadGovernor::ThreadGovernor(int max_threads, Settings settings)
    : set_(settings), interval_(settings.first_interval) {
    const int n = std::max(1, max_threads);
    // All threads, all but one (one core taken by another process), then
    // halves: a few probes reach any count a loaded machine favours.
    for (int k = n; k >= 1; k /= 2)
        ladder_.push_back(k);
    ladder_.push_back(n - 1);
    std::erase_if(ladder_, [](int k) { return k < 1; });
    std::sort(ladder_.begin(), ladder_.end());
    ladder_.erase(std::unique(ladder_.begin(), ladder_.end()), ladder_.end());
    chosen_ = static_cast<int>(ladder_.size()) - 1;
    running_ = n;
    steps_at_.assign(static_cast<std::size_t>(n) + 1, 0);
}

int ThreadGovernor::next_probe() {
    // One and two rungs either way, in turn: two, so that a rung that is
    // no better (all but one thread on an idle machine) does not hide the
    // one beyond it.
    constexpr int kOffsets[] = {-1, +1, -2, +2};
    for (int tries = 0; tries < 4; ++tries) {
        const int i = chosen_ + kOffsets[probe_turn_ % 4];
        probe_turn_ = (probe_turn_ + 1) % 4;
        if (i >= 0 && i < static_cast<int>(ladder_.size())) return i;
    }
    return chosen_; // not reached: the ladder has two rungs at least here
}

void ThreadGovernor::start_window() {
    window_time_ = 0.0;
    window_count_ = 0;
}

void ThreadGovernor::took(double seconds) {
    ++steps_at_[static_cast<std::size_t>(running_)];
    if (ladder_.size() == 1) return; // one thread: nothing to choose
    if (warm_up_) {
        warm_up_ = false;
        return;
    }
    if (!(seconds >= 0.0)) {
        // A clock that went back: not a measurement. A probe that cannot
        // be measured is given up, so that it does not last.
        if (probing_) {
            start_window();
            end_probe();
        }
        return;
    }
    window_time_ += seconds;
    ++window_count_;
    if (window_count_ < set_.window_steps) return;
    if (probing_) {
        const double mean = window_time_ / static_cast<double>(window_count_);
        // A probe already slower than the choice ends at once (it could
        // hardly still win by the margin), so that on a steady machine the
        // probes of a slower count are a few steps each; the others run
        // their window.
        if (mean <= baseline_ && window_time_ < set_.window_seconds) return;
        if (mean < (1.0 - set_.margin) * baseline_)
            adopt_probe();
        else
            end_probe();
        start_window();
        return;
    }
    if (window_time_ < set_.window_seconds) return;
    remember(window_time_, window_count_);
    start_window();
    if (++windows_at_chosen_ < interval_) return;
    // The chosen count's mean over its last windows: it holds the rare
    // long steps (a thread descheduled for a time slice) that make a
    // loaded machine's cost, which the best window would hide, and it is
    // recent: a model's step cost drifts as it evolves (the column's
    // doubles), and an older mean would compare the probe with another
    // model.
    double time = 0.0;
    long steps = 0;
    for (const Window &w : recent_) {
        time += w.seconds;
        steps += w.steps;
    }
    baseline_ = time / static_cast<double>(steps);
    probing_ = true;
    running_ = ladder_[static_cast<std::size_t>(next_probe())];
    warm_up_ = true;
}

void ThreadGovernor::remember(double seconds, long steps) {
    recent_[static_cast<std::size_t>(next_recent_)] = {seconds, steps};
    next_recent_ = (next_recent_ + 1) % kRecent;
}

// A probe that won: its count becomes the choice, and its window the
// first measurement of it.
void ThreadGovernor::adopt_probe() {
    const int left = chosen_, left_interval = interval_;
    chosen_ =
        static_cast<int>(std::find(ladder_.begin(), ladder_.end(), running_) - ladder_.begin());
    ++changes_;
    // Back to the count left at the last change: that change was a mistake
    // (a lucky window) or the load came and went. The probes go on from
    // the interval it had, doubled, so that noise does not make the run
    // flip back and forth; otherwise soon, to follow a load that changed.
    interval_ = chosen_ == left_before_ ? std::min(2 * interval_before_, set_.longest_interval)
                                        : set_.first_interval;
    left_before_ = left;
    interval_before_ = left_interval;
    probe_turn_ = 0;
    probing_ = false;
    recent_ = {};
    remember(window_time_, window_count_);
    windows_at_chosen_ = 1;
}

// A probe that lost: back to the chosen count, and the next probe later.
void ThreadGovernor::end_probe() {
    probing_ = false;
    windows_at_chosen_ = 0;
    interval_ = std::min(2 * interval_, set_.longest_interval);
    running_ = ladder_[static_cast<std::size_t>(chosen_)];
    warm_up_ = true;
}

} // namespace talus
