#include "fp_environment.hpp"

#include <talus/material/plugin_loader.hpp>

#include <fmt/format.h>

#include <cfenv>
#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
#define TALUS_FP_X86 1
#endif

namespace talus {

namespace {

#if TALUS_FP_X86
// MXCSR: bits 0-5 sticky flags, 6 DAZ, 7-12 exception masks, 13-14
// rounding, 15 FTZ (Intel SDM vol. 1, 10.2.3). x87 control word: bits 0-5
// exception masks, 8-9 precision, 10-11 rounding (8.1.5).
constexpr unsigned kSseControl = 0xFFC0u;

const char *rounding_name(unsigned r) {
    switch (r & 3u) {
    case 0: return "to nearest";
    case 1: return "downward";
    case 2: return "upward";
    default: return "toward zero";
    }
}

// The exceptions a mask word leaves unmasked (trapping), by name.
std::string traps(unsigned masks) {
    static const char *names[] = {"invalid",  "denormal",  "divide-by-zero",
                                  "overflow", "underflow", "inexact"};
    std::string s;
    for (unsigned k = 0; k < 6; ++k)
        if (!(masks & (1u << k))) s += (s.empty() ? "" : ", ") + std::string(names[k]);
    return s.empty() ? "none" : s;
}
#endif

} // namespace

FpControl fp_control() noexcept {
    FpControl c;
#if TALUS_FP_X86
    unsigned short cw = 0;
    __asm__ volatile("fnstcw %0" : "=m"(cw));
    c.x87 = cw;
    c.sse = _mm_getcsr() & kSseControl;
#else
    c.x87 = static_cast<unsigned>(std::fegetround());
#endif
    return c;
}

void set_fp_control(const FpControl &c) noexcept {
#if TALUS_FP_X86
    const auto cw = static_cast<unsigned short>(c.x87);
    __asm__ volatile("fldcw %0" : : "m"(cw));
    _mm_setcsr((_mm_getcsr() & ~kSseControl) | (c.sse & kSseControl));
#else
    std::fesetround(static_cast<int>(c.x87));
#endif
}

std::string fp_difference(const FpControl &b, const FpControl &a) {
    std::string s;
    auto add = [&](const std::string &t) { s += (s.empty() ? "" : "; ") + t; };
#if TALUS_FP_X86
    const unsigned rb = (b.sse >> 13) & 3u, ra = (a.sse >> 13) & 3u;
    if (ra != rb)
        add(fmt::format("rounding {} instead of {}", rounding_name(ra), rounding_name(rb)));
    if ((a.sse ^ b.sse) & 0x8000u) add(a.sse & 0x8000u ? "flush-to-zero on" : "flush-to-zero off");
    if ((a.sse ^ b.sse) & 0x0040u)
        add(a.sse & 0x0040u ? "denormals-are-zero on" : "denormals-are-zero off");
    if ((a.sse ^ b.sse) & 0x1F80u)
        add(fmt::format("SSE traps on: {} (were: {})", traps(a.sse >> 7), traps(b.sse >> 7)));
    // The x87 unit's rounding said apart only where it is not the change
    // of the SSE rounding already named (fesetround sets both).
    const unsigned xb = (b.x87 >> 10) & 3u, xa = (a.x87 >> 10) & 3u;
    if (xa != xb && !(ra != rb && xa == ra))
        add(fmt::format("x87 rounding {} instead of {}", rounding_name(xa), rounding_name(xb)));
    if ((a.x87 ^ b.x87) & ~0x0C00u)
        add(fmt::format("x87 control word 0x{:04x} instead of 0x{:04x} (traps on: {})", a.x87,
                        b.x87, traps(a.x87)));
#else
    add(fmt::format("rounding mode {} instead of {}", a.x87, b.x87));
#endif
    return s;
}

void FpGuard::restore(const FpControl &now) const noexcept {
    set_fp_control(saved_);
    try {
        library_.note_fp_change(model_, call_, fp_difference(saved_, now));
    } catch (...) {
    }
}

} // namespace talus
