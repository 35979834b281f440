// talus/sdk/material.hpp -- the C++ authoring layer over talus/material_abi.h.
//
// A model author writes a plain class:
//
//   struct MyModel {
//       static constexpr talus::sdk::ModelInfo info{
//           .id = "my_model", .name = "My model", .version = "1.0.0",
//           .doc = "What it is, with the reference.", .tangent = true};
//       static constexpr std::array params{
//           talus::sdk::real("youngs_modulus", "Pa", "Young's modulus.")
//               .required().above(0.0).typical(1e7)};
//       static constexpr std::array<talus::sdk::State, 0> state{};
//
//       explicit MyModel(const talus::sdk::ParamValues &p);   // may throw
//       void update(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const;
//       double wave_speed(const talus::sdk::PointIn &in,
//                         const talus::sdk::PointOut &out) const;
//   };
//   TALUS_MATERIAL_LIBRARY("my_library", "1.0.0", MyModel)
//
// and TALUS_MATERIAL_LIBRARY generates the descriptors, the batch loop, the
// exception guard and the exported entry point. update() may throw
// talus::sdk::Failure or talus::sdk::CutStep (or any std::exception); the
// guard turns it into a status naming the point. Non-finite inputs or
// outputs are reported as failures by the batch loop, so a model never hands
// NaN to the host.
#pragma once

#include <talus/material_abi.h>
#include <talus/sdk/voigt.hpp>

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace talus::sdk {

// ---------------------------------------------------------------- tables --

// One parameter of a model, built with real()/integer()/boolean() and the
// chained modifiers below, all usable in constant expressions.
struct Param {
    const char *key = "";
    const char *unit = "-";
    const char *doc = "";
    std::uint32_t type = TALUS_PARAM_REAL;
    std::uint32_t flags = 0;
    double default_value = 0.0;
    double min_value = -std::numeric_limits<double>::infinity();
    double max_value = std::numeric_limits<double>::infinity();
    double typical_value = 0.0;

    // The user must give it (no default).
    constexpr Param required() const {
        Param p = *this;
        p.flags |= TALUS_PARAM_REQUIRED;
        return p;
    }
    // The value used when the user omits it; also the typical value unless
    // typical() says otherwise.
    constexpr Param defaults_to(double v) const {
        Param p = *this;
        p.flags &= ~TALUS_PARAM_REQUIRED;
        p.default_value = v;
        p.typical_value = v;
        return p;
    }
    constexpr Param typical(double v) const {
        Param p = *this;
        p.typical_value = v;
        return p;
    }
    constexpr Param above(double v) const { return bound_min(v, true); }
    constexpr Param at_least(double v) const { return bound_min(v, false); }
    constexpr Param below(double v) const { return bound_max(v, true); }
    constexpr Param at_most(double v) const { return bound_max(v, false); }

  private:
    constexpr Param bound_min(double v, bool exclusive) const {
        Param p = *this;
        p.min_value = v;
        p.flags = exclusive ? (p.flags | TALUS_PARAM_MIN_EXCLUSIVE)
                            : (p.flags & ~TALUS_PARAM_MIN_EXCLUSIVE);
        return p;
    }
    constexpr Param bound_max(double v, bool exclusive) const {
        Param p = *this;
        p.max_value = v;
        p.flags = exclusive ? (p.flags | TALUS_PARAM_MAX_EXCLUSIVE)
                            : (p.flags & ~TALUS_PARAM_MAX_EXCLUSIVE);
        return p;
    }
};

constexpr Param real(const char *key, const char *unit, const char *doc) {
    Param p;
    p.key = key;
    p.unit = unit;
    p.doc = doc;
    return p;
}
constexpr Param integer(const char *key, const char *unit, const char *doc) {
    Param p = real(key, unit, doc);
    p.type = TALUS_PARAM_INTEGER;
    return p;
}
constexpr Param boolean(const char *key, const char *doc) {
    Param p = real(key, "-", doc);
    p.type = TALUS_PARAM_BOOLEAN;
    p.min_value = 0.0;
    p.max_value = 1.0;
    return p;
}

// One named state variable of a model.
struct State {
    const char *name = "";
    const char *unit = "-";
    const char *doc = "";
    std::uint32_t size = 1;
    std::uint32_t flags = 0;
    double initial_value = 0.0;

    constexpr State components(std::uint32_t n) const {
        State s = *this;
        s.size = n;
        return s;
    }
    constexpr State output() const {
        State s = *this;
        s.flags |= TALUS_STATE_OUTPUT;
        return s;
    }
    constexpr State user_initialisable() const {
        State s = *this;
        s.flags |= TALUS_STATE_USER_INIT;
        return s;
    }
    constexpr State initially(double v) const {
        State s = *this;
        s.initial_value = v;
        return s;
    }
};

constexpr State state_variable(const char *name, const char *unit, const char *doc) {
    State s;
    s.name = name;
    s.unit = unit;
    s.doc = doc;
    return s;
}

struct ModelInfo {
    const char *id = "";
    const char *name = "";
    const char *version = "";
    const char *doc = "";
    bool finite_strain = false; // computes stress from F, owns objectivity
    bool tangent = false;       // update() fills out.tangent when asked
};

// ------------------------------------------------------------ exceptions --

// Throw from a constructor or update() to fail with a message.
struct Failure : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// Throw from update() to ask the host for a smaller time step.
struct CutStep : std::runtime_error {
    CutStep(double factor_, const std::string &why) : std::runtime_error(why), factor(factor_) {}
    double factor;
};

// --------------------------------------------------------- author-facing --

// Parameter values handed to a model's constructor, already checked by the
// host against the table (type, bounds, required).
class ParamValues {
  public:
    ParamValues(std::span<const Param> table, std::span<const double> values)
        : table_(table), values_(values) {}

    // Value by YAML key. An unknown key is a bug in the model: throws.
    double operator[](std::string_view key) const {
        for (std::size_t i = 0; i < table_.size(); ++i)
            if (key == table_[i].key) return values_[i];
        throw std::logic_error("model asked for undeclared parameter '" + std::string(key) + "'");
    }
    double at(std::size_t index) const { return values_[index]; }
    std::size_t size() const { return values_.size(); }

  private:
    std::span<const Param> table_;
    std::span<const double> values_;
};

using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

// Inputs of one point over one increment. The stress and the state are
// copies (the host may update them in place, so the batch's arrays can be
// overwritten while the model runs); the other inputs are read-only views
// of the batch, which the host never aliases with an output.
struct PointIn {
    PointIn(const double *de, const double *F0, const double *F1, const double *s0)
        : strain_increment(de), F_start(F0), F_end(F1), stress(Eigen::Map<const Vec6>(s0)) {}
    double time = 0.0;
    double dt = 0.0;
    Eigen::Map<const Vec6> strain_increment; // engineering shear
    Eigen::Map<const RowMat3> F_start;
    Eigen::Map<const RowMat3> F_end;
    double density = 0.0;
    Vec6 stress;                   // Cauchy at the start of the increment
    std::span<const double> state; // at the start of the increment (copy)
};

// Outputs of one point. `state` starts as a copy of the start state, so a
// model writes only what changes. `tangent` is null unless the host asked.
struct PointOut {
    Vec6 stress;
    std::span<double> state;
    Mat6 *tangent = nullptr;
};

// ------------------------------------------------------------ internals --
namespace detail {

inline void write_message(talus_error *err, std::string_view msg) {
    if (!err || err->struct_size < offsetof(talus_error, message) + 1) return;
    const std::size_t cap =
        std::min<std::size_t>(TALUS_ERROR_MESSAGE_SIZE,
                              err->struct_size - offsetof(talus_error, message)) -
        1;
    const std::size_t n = std::min(cap, msg.size());
    std::memcpy(err->message, msg.data(), n);
    err->message[n] = '\0';
}

inline std::int32_t fail(talus_error *err, std::int64_t point, std::string_view msg) {
    if (err && err->struct_size >= offsetof(talus_error, cut_factor)) err->point_index = point;
    write_message(err, msg);
    return TALUS_STATUS_FAILED;
}

template <std::size_t N>
constexpr std::uint32_t total_state_size(const std::array<State, N> &s) {
    std::uint32_t n = 0;
    for (const State &v : s)
        n += v.size;
    return n;
}

// Whether any of the n values is NaN or infinite: exactly those have all
// exponent bits set. An integer test with an OR reduction, which the
// compiler vectorises (a floating-point sum would be a chain of dependent
// adds).
inline bool any_nonfinite(const double *p, std::size_t n) {
    // The exponent lies in the upper 32 bits: a 32-bit test is one the x86-64
    // baseline (SSE2) has in vector form; a 64-bit one is not.
    constexpr std::uint32_t exponent = 0x7ff00000u;
    std::uint32_t any = 0;
    for (std::size_t i = 0; i < n; ++i) {
        std::uint64_t bits;
        std::memcpy(&bits, p + i, sizeof bits);
        const auto high = static_cast<std::uint32_t>(bits >> 32);
        any |= static_cast<std::uint32_t>((high & exponent) == exponent);
    }
    return any != 0;
}

template <class M>
struct Descriptors {
    static constexpr auto n_params = std::tuple_size_v<decltype(M::params)>;
    static constexpr auto n_state = std::tuple_size_v<decltype(M::state)>;
    static constexpr std::uint32_t state_size = total_state_size(M::state);

    static constexpr std::array<talus_param_desc, n_params> make_params() {
        std::array<talus_param_desc, n_params> out{};
        for (std::size_t i = 0; i < n_params; ++i) {
            const Param &p = M::params[i];
            out[i] = talus_param_desc{sizeof(talus_param_desc),
                                      p.type,
                                      p.flags,
                                      0,
                                      p.key,
                                      p.unit,
                                      p.doc,
                                      p.default_value,
                                      p.min_value,
                                      p.max_value,
                                      p.typical_value};
        }
        return out;
    }
    static constexpr std::array<talus_state_desc, n_state> make_state() {
        std::array<talus_state_desc, n_state> out{};
        for (std::size_t i = 0; i < n_state; ++i) {
            const State &s = M::state[i];
            out[i] = talus_state_desc{
                sizeof(talus_state_desc), s.flags, s.size, 0, s.name, s.unit, s.doc,
                s.initial_value};
        }
        return out;
    }

    static constexpr std::array<talus_param_desc, n_params> params = make_params();
    static constexpr std::array<talus_state_desc, n_state> state = make_state();

    template <class T, std::size_t N>
    static constexpr std::array<const T *, N> pointers(const std::array<T, N> &a) {
        std::array<const T *, N> out{};
        for (std::size_t i = 0; i < N; ++i)
            out[i] = &a[i];
        return out;
    }
    static constexpr std::array<const talus_param_desc *, n_params> param_ptrs = pointers(params);
    static constexpr std::array<const talus_state_desc *, n_state> state_ptrs = pointers(state);

    static std::int32_t create(const double *values, std::uint32_t n, talus_instance **out,
                               talus_error *err) noexcept {
        if (!out) return fail(err, -1, "create: null instance pointer");
        *out = nullptr;
        if (n != n_params)
            return fail(err, -1,
                        "create: expected " + std::to_string(n_params) + " parameter values, got " +
                            std::to_string(n));
        try {
            const ParamValues pv(std::span<const Param>(M::params.data(), n_params),
                                 std::span<const double>(values, n));
            *out = reinterpret_cast<talus_instance *>(new M(pv));
            return TALUS_STATUS_OK;
        } catch (const std::exception &e) {
            return fail(err, -1, e.what());
        } catch (...) {
            return fail(err, -1, "create: unknown exception");
        }
    }

    static void destroy(talus_instance *inst) noexcept { delete reinterpret_cast<M *>(inst); }

    static std::int32_t update(const talus_instance *inst, const talus_batch *b,
                               talus_error *err) noexcept {
        if (!inst || !b) return fail(err, -1, "update: null instance or batch");
        if (b->struct_size < offsetof(talus_batch, tangent) + sizeof(double *))
            return fail(err, -1, "update: batch structure too small for ABI 1.0");
        if (b->state_size != state_size)
            return fail(err, -1,
                        "update: batch has " + std::to_string(b->state_size) +
                            " state values per point, the model has " + std::to_string(state_size));
        const bool want_c = (b->flags & TALUS_BATCH_WANT_WAVE_SPEED) != 0;
        const bool want_t = (b->flags & TALUS_BATCH_WANT_TANGENT) != 0;
        if (want_t && !M::info.tangent)
            return fail(err, -1, "update: tangent requested but the model does not provide one");
        if (b->n_points > 0 &&
            (!b->strain_increment || !b->F_start || !b->F_end || !b->density || !b->stress_start ||
             !b->stress_end || (state_size > 0 && (!b->state_start || !b->state_end)) ||
             (want_c && !b->wave_speed) || (want_t && !b->tangent)))
            return fail(err, -1, "update: a required batch array is null");

        const M &model = *reinterpret_cast<const M *>(inst);
        // The inputs are screened for the whole batch first, in vector-wide
        // passes, and a failing point is looked for only when one trips. F
        // is screened for the models that compute from it; for the others
        // the strain increment, which the host derives from the same
        // velocity gradient, already carries any NaN, and reading F would
        // cost 72 bytes per point.
        const std::size_t n = b->n_points;
        auto bad_inputs = [&](std::size_t first, std::size_t count) {
            bool density_ok = true;
            for (std::size_t k = first; k < first + count; ++k)
                density_ok &= b->density[k] > 0.0;
            return !density_ok || any_nonfinite(b->strain_increment + 6 * first, 6 * count) ||
                   any_nonfinite(b->stress_start + 6 * first, 6 * count) ||
                   (M::info.finite_strain && any_nonfinite(b->F_end + 9 * first, 9 * count)) ||
                   (state_size > 0 &&
                    any_nonfinite(b->state_start + state_size * first, state_size * count));
        };
        if (n > 0 && bad_inputs(0, n))
            for (std::size_t k = 0; k < n; ++k)
                if (bad_inputs(k, 1))
                    return fail(err, static_cast<std::int64_t>(k),
                                "non-finite input (strain increment, stress, state, density "
                                "(or not positive), or F for a finite-strain model) at point " +
                                    std::to_string(k));
        using RowMat6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;
        Mat6 tangent;
        std::int64_t i = 0;
        try {
            for (; i < static_cast<std::int64_t>(n); ++i) {
                const std::size_t k = static_cast<std::size_t>(i);
                const double *de = b->strain_increment + 6 * k;
                const double *s0 = b->stress_start + 6 * k;
                const double *q0 = state_size ? b->state_start + state_size * k : nullptr;
                double *q1 = state_size ? b->state_end + state_size * k : nullptr;

                PointIn in(de, b->F_start + 9 * k, b->F_end + 9 * k, s0);
                in.time = b->time;
                in.dt = b->dt;
                in.density = b->density[k];
                // With an in-place update the start state is copied aside
                // before the model may overwrite it.
                // (sized by the model's own state, known at compile time)
                std::array<double, state_size == 0 ? 1 : state_size> state_copy;
                if (q1 == q0 && state_size > 0) {
                    for (std::uint32_t j = 0; j < state_size; ++j)
                        state_copy[j] = q0[j];
                    in.state = std::span<const double>(state_copy.data(), state_size);
                } else {
                    in.state = std::span<const double>(q0, state_size);
                }

                PointOut out;
                if (q1 != q0)
                    for (std::uint32_t j = 0; j < state_size; ++j)
                        q1[j] = q0[j];
                out.state = std::span<double>(q1, state_size);
                out.tangent = want_t ? &tangent : nullptr;
                // From here on the start state may already be overwritten
                // (aliasing), so `in` holds the only copy of the inputs.
                model.update(in, out);

                // The outputs are not screened here: the host screens every
                // plugin's outputs after the batch (NaN, infinities and
                // non-positive wave speeds), whether built with this SDK or
                // not, so one screen serves both.
                double c = 0.0;
                if (want_c) c = model.wave_speed(in, out);
                Eigen::Map<Vec6>(b->stress_end + 6 * k) = out.stress;
                if (want_c) b->wave_speed[k] = c;
                if (want_t) Eigen::Map<RowMat6>(b->tangent + 36 * k) = tangent;
            }
        } catch (const CutStep &e) {
            if (err && err->struct_size >= offsetof(talus_error, message)) {
                err->point_index = i;
                err->cut_factor = e.factor;
            }
            write_message(err, e.what());
            return TALUS_STATUS_CUT_STEP;
        } catch (const std::exception &e) {
            return fail(err, i,
                        std::string("exception at point ") + std::to_string(i) + ": " + e.what());
        } catch (...) {
            return fail(err, i, "unknown exception at point " + std::to_string(i));
        }
        return TALUS_STATUS_OK;
    }

    static constexpr talus_model model = {
        sizeof(talus_model),
        (M::info.finite_strain ? TALUS_MODEL_FINITE_STRAIN : 0u) |
            (M::info.tangent ? TALUS_MODEL_TANGENT : 0u),
        static_cast<std::uint32_t>(n_params),
        static_cast<std::uint32_t>(n_state),
        M::info.id,
        M::info.name,
        M::info.version,
        M::info.doc,
        param_ptrs.data(),
        state_ptrs.data(),
        &create,
        &destroy,
        &update,
    };
};

template <class... Models>
struct Library {
    static constexpr std::array<const talus_model *, sizeof...(Models)> models = {
        &Descriptors<Models>::model...};

    static std::int32_t entry(const char *name, const char *version, const talus_host_info *host,
                              const talus_library **out, talus_error *err) noexcept {
        static const talus_library lib = {sizeof(talus_library),
                                          TALUS_ABI_VERSION_MAJOR,
                                          TALUS_ABI_VERSION_MINOR,
                                          static_cast<std::uint32_t>(sizeof...(Models)),
                                          name,
                                          version,
                                          models.data()};
        if (!host || !out) return fail(err, -1, "entry: null host or library pointer");
        if (host->abi_major != TALUS_ABI_VERSION_MAJOR)
            return fail(err, -1,
                        std::string("library '") + name + "' was built for Talus material ABI " +
                            std::to_string(TALUS_ABI_VERSION_MAJOR) + "." +
                            std::to_string(TALUS_ABI_VERSION_MINOR) + ", the host speaks ABI " +
                            std::to_string(host->abi_major) + "." +
                            std::to_string(host->abi_minor) +
                            ": rebuild it against this host's SDK");
        *out = &lib;
        return TALUS_STATUS_OK;
    }
};

} // namespace detail
} // namespace talus::sdk

// How the plugin was compiled, as a string in the library file that `talus
// plugin info` and `talus run` read (a plugin built at -O0 runs about ten
// times slower, and nothing else would tell). Not part of the ABI: a plugin
// without it is simply reported as "build unknown".
#if defined(__OPTIMIZE__)
#define TALUS_SDK_BUILD_OPTIMISED "1"
#else
#define TALUS_SDK_BUILD_OPTIMISED "0"
#endif
#if defined(NDEBUG)
#define TALUS_SDK_BUILD_ASSERTS "0"
#else
#define TALUS_SDK_BUILD_ASSERTS "1"
#endif
#define TALUS_SDK_BUILD_INFO                                                                       \
    "TALUS_BUILD_INFO optimised=" TALUS_SDK_BUILD_OPTIMISED " asserts=" TALUS_SDK_BUILD_ASSERTS

// Defines the exported entry point of a plugin library holding the given
// model classes. Use once per shared library, at namespace scope.
#define TALUS_MATERIAL_LIBRARY(LIB_NAME, LIB_VERSION, ...)                                         \
    [[gnu::used]] static const char talus_build_info_[] = TALUS_SDK_BUILD_INFO;                    \
    TALUS_PLUGIN_EXPORT std::int32_t talus_material_entry(                                         \
        const talus_host_info *host, const talus_library **library, talus_error *error) {          \
        return ::talus::sdk::detail::Library<__VA_ARGS__>::entry(LIB_NAME, LIB_VERSION, host,      \
                                                                 library, error);                  \
    }
