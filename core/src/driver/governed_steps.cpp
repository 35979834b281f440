#include "governed_steps.hpp"

#include <fmt/format.h>

#include <chrono>
#include <ostream>
#include <string>

namespace talus {

GovernedSteps::GovernedSteps(bool adapt, const Comm &comm) {
    if (adapt && !comm.distributed() && Simulation::max_threads() > 1)
        governor_.emplace(Simulation::max_threads());
}

GovernedSteps::~GovernedSteps() {
    if (governor_) Simulation::set_threads(governor_->max_threads());
}

void GovernedSteps::step(Simulation &sim, double max_dt) {
    if (!governor_) {
        sim.step(max_dt);
        return;
    }
    const auto started = std::chrono::steady_clock::now();
    sim.step(max_dt);
    const int before = governor_->threads();
    governor_->took(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count());
    if (governor_->threads() != before) Simulation::set_threads(governor_->threads());
}

const std::vector<long> &GovernedSteps::steps_at() const {
    static const std::vector<long> none;
    return governor_ ? governor_->steps_at() : none;
}

void GovernedSteps::report(std::ostream &log) const {
    if (changes() == 0) return;
    std::string counts;
    const std::vector<long> &at = steps_at();
    for (std::size_t k = 1; k < at.size(); ++k)
        if (at[k] > 0)
            counts +=
                fmt::format("{}{} step(s) on {} thread(s)", counts.empty() ? "" : ", ", at[k], k);
    log << fmt::format("talus: threads chosen by the steps' measured times beside the "
                       "machine's other load: {} ({} change(s); --threads N fixes them)\n",
                       counts, changes());
}

} // namespace talus
