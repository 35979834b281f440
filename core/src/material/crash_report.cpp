#include <talus/material/crash_report.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <stdio_ext.h>
#include <string>
#include <sys/mman.h>
#include <sys/wait.h>
#include <ucontext.h>
#include <unistd.h>

namespace talus::crash {

namespace {

thread_local const PluginCall *t_call = nullptr;
thread_local const Task *t_task = nullptr;

std::atomic<LastAction> g_action{nullptr};
std::atomic<void *> g_action_context{nullptr};
std::atomic<int> g_entered{0};

std::atomic<int> g_rank{-1}, g_ranks{0};

// The plugin call that returned last, on any thread: a crash outside any
// call may be its doing (a write past its arrays corrupts what the host
// uses next). Relaxed stores: a hint for the report, no order needed.
std::atomic<const char *> g_last_model{nullptr}, g_last_library{nullptr};

// The per-thread slots of mark_calls(): padded to a cache line each, so
// that a thread's stores per call never touch another's line. Threads past
// kSlots are not counted.
constexpr int kSlots = 256;
struct alignas(64) Slot {
    std::atomic<const char *> model{nullptr}, library{nullptr}, material{nullptr};
    std::atomic<unsigned long> calls{0}; // begun
    std::atomic<int> depth{0};           // > 0: inside a call
    unsigned long marked = 0;            // calls at mark_calls()
};
Slot g_slots[kSlots];
std::atomic<int> g_slots_taken{0};
thread_local Slot *t_slot = nullptr;
thread_local bool t_slot_taken = false;

Slot *my_slot() noexcept {
    if (!t_slot_taken) {
        t_slot_taken = true;
        const int i = g_slots_taken.fetch_add(1, std::memory_order_relaxed);
        if (i < kSlots) t_slot = &g_slots[i];
    }
    return t_slot;
}

// Async-signal-safe output: the message is built in a static buffer and
// written by write(2) at once (flush), so that the reports of several
// ranks crashing together do not interleave (a write of up to PIPE_BUF
// bytes to a pipe is not split). No formatting library.
char g_text[4096];
std::size_t g_used = 0;

void put(const char *s) {
    if (!s) s = "?";
    for (; *s && g_used < sizeof g_text; ++s)
        g_text[g_used++] = *s;
}

void flush() {
    const char *s = g_text;
    std::size_t n = g_used;
    while (n > 0) {
        const ssize_t w = ::write(STDERR_FILENO, s, n);
        if (w <= 0) break;
        s += w;
        n -= static_cast<std::size_t>(w);
    }
    g_used = 0;
}

void put_int(long long v) {
    char buf[24];
    int i = sizeof buf;
    buf[--i] = '\0';
    const bool neg = v < 0;
    unsigned long long u =
        neg ? 0ULL - static_cast<unsigned long long>(v) : static_cast<unsigned long long>(v);
    do {
        buf[--i] = static_cast<char>('0' + u % 10);
        u /= 10;
    } while (u > 0);
    if (neg) buf[--i] = '-';
    put(buf + i);
}

const char *signal_text(int sig) {
    switch (sig) {
    case SIGSEGV: return "SIGSEGV, invalid memory access";
    case SIGBUS: return "SIGBUS, bus error";
    case SIGFPE: return "SIGFPE, arithmetic trap";
    case SIGILL: return "SIGILL, illegal instruction";
    case SIGABRT: return "SIGABRT, abort";
    default: return "fatal signal";
    }
}

void put_who() {
    put("talus: ");
    if (g_ranks.load() > 1) {
        put("rank ");
        put_int(g_rank.load());
        put(" of ");
        put_int(g_ranks.load());
        put(": ");
    }
}

void on_alarm(int) {
    put_who();
    put("the state could not be written in time after the crash\n");
    flush();
    ::_exit(128 + SIGALRM);
}

// "model 'm' from lib, updating material 'x', group 'g', particles a..b,
// in step n": the call, and the task where the solver said what it is.
void put_call(const PluginCall *c) {
    put("model '");
    put(c->model());
    put("' from ");
    put(c->library());
    const Task *t = t_task;
    if (!t) return;
    put(", updating material '");
    put(t->material);
    put("'");
    if (t->group_names && t->group) {
        put(", group '");
        put(t->group_names[*t->group]);
        put("'");
    }
    if (t->ids && t->count > 0) {
        put(", particles ");
        put_int(t->ids[0]);
        if (t->ids[t->count - 1] != t->ids[0]) {
            put("..");
            put_int(t->ids[t->count - 1]);
        }
    }
    if (t->step > 0) {
        put(", in step ");
        put_int(t->step);
    } else {
        put(", on the initial state");
    }
}

// ---- The particle a crash is the doing of ----
//
// A batch's inputs are still as they were when the call began (a call
// writes its outputs only), so each point can be run again alone; each in a
// child process of its own (a copy of this one, which the crash or exit()
// then ends, not this process), until one ends as the call did. _Fork, not
// fork: no fork handlers run, so none can wait for a lock (malloc's) that
// the crashed call may hold.

volatile std::sig_atomic_t g_in_child = 0;
const Task *g_alone_task = nullptr;
std::size_t g_alone_k = 0;

constexpr int kReturned = 97;         // a child's status after the call returned
constexpr int kNoStack = 98;          // a child that could not map its stack
constexpr unsigned kAloneSeconds = 5; // a point's call takes microseconds
constexpr long kSearchSeconds = 30;   // the whole search
constexpr std::size_t kAloneStack = std::size_t{16} << 20; // a Fortran UMAT's arrays

void alone_entry() {
    g_alone_task->run_alone(g_alone_task->alone_context, g_alone_k);
    ::_exit(kReturned);
}

[[noreturn]] void run_alone_child(const Task *t, std::size_t k) {
    g_in_child = 1;
    // A crash ends the child by its signal, for the parent to see; a call
    // that hangs (on a lock another thread held at the fork) is ended by
    // SIGALRM.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    sigset_t unblock;
    sigemptyset(&unblock);
    for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGALRM}) {
        ::sigaction(sig, &dfl, nullptr);
        sigaddset(&unblock, sig);
    }
    ::sigprocmask(SIG_UNBLOCK, &unblock, nullptr);
    // Output the parent buffered is the parent's: an exit() in the child
    // must not write it a second time.
    __fpurge(stdout);
    __fpurge(stderr);
    ::alarm(kAloneSeconds);
    // A stack of its own: the crashed thread may be on the small signal
    // stack (install_handlers), too small for a model's call.
    void *stack = ::mmap(nullptr, kAloneStack, PROT_READ | PROT_WRITE,
                         MAP_PRIVATE | MAP_ANONYMOUS | MAP_STACK, -1, 0);
    if (stack == MAP_FAILED) ::_exit(kNoStack);
    g_alone_task = t;
    g_alone_k = k;
    static ucontext_t here, there;
    ::getcontext(&there);
    there.uc_stack.ss_sp = stack;
    there.uc_stack.ss_size = kAloneStack;
    there.uc_link = &here;
    ::makecontext(&there, alone_entry, 0);
    ::swapcontext(&here, &there);
    ::_exit(kReturned);
}

double seconds_now() {
    timespec ts{};
    ::clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Runs the task's points alone, in order, and reports the first whose call
// does not return: "talus: run alone, particle 10 (group 'lump') crashes
// in the same way (signal 11)". Ends with a newline.
void search_for_the_particle() {
    const Task *t = t_task;
    if (!t || !t->run_alone || !t->ids || t->count == 0) return;
    const double start = seconds_now();
    for (std::size_t k = 0; k < t->count; ++k) {
        if (seconds_now() - start > kSearchSeconds) {
            put_who();
            put("the search for the particle stopped after ");
            put_int(static_cast<long long>(k));
            put(" of the batch's ");
            put_int(static_cast<long long>(t->count));
            put(" points (time limit)\n");
            flush();
            return;
        }
        const pid_t pid = ::_Fork();
        if (pid < 0) {
            put_who();
            put("the batch could not be searched for the particle: fork failed\n");
            flush();
            return;
        }
        if (pid == 0) run_alone_child(t, k);
        int st = 0;
        while (::waitpid(pid, &st, 0) < 0 && errno == EINTR) {
        }
        if (WIFEXITED(st) && WEXITSTATUS(st) == kReturned) continue;
        put_who();
        if (WIFEXITED(st) && WEXITSTATUS(st) == kNoStack) {
            put("the batch could not be searched for the particle: no memory for a stack\n");
            flush();
            return;
        }
        if (WIFSIGNALED(st) && WTERMSIG(st) == SIGALRM) {
            put("the search for the particle stopped: particle ");
            put_int(t->ids[k]);
            put(" run alone did not return in ");
            put_int(kAloneSeconds);
            put(" s\n");
            flush();
            return;
        }
        put("run alone, particle ");
        put_int(t->ids[k]);
        if (t->group_names && t->group) {
            put(" (group '");
            put(t->group_names[t->group[k]]);
            put("')");
        }
        if (WIFSIGNALED(st)) {
            put(" ends in the same way: signal ");
            put_int(WTERMSIG(st));
            put(" (");
            put(signal_text(WTERMSIG(st)));
            put(")");
        } else {
            put(" ends the process (exit status ");
            put_int(WIFEXITED(st) ? WEXITSTATUS(st) : -1);
            put(")");
        }
        put("; point ");
        put_int(static_cast<long long>(k + 1));
        put(" of the batch's ");
        put_int(static_cast<long long>(t->count));
        if (k > 0) put(", the points before it return");
        put(": its input is what the plugin fails on\n");
        flush();
        return;
    }
    put_who();
    put("run alone, each of the batch's ");
    put_int(static_cast<long long>(t->count));
    put(" points returns: the fault is not one particle's input (the plugin's own data, or "
        "memory written before this call)\n");
    flush();
}

// The one last action, under a time limit, then the end with `status`.
[[noreturn]] void last_action_and_end(int status) {
    if (LastAction a = g_action.load()) {
        std::signal(SIGALRM, on_alarm);
        ::alarm(60);
        a(g_action_context.load());
        ::alarm(0);
    }
    ::_exit(status);
}

// exit() called inside a plugin call (a model that ends the process where
// it should fail the call; gfortran's STOP): the process would end with the
// plugin's status, 0 included, and the run's output cut short. Registered
// with on_exit, so it runs in the thread that called exit(), where t_call
// says whether that thread was inside a plugin; an exit elsewhere goes on.
// Registered early, it runs after every exit handler registered later
// (static destructors among them) and while other threads may still be in
// the step: the state it writes is best effort, as after a crash.
void on_exit_in_call(int status, void *) {
    if (g_in_child) ::_exit(kExitInPluginCall); // a point run alone (above)
    const PluginCall *c = t_call;
    if (!c) return;
    if (g_entered.fetch_add(1) > 0) ::_exit(kExitInPluginCall);
    put_who();
    put("fatal: the material plugin called exit(");
    put_int(status);
    put(") inside ");
    put_call(c);
    put(". A plugin must fail the call (TALUS_STATUS_FAILED with a message), never end the "
        "process: the run stops here.\n");
    flush();
    search_for_the_particle();
    last_action_and_end(kExitInPluginCall);
}

void on_fatal(int sig) {
    if (g_entered.fetch_add(1) > 0) {
        // A second fault: in another thread at the same time, or inside the
        // last action. Do not report twice.
        ::_exit(128 + sig);
    }
    put_who();
    put("fatal: signal ");
    put_int(sig);
    put(" (");
    put(signal_text(sig));
    put(")");
    if (const PluginCall *c = t_call) {
        put(" inside the material plugin: ");
        put_call(c);
        put(". The plugin is at fault, not the input: run `talus plugin check` on it, or "
            "debug it under gdb.\n");
        flush();
        search_for_the_particle();
    } else if (const char *model = g_last_model.load(std::memory_order_relaxed)) {
        put(" in talus, outside any plugin call. This may be a bug in Talus (please report it "
            "with the scenario), or the doing of a plugin that wrote past its arrays into memory "
            "Talus used later: the last plugin call to return was model '");
        put(model);
        put("' from ");
        put(g_last_library.load(std::memory_order_relaxed));
        put("; `talus plugin check` on it (its buffers check) tells which.\n");
    } else {
        put(" in talus itself, outside any plugin call. This is a bug in Talus; please report "
            "it with the scenario.\n");
    }
    flush();
    last_action_and_end(128 + sig);
}

} // namespace

PluginCall::PluginCall(const char *model, const char *library) noexcept
    : model_(model), library_(library), saved_(t_call) {
    t_call = this;
    if (Slot *s = my_slot()) {
        constexpr auto relaxed = std::memory_order_relaxed;
        s->model.store(model, relaxed);
        s->library.store(library, relaxed);
        s->material.store(t_task ? t_task->material : nullptr, relaxed);
        s->calls.store(s->calls.load(relaxed) + 1, relaxed);
        s->depth.store(s->depth.load(relaxed) + 1, relaxed);
    }
}

PluginCall::~PluginCall() {
    t_call = saved_;
    if (Slot *s = t_slot)
        s->depth.store(s->depth.load(std::memory_order_relaxed) - 1, std::memory_order_relaxed);
    // Stored only when it changes: every batch of every thread would
    // otherwise write the one cache line the threads then pass around.
    if (g_last_model.load(std::memory_order_relaxed) != model_)
        g_last_model.store(model_, std::memory_order_relaxed);
    if (g_last_library.load(std::memory_order_relaxed) != library_)
        g_last_library.store(library_, std::memory_order_relaxed);
}

TaskScope::TaskScope(const Task *task) noexcept : saved_(t_task) { t_task = task; }
TaskScope::~TaskScope() { t_task = saved_; }

std::string current_task() {
    const Task *t = t_task;
    if (!t || !t->material) return {};
    std::string s = std::string("material '") + t->material + "'";
    if (t->group_names && t->group) s += std::string(", group '") + t->group_names[*t->group] + "'";
    if (t->ids && t->count > 0) {
        s += ", particles " + std::to_string(t->ids[0]);
        if (t->ids[t->count - 1] != t->ids[0]) s += ".." + std::to_string(t->ids[t->count - 1]);
    }
    s += t->step > 0 ? ", in step " + std::to_string(t->step) : std::string(", initial state");
    return s;
}

void mark_calls() noexcept {
    const int n = std::min(g_slots_taken.load(), kSlots);
    for (int i = 0; i < n; ++i)
        g_slots[i].marked = g_slots[i].calls.load(std::memory_order_relaxed);
}

int report_calls_since_mark(const char *lead) noexcept {
    const int n = std::min(g_slots_taken.load(), kSlots);
    int stuck = 0;
    for (int i = 0; i < n; ++i) {
        const Slot &s = g_slots[i];
        if (s.depth.load() <= 0 || s.calls.load() != s.marked) continue;
        ++stuck;
        put(lead);
        put("talus: a thread has been inside one call of model '");
        put(s.model.load());
        put("' from ");
        put(s.library.load());
        if (const char *m = s.material.load()) {
            put(" (material '");
            put(m);
            put("')");
        }
        put(" since then\n");
        flush();
    }
    return stuck;
}

void install_handlers() {
    // An alternate stack, so that a plugin's stack overflow can still be
    // reported (on the main thread).
    static char stack[1 << 16];
    stack_t ss{};
    ss.ss_sp = stack;
    ss.ss_size = sizeof stack;
    ::sigaltstack(&ss, nullptr);
    struct sigaction sa {};
    sa.sa_handler = on_fatal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_ONSTACK | SA_NODEFER;
    for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT})
        ::sigaction(sig, &sa, nullptr);
    static bool exit_guard = false; // one registration: it runs once per one made
    if (!exit_guard) exit_guard = ::on_exit(on_exit_in_call, nullptr) == 0;
}

void set_rank(int rank, int ranks) noexcept {
    g_rank.store(rank);
    g_ranks.store(ranks);
}

void set_last_action(LastAction action, void *context) noexcept {
    g_action_context.store(context);
    g_action.store(action);
}

} // namespace talus::crash
