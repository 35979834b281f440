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
//       // optional (ABI 1.1): the set-up call before the first step
//       void init_state(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const;
//       // optional, for speed (see Points below): finishes the cheap points
//       // of a chunk of the batch; update for two of the points it leaves
//       void quick_update(const talus::sdk::Points &p) const;
//       void update_pair(const talus::sdk::PointIn &a, talus::sdk::PointOut &oa,
//                        const talus::sdk::PointIn &b, talus::sdk::PointOut &ob) const;
//       // or update for 2 to kGroupSize of them (taken over update_pair)
//       void update_group(const talus::sdk::PointIn *const *in,
//                         talus::sdk::PointOut *const *out, std::size_t n) const;
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

#include <algorithm>
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
#include <type_traits>

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
    // ABI 1.1: a list's allowed counts (max 0: no limit); a string's
    // default and example.
    std::uint32_t min_count = 0, max_count = 0;
    const char *default_string = nullptr;
    const char *typical_string = nullptr;

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
    // A string parameter's default (also its example unless typical() says
    // otherwise) and example.
    constexpr Param defaults_to(const char *v) const {
        Param p = *this;
        p.flags &= ~TALUS_PARAM_REQUIRED;
        p.default_string = v;
        p.typical_string = v;
        return p;
    }
    constexpr Param typical(const char *v) const {
        Param p = *this;
        p.typical_string = v;
        return p;
    }
    // A list's allowed number of values (max 0: no limit).
    constexpr Param counts(std::uint32_t min, std::uint32_t max) const {
        Param p = *this;
        p.min_count = min;
        p.max_count = max;
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
// ABI 1.1: a list of reals (YAML sequence; bounds apply to each value) and
// a string (e.g. a file name: resolve it against ParamValues::base_dir()).
// A model with either needs a 1.1 host; the SDK says so to an older one.
constexpr Param reals(const char *key, const char *unit, const char *doc) {
    Param p = real(key, unit, doc);
    p.type = TALUS_PARAM_REAL_ARRAY;
    return p;
}
constexpr Param text(const char *key, const char *doc) {
    Param p = real(key, "-", doc);
    p.type = TALUS_PARAM_STRING;
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
    // ABI 1.1:
    bool reentrant = true;       // false: the host never calls it from two threads at once
    bool wants_rotation = false; // PointIn::rotation is filled (tensor state to rotate)
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

// One parameter's value as the host gave it.
struct ParamValue {
    double scalar = 0.0;
    std::span<const double> reals; // a list (ABI 1.1)
    std::string_view text;         // a string (ABI 1.1)
};

// Parameter values handed to a model's constructor, already checked by the
// host against the table (type, bounds, counts, required).
class ParamValues {
  public:
    ParamValues(std::span<const Param> table, std::span<const ParamValue> values,
                std::string_view material_name = {}, std::string_view base_dir = {})
        : table_(table), values_(values), material_(material_name), base_dir_(base_dir) {}

    // Value by YAML key. An unknown key, or one of another type, is a bug in
    // the model: throws.
    double operator[](std::string_view key) const { return value(key, false).scalar; }
    // A list parameter's values (ABI 1.1).
    std::span<const double> list(std::string_view key) const {
        return value(key, TALUS_PARAM_REAL_ARRAY).reals;
    }
    // A string parameter's value (ABI 1.1).
    std::string_view text(std::string_view key) const {
        return value(key, TALUS_PARAM_STRING).text;
    }
    double at(std::size_t index) const { return values_[index].scalar; }
    std::size_t size() const { return values_.size(); }
    // The user's name for the material, and the folder of the file it came
    // from (for relative paths); empty from a 1.0 host.
    std::string_view material_name() const { return material_; }
    std::string_view base_dir() const { return base_dir_; }

  private:
    const ParamValue &value(std::string_view key, std::uint32_t type) const {
        for (std::size_t i = 0; i < table_.size(); ++i) {
            if (key != table_[i].key) continue;
            const bool scalar = table_[i].type <= TALUS_PARAM_BOOLEAN;
            if (type == 0 ? !scalar : table_[i].type != type)
                throw std::logic_error("model asked for parameter '" + std::string(key) +
                                       "' as another type than it declared");
            return values_[i];
        }
        throw std::logic_error("model asked for undeclared parameter '" + std::string(key) + "'");
    }
    std::span<const Param> table_;
    std::span<const ParamValue> values_;
    std::string_view material_, base_dir_;
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
    // ABI 1.1 context (from a 1.0 host: step and point_id -1, the length
    // NaN, rotation null). rotation: row-major 3x3, with
    // ModelInfo::wants_rotation.
    std::int64_t step = -1;
    std::int64_t point_id = -1;
    double characteristic_length = std::numeric_limits<double>::quiet_NaN();
    const double *rotation = nullptr;
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

// The most points update_group() gets at once (eight: the decompositions
// of spectral.hpp's symmetric_eigen_group fill one AVX-512 vector).
inline constexpr std::size_t kGroupSize = 8;

// A chunk of a batch, for a model's optional quick pass (see the head of
// this file), which finishes the points it can finish cheaply (a model's
// common case: an elastic step) in a loop over the chunk's arrays, without
// the per-point set-up of update(); the others go to update(), or in pairs
// to update_pair(), or in groups of up to kGroupSize to update_group().
// Each point's result must be what update() gives it, whatever its
// neighbours. Arrays of n points, point after point (6 strain or stress
// components, the model's state values, 36 tangent entries row-major).
// state_end holds a copy of the start state on entry. A point the pass
// finishes gets its whole result: stress_end, the state values that change,
// wave_speed[k] when wave_speed is not null, the tangent when tangent is
// not null, and done[k] = 1. A point it leaves keeps done[k] = 0; its
// stress_end and state_end stay untouched where they are the start arrays
// (stress_end == stress_start, state_end == state_start: update() reads its
// inputs from them) and may be written where they are not, as may its
// wave_speed and tangent entries: update() writes them all again (a pass
// over vectors of points then stores a whole vector without keeping the
// unfinished points' old values).
// The pass must not throw (a failure would name the chunk's first point):
// a point it cannot finish is left to update().
struct Points {
    static constexpr std::size_t kMaxSize = 64;
    std::size_t n = 0;
    double time = 0.0, dt = 0.0;
    const double *strain_increment = nullptr;
    const double *stress_start = nullptr;
    const double *state_start = nullptr;
    const double *density = nullptr;
    double *stress_end = nullptr;
    double *state_end = nullptr;
    double *wave_speed = nullptr;
    double *tangent = nullptr;
    std::uint8_t *done = nullptr;
};

// ------------------------------------------------------------ internals --
namespace detail {
struct HostLog;
} // namespace detail

// Reports something worth a user's attention without failing, through the
// host's log (ABI 1.1; dropped by a 1.0 host). Any thread, also inside
// update. The host shows the first messages and counts the rest.
inline void log_warning(std::string_view message);
inline void log_info(std::string_view message);

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

// The host's log callback, kept from the entry call (one per plugin
// library: the SDK is compiled into each).
struct HostLog {
    void (*log)(void *, std::int32_t, const char *) = nullptr;
    void *context = nullptr;
};
inline HostLog host_log;

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
                                      p.typical_value,
                                      p.min_count,
                                      p.max_count,
                                      p.default_string,
                                      p.typical_string};
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

    static constexpr bool scalar_params = [] {
        for (const Param &p : M::params)
            if (p.type > TALUS_PARAM_BOOLEAN) return false;
        return true;
    }();
    // Whether the model needs a host of ABI 1.1 or later.
    static constexpr bool needs_1_1 =
        !scalar_params || !M::info.reentrant || M::info.wants_rotation;
    static constexpr bool has_init_state = requires(const M &m, const PointIn &in, PointOut &out) {
        m.init_state(in, out);
    };
    static constexpr bool has_quick_update = requires(const M &m, const Points &p) {
        m.quick_update(p);
    };
    static constexpr bool has_pair_update = requires(const M &m, const PointIn &in, PointOut &out) {
        m.update_pair(in, out, in, out);
    };
    static constexpr bool has_group_update =
        requires(const M &m, const PointIn *const *in, PointOut *const *out, std::size_t n) {
        m.update_group(in, out, n);
    };
    // What the batch gives every point, read once per batch.
    struct Context {
        const talus_batch *b = nullptr;
        bool v11 = false, want_t = false;
        const std::int64_t *ids = nullptr;
        const double *lengths = nullptr, *rotations = nullptr;
    };
    // Point k's inputs and outputs made ready for the model, with room for
    // its start state's copy and its tangent. Not copyable: `in` may point
    // into it.
    struct Slot {
        PointIn in;
        PointOut out;
        std::array<double, state_size == 0 ? 1 : state_size> state_copy;
        Mat6 tangent;

        Slot(const Context &x, std::size_t k)
            : in(x.b->strain_increment + 6 * k, x.b->F_start + 9 * k, x.b->F_end + 9 * k,
                 x.b->stress_start + 6 * k) {
            const talus_batch *b = x.b;
            in.time = b->time;
            in.dt = b->dt;
            in.density = b->density[k];
            if (x.v11) in.step = b->step;
            if (x.ids) in.point_id = x.ids[k];
            if (x.lengths) in.characteristic_length = x.lengths[k];
            if (x.rotations) in.rotation = x.rotations + 9 * k;
            const double *q0 = state_size ? b->state_start + state_size * k : nullptr;
            double *q1 = state_size ? b->state_end + state_size * k : nullptr;
            // With an in-place update the start state is copied aside
            // before the model may overwrite it.
            if (q1 == q0 && state_size > 0) {
                for (std::uint32_t j = 0; j < state_size; ++j)
                    state_copy[j] = q0[j];
                in.state = std::span<const double>(state_copy.data(), state_size);
            } else {
                in.state = std::span<const double>(q0, state_size);
            }
            if (q1 != q0)
                for (std::uint32_t j = 0; j < state_size; ++j)
                    q1[j] = q0[j];
            out.state = std::span<double>(q1, state_size);
            out.tangent = x.want_t ? &tangent : nullptr;
        }
        Slot(const Slot &) = delete;
        Slot &operator=(const Slot &) = delete;
    };

    static std::int32_t construct(std::span<const ParamValue> values, std::string_view material,
                                  std::string_view base_dir, talus_instance **out,
                                  talus_error *err) noexcept {
        try {
            const ParamValues pv(std::span<const Param>(M::params.data(), n_params), values,
                                 material, base_dir);
            *out = reinterpret_cast<talus_instance *>(new M(pv));
            return TALUS_STATUS_OK;
        } catch (const std::exception &e) {
            return fail(err, -1, e.what());
        } catch (...) {
            return fail(err, -1, "create: unknown exception");
        }
    }

    static std::int32_t create(const double *values, std::uint32_t n, talus_instance **out,
                               talus_error *err) noexcept {
        if (!out) return fail(err, -1, "create: null instance pointer");
        *out = nullptr;
        if (!scalar_params)
            return fail(err, -1,
                        "create: this model has list or string parameters, which need a "
                        "host of Talus material ABI 1.1 or later (create_ex)");
        if (n != n_params)
            return fail(err, -1,
                        "create: expected " + std::to_string(n_params) + " parameter values, got " +
                            std::to_string(n));
        std::array<ParamValue, n_params == 0 ? 1 : n_params> typed{};
        for (std::size_t i = 0; i < n; ++i)
            typed[i].scalar = values[i];
        return construct(std::span<const ParamValue>(typed.data(), n), {}, {}, out, err);
    }

    static std::int32_t create_ex(const talus_create_args *args, talus_instance **out,
                                  talus_error *err) noexcept {
        if (!out || !args) return fail(err, -1, "create_ex: null arguments or instance pointer");
        *out = nullptr;
        if (args->n_values != n_params || (n_params > 0 && !args->values))
            return fail(err, -1,
                        "create_ex: expected " + std::to_string(n_params) +
                            " parameter values, got " + std::to_string(args->n_values));
        std::array<ParamValue, n_params == 0 ? 1 : n_params> typed{};
        for (std::size_t i = 0; i < n_params; ++i) {
            const talus_param_value *v = args->values[i];
            if (!v || v->type != M::params[i].type)
                return fail(err, -1,
                            std::string("create_ex: parameter '") + M::params[i].key +
                                "' is missing or of another type than declared");
            typed[i].scalar = v->scalar;
            if (v->type == TALUS_PARAM_REAL_ARRAY && v->count > 0)
                typed[i].reals = std::span<const double>(v->reals, v->count);
            if (v->type == TALUS_PARAM_STRING && v->string)
                typed[i].text = std::string_view(v->string, v->count);
        }
        return construct(std::span<const ParamValue>(typed.data(), n_params),
                         args->material_name ? args->material_name : "",
                         args->base_dir ? args->base_dir : "", out, err);
    }

    static void destroy(talus_instance *inst) noexcept { delete reinterpret_cast<M *>(inst); }

    static std::int32_t update(const talus_instance *inst, const talus_batch *b,
                               talus_error *err) noexcept {
        return run(inst, b, err, false);
    }
    static std::int32_t init_state(const talus_instance *inst, const talus_batch *b,
                                   talus_error *err) noexcept {
        return run(inst, b, err, true);
    }

    // The batch loop of update (setup false) and init_state (true): the
    // batch checked, its inputs screened, then the points (quick_then_rest
    // or point_by_point), a model's failure reported with its point.
    static std::int32_t run(const talus_instance *inst, const talus_batch *b, talus_error *err,
                            bool setup) noexcept {
        Batch batch;
        if (const std::int32_t refused = check_batch(inst, b, err, batch);
            refused != TALUS_STATUS_OK)
            return refused;
        if (const std::int32_t bad = screen_inputs(b, err); bad != TALUS_STATUS_OK) return bad;
        const M &self = *reinterpret_cast<const M *>(inst);
        std::int64_t i = 0; // the point being updated, for a failure's report
        try {
            if constexpr (has_quick_update) {
                if (!setup) {
                    quick_then_rest(self, batch, i);
                    return TALUS_STATUS_OK;
                }
            }
            point_by_point(self, batch, setup, i);
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

    // What the batch asks for, read once.
    struct Batch {
        Context ctx;
        bool want_c = false;
    };

    // Refuses a batch the model cannot take (a null array, the wrong state
    // size, an output the model does not give); fills `batch` otherwise.
    static std::int32_t check_batch(const talus_instance *inst, const talus_batch *b,
                                    talus_error *err, Batch &batch) noexcept {
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
        // The 1.1 context, when the host knows it.
        const bool v11 = TALUS_HAS_FIELD(talus_batch, b, rotation);
        const std::int64_t *ids = v11 ? b->point_id : nullptr;
        const double *lengths = v11 ? b->characteristic_length : nullptr;
        const double *rotations = v11 ? b->rotation : nullptr;
        if (M::info.wants_rotation && b->n_points > 0 && !rotations)
            return fail(err, -1,
                        "update: the model needs the increment's rotation and the host "
                        "gave none");
        batch.ctx = Context{b, v11, want_t, ids, lengths, rotations};
        batch.want_c = want_c;
        return TALUS_STATUS_OK;
    }

    // The inputs are screened for the whole batch first, in vector-wide
    // passes, and a failing point is looked for only when one trips. F is
    // screened for the models that compute from it; for the others the
    // strain increment, which the host derives from the same velocity
    // gradient, already carries any NaN, and reading F would cost 72 bytes
    // per point. A host that has screened them itself says so
    // (TALUS_BATCH_INPUTS_FINITE, ABI 1.2): the solver's inputs are its
    // screened outputs and its kinematics, tested there, and a second
    // screen of the same values would be a large share of a cheap model's
    // batch.
    static std::int32_t screen_inputs(const talus_batch *b, talus_error *err) noexcept {
        const std::size_t n = b->n_points;
        if (n == 0 || (b->flags & TALUS_BATCH_INPUTS_FINITE) != 0 || !bad_inputs(b, 0, n))
            return TALUS_STATUS_OK;
        for (std::size_t k = 0; k < n; ++k)
            if (bad_inputs(b, k, 1))
                return fail(err, static_cast<std::int64_t>(k),
                            "non-finite input (strain increment, stress, state, density "
                            "(or not positive), or F for a finite-strain model) at point " +
                                std::to_string(k));
        return TALUS_STATUS_OK;
    }
    static bool bad_inputs(const talus_batch *b, std::size_t first, std::size_t count) {
        // Positive and finite (an infinite density passed `> 0` alone and
        // reached the model, whose wave speed came out zero); the two tests
        // without a branch, so that the loop vectorises.
        bool density_ok = true;
        for (std::size_t k = first; k < first + count; ++k) {
            const double rho = b->density[k];
            density_ok &= (rho > 0.0) & (rho < std::numeric_limits<double>::infinity());
        }
        return !density_ok || any_nonfinite(b->strain_increment + 6 * first, 6 * count) ||
               any_nonfinite(b->stress_start + 6 * first, 6 * count) ||
               (M::info.finite_strain && any_nonfinite(b->F_end + 9 * first, 9 * count)) ||
               (state_size > 0 &&
                any_nonfinite(b->state_start + state_size * first, state_size * count));
    }

    // Point k's outputs into the batch.
    [[gnu::always_inline]] static void commit(const M &self, const Batch &batch, const Slot &slot,
                                              std::size_t k) {
        using RowMat6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;
        const talus_batch *b = batch.ctx.b;
        // The outputs are not screened here: the host screens every
        // plugin's outputs after the batch (NaN, infinities and
        // non-positive wave speeds), whether built with this SDK or not, so
        // one screen serves both.
        double c = 0.0;
        if (batch.want_c) c = self.wave_speed(slot.in, slot.out);
        // Element by element: the model has just written out.stress, in
        // stores whose widths and overlaps its compiler chose. A 16-byte
        // load needing two of them waits until they reach the cache (no
        // store forwarding); an 8-byte load forwards from any store holding
        // it. The empty asm (GCC and clang) keeps the compiler from pairing
        // the loads.
        for (std::size_t e = 0; e < 6; ++e) {
            b->stress_end[6 * k + e] = slot.out.stress[static_cast<Eigen::Index>(e)];
#if defined(__GNUC__) || defined(__clang__)
            asm volatile("" ::: "memory");
#endif
        }
        if (batch.want_c) b->wave_speed[k] = c;
        if (batch.ctx.want_t) Eigen::Map<RowMat6>(b->tangent + 36 * k) = slot.tangent;
    }

    // The simple path: each point through update() (or init_state()).
    [[gnu::always_inline]] static void point_by_point(const M &self, const Batch &batch, bool setup,
                                                      std::int64_t &i) {
        const std::int64_t n = static_cast<std::int64_t>(batch.ctx.b->n_points);
        for (; i < n; ++i) {
            const std::size_t k = static_cast<std::size_t>(i);
            Slot slot(batch.ctx, k);
            // From here on the start state may already be overwritten
            // (aliasing), so `in` holds the only copy of the inputs.
            if constexpr (has_init_state) {
                if (setup)
                    self.init_state(slot.in, slot.out);
                else
                    self.update(slot.in, slot.out);
            } else {
                (void)setup;
                self.update(slot.in, slot.out);
            }
            commit(self, batch, slot, k);
        }
    }

    // The opt-in speed path (quick_update): per chunk, the model's quick
    // pass over the chunk's arrays, then update() on the points it left,
    // by groups or two at a time where the model takes them.
    [[gnu::always_inline]] static void quick_then_rest(const M &self, const Batch &batch,
                                                       std::int64_t &i) {
        const talus_batch *b = batch.ctx.b;
        const std::size_t n = b->n_points;
        const bool want_c = batch.want_c, want_t = batch.ctx.want_t;
        std::array<std::uint8_t, Points::kMaxSize> done;
        std::array<std::uint32_t, Points::kMaxSize> rest;
        for (std::size_t c0 = 0; c0 < n; c0 += Points::kMaxSize) {
            const std::size_t m = std::min(n - c0, Points::kMaxSize);
            i = static_cast<std::int64_t>(c0);
            // The end state starts as the start state.
            if (state_size > 0 && b->state_end != b->state_start)
                std::copy(b->state_start + state_size * c0, b->state_start + state_size * (c0 + m),
                          b->state_end + state_size * c0);
            std::fill(done.begin(), done.begin() + m, std::uint8_t{0});
            const Points pts{m,
                             b->time,
                             b->dt,
                             b->strain_increment + 6 * c0,
                             b->stress_start + 6 * c0,
                             state_size ? b->state_start + state_size * c0 : nullptr,
                             b->density + c0,
                             b->stress_end + 6 * c0,
                             state_size ? b->state_end + state_size * c0 : nullptr,
                             want_c ? b->wave_speed + c0 : nullptr,
                             want_t ? b->tangent + 36 * c0 : nullptr,
                             done.data()};
            self.quick_update(pts);
            // The points left, listed without a branch per point (every
            // index written, the count advanced past the ones left): where
            // elastic and plastic points mix, a branch would be mispredicted
            // at every change. A chunk the quick pass finished whole (every
            // point of an elastic model) skips the listing: the library's
            // search for a zero byte reads the flags a vector at a time.
            std::size_t n_rest = 0;
            if (std::memchr(done.data(), 0, m) != nullptr)
                for (std::size_t k = 0; k < m; ++k) {
                    rest[n_rest] = static_cast<std::uint32_t>(c0 + k);
                    n_rest += done[k] == 0 ? 1u : 0u;
                }
            update_rest(self, batch, rest.data(), n_rest, i);
        }
    }

    // update() on the points a quick pass left: by groups, or pairs, where
    // the model takes them; a failure of a group or pair is replayed point
    // by point, so that it names its point.
    [[gnu::always_inline]] static void update_rest(const M &self, const Batch &batch,
                                                   const std::uint32_t *rest, std::size_t n_rest,
                                                   std::int64_t &i) {
        const Context &ctx = batch.ctx;
        std::size_t j = 0;
        if constexpr (has_group_update)
            while (j + 1 < n_rest) {
                const std::size_t g = std::min(kGroupSize, n_rest - j);
                // Uninitialised room for the slots: an array of
                // std::optional<Slot> would be zeroed whole for every group.
                static_assert(std::is_trivially_destructible_v<Slot>);
                alignas(Slot) std::byte room[kGroupSize][sizeof(Slot)];
                Slot *slots[kGroupSize];
                const PointIn *ins[kGroupSize];
                PointOut *outs[kGroupSize];
                for (std::size_t k = 0; k < g; ++k) {
                    slots[k] = ::new (static_cast<void *>(room[k])) Slot(ctx, rest[j + k]);
                    ins[k] = &slots[k]->in;
                    outs[k] = &slots[k]->out;
                }
                i = rest[j];
                try {
                    self.update_group(ins, outs, g);
                } catch (...) {
                    for (std::size_t k = 0; k < g; ++k) {
                        i = rest[j + k];
                        self.update(slots[k]->in, slots[k]->out);
                    }
                    throw;
                }
                for (std::size_t k = 0; k < g; ++k)
                    commit(self, batch, *slots[k], rest[j + k]);
                j += g;
            }
        else if constexpr (has_pair_update)
            for (; j + 1 < n_rest; j += 2) {
                i = rest[j];
                Slot slot(ctx, rest[j]), other(ctx, rest[j + 1]);
                try {
                    self.update_pair(slot.in, slot.out, other.in, other.out);
                } catch (...) {
                    self.update(slot.in, slot.out);
                    i = rest[j + 1];
                    self.update(other.in, other.out);
                    throw;
                }
                commit(self, batch, slot, rest[j]);
                commit(self, batch, other, rest[j + 1]);
            }
        for (; j < n_rest; ++j) {
            i = rest[j];
            Slot slot(ctx, rest[j]);
            self.update(slot.in, slot.out);
            commit(self, batch, slot, rest[j]);
        }
    }

    static constexpr talus_model model = {
        sizeof(talus_model),
        (M::info.finite_strain ? TALUS_MODEL_FINITE_STRAIN : 0u) |
            (M::info.tangent ? TALUS_MODEL_TANGENT : 0u) |
            (M::info.reentrant ? 0u : TALUS_MODEL_NOT_REENTRANT) |
            (M::info.wants_rotation ? TALUS_MODEL_WANTS_ROTATION : 0u),
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
        &create_ex,
        nullptr,
        has_init_state ? &init_state : nullptr,
    };
};

template <class... Models>
struct Library {
    static constexpr std::array<const talus_model *, sizeof...(Models)> models = {
        &Descriptors<Models>::model...};
    static constexpr bool needs_1_1 = (Descriptors<Models>::needs_1_1 || ...);

    static std::int32_t entry(const char *name, const char *version, const talus_host_info *host,
                              const talus_library **out, talus_error *err) noexcept {
        static const talus_library lib = {sizeof(talus_library),
                                          TALUS_ABI_VERSION_MAJOR,
                                          TALUS_ABI_VERSION_MINOR,
                                          static_cast<std::uint32_t>(sizeof...(Models)),
                                          name,
                                          version,
                                          models.data(),
                                          nullptr};
        if (!host || !out) return fail(err, -1, "entry: null host or library pointer");
        const std::string versions =
            std::string("library '") + name + "' was built for Talus material ABI " +
            std::to_string(TALUS_ABI_VERSION_MAJOR) + "." +
            std::to_string(TALUS_ABI_VERSION_MINOR) + ", the host speaks ABI " +
            std::to_string(host->abi_major) + "." + std::to_string(host->abi_minor);
        if (host->abi_major != TALUS_ABI_VERSION_MAJOR)
            return fail(err, -1, versions + ": rebuild it against this host's SDK");
        if (needs_1_1 && host->abi_minor < 1)
            return fail(err, -1,
                        versions + ", and one of its models needs ABI 1.1 (list or string "
                                   "parameters, not reentrant, or the increment's rotation): "
                                   "use a newer host");
        if (TALUS_HAS_FIELD(talus_host_info, host, log_context)) {
            host_log.log = host->log;
            host_log.context = host->log_context;
        }
        *out = &lib;
        return TALUS_STATUS_OK;
    }
};

} // namespace detail

inline void log_message(std::int32_t level, std::string_view message) {
    if (!detail::host_log.log) return;
    // One line, NUL-terminated: a bounded copy on the stack (no allocation
    // inside update).
    char line[512];
    const std::size_t n = std::min(message.size(), sizeof line - 1);
    std::memcpy(line, message.data(), n);
    line[n] = '\0';
    detail::host_log.log(detail::host_log.context, level, line);
}
inline void log_warning(std::string_view message) { log_message(TALUS_LOG_WARNING, message); }
inline void log_info(std::string_view message) { log_message(TALUS_LOG_INFO, message); }

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
