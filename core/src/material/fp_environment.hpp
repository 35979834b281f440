// The floating-point environment a plugin call leaves behind. The rounding
// mode, flush-to-zero, denormals-are-zero and the exception masks are the
// calling thread's, shared by the plugin and the host: a plugin that sets
// upward rounding in create would shift every later result of the solver,
// one that unmasks a trap would crash it later in Talus's own code, and a
// library built with -ffast-math sets flush-to-zero as it loads. Each call
// into a plugin (loading included) is wrapped in a FpGuard: what the call
// changed is put back when it returns, and the library records the first
// change for the run's log and `talus plugin check`.
#pragma once

#include <string>

namespace talus {

class PluginLibrary;

// The control state of the calling thread: the x87 control word and the
// control bits of MXCSR on x86-64 (its sticky exception flags, which any
// arithmetic may set, left out); fegetround() elsewhere.
struct FpControl {
    unsigned x87 = 0, sse = 0;
    friend bool operator==(const FpControl &, const FpControl &) = default;
};

FpControl fp_control() noexcept;
// Puts the control state back (the SSE exception flags kept as they are).
void set_fp_control(const FpControl &c) noexcept;
// What differs, in words: "rounding upward instead of to nearest, ...".
std::string fp_difference(const FpControl &before, const FpControl &after);

class FpGuard {
  public:
    // `model` and `call` name the call for the report ("elastic", "create";
    // both must outlive the guard).
    FpGuard(const PluginLibrary &library, const char *model, const char *call) noexcept
        : library_(library), model_(model), call_(call), saved_(fp_control()) {}
    ~FpGuard() {
        const FpControl now = fp_control();
        if (!(now == saved_)) [[unlikely]]
            restore(now);
    }
    FpGuard(const FpGuard &) = delete;
    FpGuard &operator=(const FpGuard &) = delete;

  private:
    void restore(const FpControl &now) const noexcept;
    const PluginLibrary &library_;
    const char *model_, *call_;
    FpControl saved_;
};

} // namespace talus
