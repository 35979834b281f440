// A created model (MaterialInstance): its batch calls, the screen of their
// outputs, and its destruction.
#include <talus/material/plugin_loader.hpp>

#include "fp_environment.hpp"
#include "plugin_errors.hpp"

#include <talus/material/crash_report.hpp>

#include <fmt/format.h>

#include <cmath>

namespace talus {

MaterialInstance::~MaterialInstance() {
    if (instance_) {
        const crash::PluginCall call(model_->id().c_str(), library_->path().c_str());
        const FpGuard fp(*library_, model_->id().c_str(), "destroy");
        model_->raw().destroy(instance_);
    }
}

MaterialInstance::Result MaterialInstance::update(talus_batch &b) const noexcept {
    return call(b, false);
}

MaterialInstance::Result MaterialInstance::start(talus_batch &b) const noexcept {
    return call(b, true);
}

void MaterialInstance::run_alone(const void *alone_call, std::size_t k) noexcept {
    const auto &a = *static_cast<const AloneCall *>(alone_call);
    const talus_batch &b = *a.batch;
    const std::size_t ns = b.state_size;
    // Each array at point k: the batch's layout (material_abi.h), n x width.
    const auto at = [k](auto *p, std::size_t width) { return p ? p + width * k : p; };
    talus_batch one = b;
    one.n_points = 1;
    one.strain_increment = at(b.strain_increment, 6);
    one.F_start = at(b.F_start, 9);
    one.F_end = at(b.F_end, 9);
    one.density = at(b.density, 1);
    one.stress_start = at(b.stress_start, 6);
    one.state_start = at(b.state_start, ns);
    one.stress_end = at(b.stress_end, 6);
    one.state_end = at(b.state_end, ns);
    one.wave_speed = at(b.wave_speed, 1);
    one.tangent = at(b.tangent, 36);
    one.point_id = at(b.point_id, 1);
    one.characteristic_length = at(b.characteristic_length, 1);
    one.rotation = at(b.rotation, 9);
    const Model &m = *a.instance->model_;
    const auto fn = a.setup && m.init_state_ ? m.init_state_ : m.raw().update;
    talus_error err = fresh_error();
    fn(a.instance->instance_, &one, &err);
}

namespace {

// The output screens below, in one version per instruction set, the
// widest the machine has picked when the program loads (GCC's and clang's
// target_clones): the core is built for the x86-64 baseline, where these
// loops take two values an instruction, and they run at every batch
// (bench/results/2026-11-25-lane-tests-epyc-zen4.md).
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__APPLE__)
#define TALUS_SCREEN_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define TALUS_SCREEN_CLONES
#endif

// Whether any of the count values is NaN or infinite. The SDK's any_nonfinite
// is the same test for a plugin's inputs; the core does not use the SDK (the
// C header is all it shares with plugins), so each side keeps its own.
TALUS_SCREEN_CLONES bool nonfinite(const double *p, std::size_t count) {
    // The exponent lies in the upper 32 bits: a 32-bit test is one the
    // x86-64 baseline (SSE2) has in vector form; a 64-bit one is not.
    constexpr std::uint32_t exponent = 0x7ff00000u;
    std::uint32_t any = 0;
    for (std::size_t k = 0; k < count; ++k) {
        std::uint64_t bits;
        std::memcpy(&bits, p + k, sizeof bits);
        const auto high = static_cast<std::uint32_t>(bits >> 32);
        any |= static_cast<std::uint32_t>((high & exponent) == exponent);
    }
    return any != 0;
}

// Whether every wave speed is positive and finite (NaN fails both tests).
// The failures are or-ed without a branch so that the loop vectorises: as
// `ok &= c > 0 && c < inf` it is a scalar loop with a branch per value
// (bench/results/2026-11-26-xeon-2.1ghz-against-4eb0ad2-small-parts.md).
TALUS_SCREEN_CLONES bool speeds_valid(const double *c, std::size_t n) {
    std::uint32_t bad = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const double x = c[i];
        bad |= static_cast<std::uint32_t>(!(x > 0.0)) | static_cast<std::uint32_t>(!(x < INFINITY));
    }
    return bad == 0;
}

} // namespace

MaterialInstance::Result MaterialInstance::call(talus_batch &b, bool setup) const noexcept {
    Result r;
    b.struct_size = sizeof(talus_batch);
    b.state_size = state_size();
    if (!model_->wants_rotation()) b.rotation = nullptr;
    talus_error err = fresh_error();
    const bool init = setup && model_->init_state_;
    const auto fn = init ? model_->init_state_ : model_->raw().update;
    const char *fn_name = init ? "init_state" : "update";
    try {
        const crash::PluginCall call(model_->id().c_str(), library_->path().c_str());
        // A lock per batch, only for models that ask for it (Fortran code
        // with SAVE or COMMON data): never in the reentrant models' path.
        std::unique_lock<std::mutex> serial;
        if (!model_->reentrant()) serial = std::unique_lock<std::mutex>(library_->call_mutex());
        const FpGuard fp(*library_, model_->id().c_str(), fn_name);
        r.status = fn(instance_, &b, &err);
    } catch (...) {
        r.status = TALUS_STATUS_FAILED;
        r.message = fmt::format("an exception escaped the plugin's {} across the C ABI", fn_name);
        return r;
    }
    if (r.status != TALUS_STATUS_OK) {
        if (r.status != TALUS_STATUS_FAILED && r.status != TALUS_STATUS_CUT_STEP) {
            r.message = fmt::format("{} returned the unknown status {}", fn_name, r.status);
            r.status = TALUS_STATUS_FAILED;
            return r;
        }
        r.point = err.point_index;
        r.cut_factor = err.cut_factor;
        r.message = read_message(err);
        if (r.message.empty()) r.message = fmt::format("{} failed without a message", fn_name);
        if (r.status == TALUS_STATUS_CUT_STEP && !(r.cut_factor > 0.0 && r.cut_factor < 1.0)) {
            r.message = fmt::format("cut-step request with an invalid factor {} (expected 0 < "
                                    "factor < 1): {}",
                                    r.cut_factor, r.message);
            r.status = TALUS_STATUS_FAILED;
        }
        return r;
    }
    // The host never trusts outputs blindly: a NaN that entered the solver
    // would spread silently through the grid. A value is NaN or infinite
    // exactly when its exponent bits are all ones; the test is an integer
    // one with an OR reduction, which the compiler vectorises (a sum of
    // x * 0, the other branch-free screen, is one long chain of dependent
    // floating-point adds). The point is looked for only when it trips.
    const std::size_t n = b.n_points, ns = b.state_size;
    const bool want_c = (b.flags & TALUS_BATCH_WANT_WAVE_SPEED) != 0;
    const bool want_t = (b.flags & TALUS_BATCH_WANT_TANGENT) != 0;
    const bool screen = nonfinite(b.stress_end, 6 * n) || (ns && nonfinite(b.state_end, ns * n)) ||
                        (want_t && nonfinite(b.tangent, 36 * n));
    const bool speeds_ok = !want_c || speeds_valid(b.wave_speed, n);
    if (!screen && speeds_ok) return r;
    for (std::size_t i = 0; i < n; ++i) {
        const bool bad_c = want_c && !speeds_valid(b.wave_speed + i, 1);
        const bool bad = nonfinite(b.stress_end + 6 * i, 6) ||
                         (ns && nonfinite(b.state_end + ns * i, ns)) ||
                         (want_t && nonfinite(b.tangent + 36 * i, 36)) || bad_c;
        if (!bad) continue;
        r.status = TALUS_STATUS_FAILED;
        r.host_detected = true;
        r.point = static_cast<std::int64_t>(i);
        r.message =
            fmt::format("returned status OK but a non-finite {} at point {}",
                        bad_c ? "or non-positive wave speed" : "stress, state or tangent", i);
        return r;
    }
    return r;
}

} // namespace talus
