#include "stop_signals.hpp"

#include <talus/material/crash_report.hpp>

#include <csignal>
#include <cstring>
#include <unistd.h>

namespace talus {

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;
volatile std::sig_atomic_t g_stop_tells = 0;
// The second word comes this long after the signal; the message says it.
constexpr unsigned kStopWait = 10;

void write_stderr(const char *s) noexcept {
    std::size_t n = std::strlen(s);
    while (n > 0) {
        const ssize_t w = ::write(STDERR_FILENO, s, n);
        if (w <= 0) return;
        s += w;
        n -= static_cast<std::size_t>(w);
    }
}

const char *signal_name(int sig) noexcept { return sig == SIGTERM ? "SIGTERM" : "SIGINT"; }

extern "C" void on_stop_signal(int sig) {
    g_stop_signal = sig;
    crash::mark_calls();
    if (g_stop_tells) {
        write_stderr("\ntalus: ");
        write_stderr(signal_name(sig));
        write_stderr(": the run stops when this step ends, after writing a checkpoint; a second "
                     "signal stops it at once, without one\n");
    }
    ::alarm(kStopWait);
}

extern "C" void on_stop_wait(int) {
    const int sig = g_stop_signal;
    if (!sig) return;
    static_assert(kStopWait == 10, "the message below says 10 s");
    if (g_stop_tells) {
        write_stderr("talus: the step has not ended 10 s after ");
        write_stderr(signal_name(sig));
        write_stderr("\n");
    }
    if (crash::report_calls_since_mark("") > 0)
        write_stderr("talus: a plugin call that does not return cannot be stopped: a second "
                     "signal ends the run at once, without a checkpoint (those written before "
                     "stay)\n");
}

} // namespace

StopSignals::StopSignals(bool tell) {
    g_stop_signal = 0;
    g_stop_tells = tell ? 1 : 0;
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sa.sa_flags = SA_RESETHAND;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGTERM, &sa, &term_);
    ::sigaction(SIGINT, &sa, &interrupt_);
    struct sigaction wait {};
    wait.sa_handler = on_stop_wait;
    sigemptyset(&wait.sa_mask);
    ::sigaction(SIGALRM, &wait, &alarm_);
}

StopSignals::~StopSignals() {
    ::alarm(0);
    ::sigaction(SIGTERM, &term_, nullptr);
    ::sigaction(SIGINT, &interrupt_, nullptr);
    ::sigaction(SIGALRM, &alarm_, nullptr);
}

int stop_signal() noexcept { return g_stop_signal; }

void stop_signal_seen() noexcept { ::alarm(0); }

} // namespace talus
