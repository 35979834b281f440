// SIGTERM and SIGINT during a run (a scheduler's kill, Ctrl-C): the run
// finishes its step, writes a checkpoint and stops (docs/restart.md). The
// first signal only raises a flag, and says so at once; a second ends the
// process at once (SA_RESETHAND). If the step has not ended 10 s after the
// first, the run says so again and names the plugin calls that have not
// returned since: a call that never returns would otherwise leave the user
// with a run that seems to ignore Ctrl-C.
#pragma once

#include <csignal>

namespace talus {

// Holds the handlers of SIGTERM, SIGINT and SIGALRM for its lifetime.
class StopSignals {
  public:
    // `tell`: this process writes the messages (rank 0 of a run that
    // reports progress); every process lists its own calls that do not
    // return.
    explicit StopSignals(bool tell);
    ~StopSignals();
    StopSignals(const StopSignals &) = delete;
    StopSignals &operator=(const StopSignals &) = delete;

  private:
    struct sigaction term_ {
    }, interrupt_{}, alarm_{};
};

// The signal that asked the run to stop, 0 for none.
int stop_signal() noexcept;
// The run has seen the signal at a step's end: no word of a step that
// does not end follows.
void stop_signal_seen() noexcept;

} // namespace talus
