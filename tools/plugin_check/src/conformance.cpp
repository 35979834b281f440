#include <talus/material/plugin_loader.hpp>
#include <talus/plugin_check/conformance.hpp>
#include <talus/plugin_check/elf_symbols.hpp>

#include <talus/sdk/kinematics.hpp>
#include <talus/sdk/voigt.hpp>

#include "guarded_array.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <fmt/format.h>

#include <cmath>
#include <csignal>
#include <cstring>
#include <functional>
#include <numbers>
#include <ostream>
#include <random>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

namespace talus {

bool ConformanceReport::passed() const { return failures() == 0 && !outcomes.empty(); }

std::size_t ConformanceReport::failures() const {
    std::size_t n = 0;
    for (const auto &o : outcomes)
        n += o.passed ? 0 : 1;
    return n;
}

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
using RowMat6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;

// One point's inputs and outputs, in the ABI's layouts.
struct Pt {
    Vec6 de = Vec6::Zero();
    RowMat3 F0 = RowMat3::Identity();
    RowMat3 F1 = RowMat3::Identity();
    double rho = 0.0;
    Vec6 s0 = Vec6::Zero();
    std::vector<double> q0;
};
struct Out {
    Vec6 s1 = Vec6::Zero();
    std::vector<double> q1;
    double c = 0.0;
    RowMat6 D = RowMat6::Zero();
};

// A --param value as the parameter's type: a number, a comma-separated
// list of numbers, or text. Checked against the parameter's bounds.
bool parse_param(const ParamInfo &p, const std::string &text, ParamValue &out, std::string &why) {
    auto number = [&](const std::string &t, double &v) {
        try {
            std::size_t used = 0;
            v = std::stod(t, &used);
            return used == t.size();
        } catch (const std::exception &) {
            return false;
        }
    };
    out = ParamValue{};
    if (p.type == TALUS_PARAM_STRING) {
        out.text = text;
    } else if (p.type == TALUS_PARAM_REAL_ARRAY) {
        std::size_t at = 0;
        while (!text.empty() && at <= text.size()) {
            const std::size_t comma = std::min(text.find(',', at), text.size());
            double v = 0.0;
            if (!number(text.substr(at, comma - at), v)) {
                why = fmt::format("'{}' is not a comma-separated list of numbers", text);
                return false;
            }
            out.reals.push_back(v);
            at = comma + 1;
        }
    } else if (p.type == TALUS_PARAM_BOOLEAN && (text == "true" || text == "false")) {
        out.scalar = text == "true" ? 1.0 : 0.0;
    } else if (!number(text, out.scalar)) {
        why = fmt::format("'{}' is not a number", text);
        return false;
    }
    why = check_parameter(p, out);
    return why.empty();
}

// F at the end of an increment de from F0: the pure stretch exp(de) applied
// on the left, consistent with the tangent's definition in the ABI.
RowMat3 advance_F(const RowMat3 &F0, const Vec6 &de) {
    return RowMat3(sdk::increment_stretch(de) * Mat3(F0));
}

// Runs points [begin, begin+n) as one batch. `in_place` makes the end arrays
// the start arrays, as a host updating its particle arrays in place would.
// Writes outside a batch's arrays, seen by run_batch and reported by the
// "buffers" check (guarded_array.hpp).
check::Overruns overruns;

MaterialInstance::Result run_batch(const MaterialInstance &mi, const std::vector<Pt> &pts,
                                   std::size_t begin, std::size_t n, std::uint32_t flags,
                                   std::vector<Out> &outs, bool in_place = false) {
    const std::size_t ns = mi.state_size();
    using check::GuardedArray;
    GuardedArray de(6 * n), F0(9 * n), F1(9 * n), rho(n), s0(6 * n), q0(ns * n), s1(6 * n),
        q1(ns * n), c(n), D(36 * n), length(n, 1.0), R(9 * n, 0.0);
    // The 1.1 context as a host gives it: each point's id is its index in
    // the check's list of points (so a point keeps its id in a batch and
    // alone), a unit length, and no rotation (the increments are stretches).
    std::vector<std::int64_t> ids(n);
    for (std::size_t i = 0; i < n; ++i) {
        const Pt &p = pts[begin + i];
        std::copy_n(p.de.data(), 6, &de[6 * i]);
        std::copy_n(p.F0.data(), 9, &F0[9 * i]);
        std::copy_n(p.F1.data(), 9, &F1[9 * i]);
        rho[i] = p.rho;
        ids[i] = static_cast<std::int64_t>(begin + i);
        R[9 * i] = R[9 * i + 4] = R[9 * i + 8] = 1.0;
        std::copy_n(p.s0.data(), 6, &s0[6 * i]);
        std::copy(p.q0.begin(), p.q0.end(), q0.begin() + static_cast<std::ptrdiff_t>(ns * i));
    }
    talus_batch b{};
    b.flags = flags;
    b.n_points = n;
    b.time = 0.0;
    b.dt = 1.0;
    b.strain_increment = de.data();
    b.F_start = F0.data();
    b.F_end = F1.data();
    b.density = rho.data();
    b.stress_start = s0.data();
    b.state_start = ns ? q0.data() : nullptr;
    b.stress_end = in_place ? s0.data() : s1.data();
    b.state_end = ns ? (in_place ? q0.data() : q1.data()) : nullptr;
    b.wave_speed = c.data();
    b.tangent = D.data();
    b.step = 1;
    b.point_id = ids.data();
    b.characteristic_length = length.data();
    b.rotation = R.data();
    const MaterialInstance::Result r = mi.update(b);
    // Every array the plugin was handed, inputs included: a write outside
    // any of them would land in the host's memory in a run.
    const std::pair<const char *, const GuardedArray *> arrays[] = {
        {"strain_increment", &de},
        {"F_start", &F0},
        {"F_end", &F1},
        {"density", &rho},
        {"stress_start", &s0},
        {"state_start", &q0},
        {"stress_end", &s1},
        {"state_end", &q1},
        {"wave_speed", &c},
        {"tangent", &D},
        {"characteristic_length", &length},
        {"rotation", &R}};
    for (const auto &[name, a] : arrays)
        if (const std::string d = a->damage(name); !d.empty())
            overruns.note(fmt::format(
                "update wrote {}{} (a batch of {} point(s), {} state "
                "value(s) each)",
                d, in_place && (a == &s0 || a == &q0) ? ", the end array too (in place)" : "", n,
                ns));
    if (outs.size() < begin + n) outs.resize(begin + n);
    for (std::size_t i = 0; i < n; ++i) {
        Out &o = outs[begin + i];
        o.s1 = Eigen::Map<const Vec6>(b.stress_end + 6 * i);
        o.q1.assign(b.state_end ? b.state_end + ns * i : nullptr,
                    b.state_end ? b.state_end + ns * (i + 1) : nullptr);
        o.c = c[i];
        o.D = Eigen::Map<const RowMat6>(&D[36 * i]);
    }
    return r;
}

// Largest difference between two output sets, relative to `scale`.
double max_difference(const std::vector<Out> &a, const std::vector<Out> &b, double stress_scale,
                      bool with_c, bool with_D) {
    double d = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        d = std::max(d, (a[i].s1 - b[i].s1).cwiseAbs().maxCoeff() / stress_scale);
        for (std::size_t k = 0; k < a[i].q1.size(); ++k)
            d = std::max(d,
                         std::abs(a[i].q1[k] - b[i].q1[k]) / std::max(1.0, std::abs(a[i].q1[k])));
        if (with_c) d = std::max(d, std::abs(a[i].c - b[i].c) / std::max(a[i].c, 1e-300));
        if (with_D)
            d = std::max(d, (a[i].D - b[i].D).cwiseAbs().maxCoeff() /
                                std::max(a[i].D.cwiseAbs().maxCoeff(), 1e-300));
    }
    return d;
}

// Receives outcomes; in the isolated mode it writes them to a pipe.
struct Sink {
    std::function<void(const CheckOutcome &)> emit;
    std::function<void(const std::string &, const std::string &)> starting;
};

class ModelChecks {
  public:
    ModelChecks(const Model &m, const CheckOptions &o, Sink &s) : model_(m), opt_(o), sink_(s) {}

    void run() {
        // Each model's own: the checks of a library's models run in turn.
        overruns.clear();
        fp_changes_before_ = model_.library().fp_changes();
        if (!create()) return;
        if (!build_states()) return;
        zero_increment();
        batch_invariance();
        in_place();
        tangent();
        wave_speed();
        nan_input();
        threads();
        determinism();
        objectivity();
        instance_.reset();
        report("buffers", overruns.count() == 0,
               overruns.count() == 0
                   ? fmt::format("no write outside a batch's arrays (guard bands of {} values on "
                                 "both sides of each)",
                                 check::GuardedArray::kGuard)
                   : fmt::format("{} ({} batch(es) in all): a plugin that writes outside its "
                                 "arrays corrupts the host's memory in a run",
                                 overruns.first(), overruns.count()));
        // The host puts back what a call changes of the floating-point
        // environment and the library records it (fp_environment.hpp):
        // loading, create, update and destroy are all seen.
        // This model's calls, or the library's load (which is every model's).
        const PluginLibrary &lib = model_.library();
        const std::string fp = lib.fp_change();
        const bool at_load = fp.rfind("loading", 0) == 0 || fp.rfind("its entry point", 0) == 0;
        const bool changed = lib.fp_changes() > fp_changes_before_ || (!fp.empty() && at_load);
        report("fp environment", !changed,
               !changed ? "rounding mode, flush-to-zero and trap masks left as they were by "
                          "loading, create, update and destroy"
                        : fmt::format("{}{} ({} call(s) of the library in all); a plugin must "
                                      "leave the floating-point environment as it found it",
                                      lib.fp_changes() > fp_changes_before_ && !at_load
                                          ? "this model's calls changed it; the library's first "
                                            "change: "
                                          : "",
                                      fp, lib.fp_changes()));
    }

  private:
    const Model &model_;
    const CheckOptions &opt_;
    Sink &sink_;
    std::unique_ptr<MaterialInstance> instance_;
    std::size_t fp_changes_before_ = 0;
    std::vector<Pt> states_;       // loaded states (start of the checks' increments)
    std::vector<Vec6> directions_; // loading direction that produced each state
    double stress_scale_ = 1.0;    // rho c^2 * strain_scale: stress of one increment
    std::string param_text_;       // the parameter values the checks use

    // A failure names the parameter values it happened with: a model can be
    // right for its typical values and wrong for the user's.
    void report(const std::string &name, bool ok, const std::string &detail) {
        sink_.emit(CheckOutcome{model_.id(), name, ok,
                                ok || param_text_.empty() || name == "create"
                                    ? detail
                                    : detail + " [parameters: " + param_text_ + "]"});
    }
    void start(const std::string &name) { sink_.starting(model_.id(), name); }

    bool create() {
        start("create");
        std::vector<ParamValue> values;
        for (const ParamInfo &p : model_.params()) {
            ParamValue v = p.typical_param();
            bool given = false;
            for (const auto &kv : opt_.params)
                if (kv.first == p.key) {
                    given = true;
                    std::string why;
                    if (!parse_param(p, kv.second, v, why)) {
                        report("create", false,
                               fmt::format("--param {}={}: {}", kv.first, kv.second, why));
                        return false;
                    }
                }
            if (!given && p.type == TALUS_PARAM_STRING && p.required() && !p.has_typical_string) {
                report("create", false,
                       fmt::format("parameter '{}' ({}) has no example value: give one with "
                                   "--param {}=VALUE",
                                   p.key, p.doc, p.key));
                return false;
            }
            values.push_back(std::move(v));
        }
        for (const auto &kv : opt_.params) {
            bool known = false;
            for (const ParamInfo &p : model_.params())
                known |= p.key == kv.first;
            if (!known) {
                report("create", false,
                       fmt::format("--param {}: the model has no such parameter", kv.first));
                return false;
            }
        }
        try {
            instance_ = model_.create(values);
        } catch (const Error &e) {
            report("create", false, e.what());
            return false;
        }
        std::string desc;
        for (std::size_t i = 0; i < values.size(); ++i)
            desc += fmt::format("{}{}={}", i ? ", " : "", model_.params()[i].key,
                                model_.params()[i].value_text(values[i]));
        param_text_ = desc;
        report("create", true, desc.empty() ? "no parameters" : desc);
        return true;
    }

    // Loading paths from the natural state, 10 increments each. The generic
    // directions (distinct principal values, all shear components) reach
    // the smooth parts of a yield surface. The axisymmetric ones (triaxial
    // compression and extension, isotropic extension) reach the edges and
    // the apex of piecewise-smooth surfaces such as Mohr-Coulomb's: the
    // continued increment then lies inside the region of the trial space
    // that returns to that edge or apex, where the return is smooth and a
    // finite-difference tangent meaningful (on a boundary between regions
    // it would not be, and the generic paths avoid those).
    bool build_states() {
        start("loading paths");
        const std::vector<Vec6> dirs = {
            (Vec6() << -1.0, -0.35, -0.6, 0.4, -0.25, 0.15).finished(),
            (Vec6() << -0.7, -1.0, -0.2, -0.3, 0.5, 0.1).finished(),
            (Vec6() << -0.3, -0.5, -1.0, 0.2, 0.1, -0.6).finished(),
            (Vec6() << 0.4, -1.0, -0.6, 0.7, 0.05, -0.2).finished(),
            (Vec6() << -1.0, 0.3, 0.3, 0.0, 0.0, 0.0).finished(),
            (Vec6() << 0.3, 0.3, -1.0, 0.0, 0.0, 0.0).finished(),
            (Vec6() << 1.0, 1.0, 1.0, 0.0, 0.0, 0.0).finished(),
        };
        Pt virgin;
        virgin.rho = opt_.density;
        virgin.q0 = instance_->state().initial();
        // The virgin state gets a compression direction: from zero stress, a
        // model without cohesion can only be probed by loading it.
        states_.push_back(virgin);
        directions_.push_back(dirs[0]);
        // Whether each path left the model's linear branch: its state
        // changed, or its stress is not ten times the first increment's
        // change (a plastic, damaged or hyperelastic response). Checks run
        // only on the linear branch test only that branch: said below.
        int state_changed = 0, nonlinear = 0;
        for (std::size_t d = 0; d < dirs.size(); ++d) {
            Pt p = virgin;
            const Vec6 de = opt_.strain_scale * dirs[d] / dirs[d].norm();
            Vec6 first = Vec6::Zero();
            for (int k = 0; k < 10; ++k) {
                p.de = de;
                p.F1 = advance_F(p.F0, de);
                p.rho = opt_.density / p.F1.determinant();
                std::vector<Out> o;
                const auto r = run_batch(*instance_, {p}, 0, 1, TALUS_BATCH_WANT_WAVE_SPEED, o);
                if (!r.ok()) {
                    report("loading paths", false,
                           fmt::format("path {} failed at increment {}: {}", d, k, r.message));
                    return false;
                }
                if (k == 0) first = o[0].s1 - p.s0;
                p.s0 = o[0].s1;
                p.q0 = o[0].q1;
                p.F0 = p.F1;
                if (k == 0 && d == 0)
                    stress_scale_ = opt_.density * o[0].c * o[0].c * opt_.strain_scale;
            }
            p.de.setZero();
            bool changed = false;
            for (std::size_t k = 0; k < p.q0.size(); ++k)
                changed |= p.q0[k] != virgin.q0[k];
            state_changed += changed;
            // 1e-6 of the path's stress: far above the round-off of ten
            // sums, far below any material nonlinearity worth the name.
            const Vec6 linear = virgin.s0 + 10.0 * first;
            nonlinear += (p.s0 - linear).cwiseAbs().maxCoeff() >
                         1e-6 * std::max(linear.cwiseAbs().maxCoeff(), 1e-300);
            states_.push_back(p);
            directions_.push_back(dirs[d]);
        }
        const int n_paths = static_cast<int>(dirs.size());
        report("loading paths", true,
               fmt::format("{} states from 4 generic and 3 axisymmetric paths of 10 increments of "
                           "{:g}; stress scale "
                           "rho c^2 de = {:.4g}; {}",
                           states_.size(), opt_.strain_scale, stress_scale_,
                           state_changed + nonlinear == 0
                               ? "NO path left the linear branch (no state changed, every "
                                 "response linear): the checks below test the linear branch "
                                 "only; raise --strain-scale or give --param values that reach "
                                 "yield"
                               : fmt::format("the nonlinear branch was reached: {} of {} paths "
                                             "changed the state, {} of {} responded nonlinearly",
                                             state_changed, n_paths, nonlinear, n_paths)));
        return true;
    }

    // Points: every state with zero increment, or with a continued-loading
    // increment (plus a random perturbation when `random` is set).
    std::vector<Pt> points(bool zero, int per_state = 1) {
        std::mt19937_64 rng(12345);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        std::vector<Pt> out;
        for (std::size_t s = 0; s < states_.size(); ++s)
            for (int k = 0; k < per_state; ++k) {
                Pt p = states_[s];
                if (zero)
                    p.de.setZero();
                else {
                    Vec6 dir = directions_[s] / directions_[s].norm();
                    if (k > 0)
                        for (int j = 0; j < 6; ++j)
                            dir[j] += 0.5 * u(rng);
                    p.de = opt_.strain_scale * dir / dir.norm();
                }
                p.F1 = advance_F(p.F0, p.de);
                p.rho = opt_.density / p.F1.determinant();
                out.push_back(p);
            }
        return out;
    }

    std::uint32_t full_flags() const {
        return TALUS_BATCH_WANT_WAVE_SPEED | (model_.has_tangent() ? TALUS_BATCH_WANT_TANGENT : 0u);
    }

    void zero_increment() {
        start("zero increment");
        const std::vector<Pt> pts = points(true);
        std::vector<Out> o;
        const auto r = run_batch(*instance_, pts, 0, pts.size(), 0, o);
        if (!r.ok()) return report("zero increment", false, r.message);
        // A model that returns its start state for a null increment does so
        // up to a few roundings of its own arithmetic (a return mapping that
        // passes through invariants loses ~1e-15 relative); 1e-12 of the
        // larger of the stress and one increment's stress leaves margin for
        // that and catches any real change.
        double worst = 0.0;
        for (std::size_t i = 0; i < pts.size(); ++i) {
            const double scale = std::max(pts[i].s0.cwiseAbs().maxCoeff(), stress_scale_);
            worst = std::max(worst, (o[i].s1 - pts[i].s0).cwiseAbs().maxCoeff() / scale);
            for (std::size_t k = 0; k < pts[i].q0.size(); ++k)
                worst = std::max(worst, std::abs(o[i].q1[k] - pts[i].q0[k]) /
                                            std::max(1.0, std::abs(pts[i].q0[k])));
        }
        report(
            "zero increment", worst <= 1e-12,
            fmt::format("largest relative change of stress or state: {:.3g} (limit 1e-12)", worst));
    }

    // Batch size and aliasing must not change a result: each point is
    // independent by contract. A vectorised plugin may round its remainder
    // loop differently (FMA or not), which moves results by an ulp or two;
    // 1e-12 relative allows that and nothing physical.
    static constexpr double kInvariance = 1e-12;

    void batch_invariance() {
        start("batch size");
        const std::vector<Pt> pts = points(false, 7);
        const std::uint32_t flags = full_flags();
        std::vector<Out> whole, ones, sevens;
        auto r = run_batch(*instance_, pts, 0, pts.size(), flags, whole);
        if (!r.ok()) return report("batch size", false, "one batch of all points: " + r.message);
        for (std::size_t i = 0; i < pts.size(); ++i) {
            r = run_batch(*instance_, pts, i, 1, flags, ones);
            if (!r.ok()) return report("batch size", false, "batches of one point: " + r.message);
        }
        for (std::size_t i = 0; i < pts.size(); i += 7) {
            r = run_batch(*instance_, pts, i, std::min<std::size_t>(7, pts.size() - i), flags,
                          sevens);
            if (!r.ok()) return report("batch size", false, "batches of 7 points: " + r.message);
        }
        const double d =
            std::max(max_difference(whole, ones, stress_scale_, true, model_.has_tangent()),
                     max_difference(whole, sevens, stress_scale_, true, model_.has_tangent()));
        report("batch size", d <= kInvariance,
               fmt::format("{} points as 1 batch, {} batches of 1 and batches of 7: largest "
                           "relative difference {:.3g} (limit {:g})",
                           pts.size(), pts.size(), d, kInvariance));
    }

    void in_place() {
        start("in place");
        const std::vector<Pt> pts = points(false, 3);
        std::vector<Out> separate, aliased;
        auto r = run_batch(*instance_, pts, 0, pts.size(), TALUS_BATCH_WANT_WAVE_SPEED, separate);
        if (r.ok())
            r = run_batch(*instance_, pts, 0, pts.size(), TALUS_BATCH_WANT_WAVE_SPEED, aliased,
                          true);
        if (!r.ok()) return report("in place", false, r.message);
        const double d = max_difference(separate, aliased, stress_scale_, true, false);
        report("in place", d <= kInvariance,
               fmt::format("stress_end = stress_start and state_end = state_start: largest "
                           "relative difference {:.3g} (limit {:g})",
                           d, kInvariance));
    }

    void tangent() {
        start("tangent");
        if (!model_.has_tangent())
            return report("tangent", true, "not provided (TALUS_MODEL_TANGENT unset): skipped");
        // Central differences with h = 1e-3 of the increment: truncation is
        // O(h^2) on a smooth branch (negligible), round-off is about
        // 1e-16 * |sigma| / h ~ 1e-12 of the modulus, and a model solving a
        // local problem to 1e-10 adds ~1e-7. A wrong tangent term is off by
        // order one, so 1e-5 of the largest entry separates the two cleanly.
        const double h = 1e-3 * opt_.strain_scale;
        const std::vector<Pt> pts = points(false);
        double worst = 0.0;
        std::size_t worst_point = 0;
        int worst_i = 0, worst_j = 0;
        for (std::size_t s = 0; s < pts.size(); ++s) {
            std::vector<Out> base;
            auto r = run_batch(*instance_, pts, s, 1, TALUS_BATCH_WANT_TANGENT, base);
            if (!r.ok()) return report("tangent", false, r.message);
            const RowMat6 D = base[s].D;
            RowMat6 fd;
            for (int j = 0; j < 6; ++j) {
                std::vector<Pt> pm = {pts[s], pts[s]};
                pm[0].de[j] += h;
                pm[1].de[j] -= h;
                for (Pt &p : pm) {
                    p.F1 = advance_F(p.F0, p.de);
                    p.rho = opt_.density / p.F1.determinant();
                }
                std::vector<Out> o;
                r = run_batch(*instance_, pm, 0, 2, 0, o);
                if (!r.ok())
                    return report("tangent", false, "finite-difference probe: " + r.message);
                fd.col(j) = (o[0].s1 - o[1].s1) / (2.0 * h);
            }
            // Relative to the larger of max|D| and the elastic modulus rho
            // c^2 of the first loading increment: a perfectly plastic return
            // to an apex has D = 0, where only the rounding of both sides
            // (~1e-16 |sigma| / h) remains.
            const double scale =
                std::max({D.cwiseAbs().maxCoeff(), stress_scale_ / opt_.strain_scale, 1e-300});
            for (int i = 0; i < 6; ++i)
                for (int j = 0; j < 6; ++j) {
                    const double e = std::abs(D(i, j) - fd(i, j)) / scale;
                    if (e > worst) {
                        worst = e;
                        worst_point = s;
                        worst_i = i;
                        worst_j = j;
                    }
                }
        }
        report("tangent", worst <= 1e-5,
               fmt::format("against central differences (h = {:g}) at {} states: largest error "
                           "{:.3g} of max(max|D|, rho c^2) (limit 1e-5){}",
                           h, pts.size(), worst,
                           worst > 1e-5 ? fmt::format(", at state {} entry D[{}][{}]", worst_point,
                                                      worst_i, worst_j)
                                        : std::string()));
    }

    void wave_speed() {
        start("wave speed");
        const std::vector<Pt> pts = points(false, 2);
        std::vector<Out> o;
        const auto r = run_batch(*instance_, pts, 0, pts.size(), TALUS_BATCH_WANT_WAVE_SPEED, o);
        if (!r.ok()) return report("wave speed", false, r.message);
        double lo = INFINITY, hi = 0.0;
        for (const Out &x : o) {
            lo = std::min(lo, x.c);
            hi = std::max(hi, x.c);
        }
        report("wave speed", true,
               fmt::format("finite and positive at {} points: {:.6g} .. {:.6g} m/s", o.size(), lo,
                           hi));
    }

    void nan_input() {
        start("nan input");
        std::vector<Pt> pts = points(false);
        pts.resize(std::min<std::size_t>(pts.size(), 3));
        const std::size_t bad = pts.size() > 1 ? 1 : 0;
        struct Case {
            const char *what;
            std::function<void(Pt &)> poison;
        };
        const Case cases[] = {
            {"NaN in the strain increment", [](Pt &p) { p.de[0] = std::nan(""); }},
            {"NaN in the start stress", [](Pt &p) { p.s0[3] = std::nan(""); }},
            {"infinite strain increment", [](Pt &p) { p.de[2] = INFINITY; }},
        };
        for (const Case &c : cases) {
            std::vector<Pt> p = pts;
            c.poison(p[bad]);
            std::vector<Out> o;
            const auto r = run_batch(*instance_, p, 0, p.size(), TALUS_BATCH_WANT_WAVE_SPEED, o);
            if (r.ok())
                return report("nan input", false,
                              fmt::format("{} at point {}: the plugin returned OK", c.what, bad));
            if (r.host_detected)
                return report("nan input", false,
                              fmt::format("{} at point {}: the plugin returned OK with non-finite "
                                          "output ({}); it must return TALUS_STATUS_FAILED",
                                          c.what, bad, r.message));
            if (r.point != -1 && r.point != static_cast<std::int64_t>(bad))
                return report("nan input", false,
                              fmt::format("{} at point {}: the plugin failed but named point {}",
                                          c.what, bad, r.point));
        }
        report("nan input", true,
               "NaN strain increment, NaN stress and infinite increment each give "
               "TALUS_STATUS_FAILED");
    }

    // The same batch three times gives the same outputs to the bit: a model
    // whose result depends on a call counter, a clock or uninitialised
    // memory breaks every bit-identical rerun and restart.
    void determinism() {
        start("determinism");
        const std::vector<Pt> pts = points(false, 4);
        const std::uint32_t flags = full_flags();
        std::vector<Out> first, again;
        auto r = run_batch(*instance_, pts, 0, pts.size(), flags, first);
        if (!r.ok()) return report("determinism", false, r.message);
        for (int rep = 0; rep < 2; ++rep) {
            again.clear();
            r = run_batch(*instance_, pts, 0, pts.size(), flags, again);
            if (!r.ok()) return report("determinism", false, r.message);
            for (std::size_t i = 0; i < pts.size(); ++i) {
                const bool same = first[i].s1 == again[i].s1 && first[i].q1 == again[i].q1 &&
                                  first[i].c == again[i].c &&
                                  (!model_.has_tangent() || first[i].D == again[i].D);
                if (!same)
                    return report("determinism", false,
                                  fmt::format("point {} gave different outputs for the same "
                                              "inputs on call {} (sigma_xx {:.17g} vs {:.17g})",
                                              i, rep + 2, first[i].s1[0], again[i].s1[0]));
            }
        }
        report(
            "determinism", true,
            fmt::format("{} points, 3 calls with the same inputs: identical outputs", pts.size()));
    }

    // A finite-strain model computes stress from F and owns its
    // objectivity: a rigid rotation R superposed on every loaded state
    // (F -> R F) must give R sigma R^T. Strain-increment models are skipped:
    // the host rotates their stress (the zero increment check covers that
    // they return it unchanged).
    void objectivity() {
        start("objectivity");
        if (!model_.finite_strain())
            return report("objectivity", true,
                          "strain-increment model: the host rotates the stress; skipped");
        const Mat3 R = Eigen::AngleAxisd(70.0 * std::numbers::pi / 180.0,
                                         Eigen::Vector3d(1, 2, 3).normalized())
                           .toRotationMatrix();
        double worst = 0.0;
        std::size_t worst_state = 0;
        for (std::size_t k = 0; k < states_.size(); ++k) {
            Pt fixed = states_[k], turned = states_[k];
            fixed.de.setZero();
            fixed.F1 = fixed.F0;
            turned.de.setZero();
            turned.F1 = RowMat3(R * Mat3(turned.F0));
            std::vector<Out> a, b;
            auto r = run_batch(*instance_, {fixed}, 0, 1, TALUS_BATCH_WANT_WAVE_SPEED, a);
            if (!r.ok()) return report("objectivity", false, r.message);
            r = run_batch(*instance_, {turned}, 0, 1, TALUS_BATCH_WANT_WAVE_SPEED, b);
            if (!r.ok()) return report("objectivity", false, "after the rotation: " + r.message);
            const Mat3 expected = R * sdk::stress_to_matrix(a[0].s1) * R.transpose();
            const double scale = std::max(a[0].s1.cwiseAbs().maxCoeff(), stress_scale_);
            const double d =
                (sdk::matrix_to_stress(expected) - b[0].s1).cwiseAbs().maxCoeff() / scale;
            if (d > worst) worst = d, worst_state = k;
        }
        // Rotating a stress costs a few ulps of its largest component.
        report("objectivity", worst <= 1e-10,
               fmt::format("a rigid rotation of 70 deg about [1, 2, 3] superposed on {} loaded "
                           "states: largest difference from R sigma R^T {:.3g} of the stress "
                           "(limit 1e-10){}",
                           states_.size(), worst,
                           worst > 1e-10 ? fmt::format(", at state {}", worst_state) : ""));
    }

    void threads() {
        start("threads");
        const std::vector<Pt> pts = points(false, 16);
        const std::uint32_t flags = full_flags();
        std::vector<Out> serial;
        auto r = run_batch(*instance_, pts, 0, pts.size(), flags, serial);
        if (!r.ok()) return report("threads", false, r.message);
        // Two threads hammer disjoint halves of the same instance; any
        // shared mutable state in the plugin shows up as a difference.
        const std::size_t half = pts.size() / 2;
        std::vector<Out> a, b;
        MaterialInstance::Result ra, rb;
        auto work = [&](std::size_t begin, std::size_t n, std::vector<Out> &out,
                        MaterialInstance::Result &res) {
            for (int rep = 0; rep < 50 && res.ok(); ++rep) {
                out.clear();
                std::vector<Out> tmp;
                res = run_batch(*instance_, pts, begin, n, flags, tmp);
                out.assign(tmp.begin() + static_cast<std::ptrdiff_t>(begin), tmp.end());
            }
        };
        std::thread t1(work, 0, half, std::ref(a), std::ref(ra));
        std::thread t2(work, half, pts.size() - half, std::ref(b), std::ref(rb));
        t1.join();
        t2.join();
        if (!ra.ok() || !rb.ok())
            return report("threads", false, ra.ok() ? rb.message : ra.message);
        a.insert(a.end(), b.begin(), b.end());
        const double d = max_difference(serial, a, stress_scale_, true, model_.has_tangent());
        report("threads", d <= kInvariance,
               fmt::format("2 threads x 50 batches on one instance: largest relative difference "
                           "from serial {:.3g} (limit {:g})",
                           d, kInvariance));
    }
};

void library_checks(const std::filesystem::path &file, const CheckOptions &opt, Sink &sink) {
    sink.starting("", "exports");
    try {
        const std::vector<std::string> syms = exported_symbols(file);
        std::vector<std::string> talus_syms, others;
        for (const auto &s : syms)
            (s.rfind("talus_", 0) == 0 ? talus_syms : others).push_back(s);
        const bool ok = talus_syms.size() == 1 && talus_syms[0] == TALUS_MATERIAL_ENTRY_SYMBOL;
        std::string list;
        for (const auto &s : talus_syms)
            list += (list.empty() ? "" : ", ") + s;
        sink.emit(CheckOutcome{
            "", "exports", ok,
            ok ? fmt::format("exactly one talus_ symbol, {}; {} other exported symbol(s)",
                             TALUS_MATERIAL_ENTRY_SYMBOL, others.size())
               : fmt::format(
                     "expected exactly one exported talus_ symbol ({}), found {}: {} (build "
                     "with talus_add_plugin, or hide the rest with -fvisibility=hidden)",
                     TALUS_MATERIAL_ENTRY_SYMBOL, talus_syms.size(),
                     list.empty() ? "none" : list)});
    } catch (const Error &e) {
        sink.emit(CheckOutcome{"", "exports", false, e.what()});
    }

    sink.starting("", "load");
    std::shared_ptr<PluginLibrary> lib;
    try {
        lib = PluginLibrary::open(file);
    } catch (const Error &e) {
        sink.emit(CheckOutcome{"", "load", false, e.what()});
        return;
    }
    std::string ids;
    for (const Model &m : lib->models())
        ids += (ids.empty() ? "" : ", ") + m.id();
    sink.emit(CheckOutcome{"", "load", true,
                           fmt::format("library '{}' {} built for ABI {}.{}; descriptors valid; "
                                       "models: {}",
                                       lib->name(), lib->version(), lib->abi_major(),
                                       lib->abi_minor(), ids)});
    for (const Model &m : lib->models())
        ModelChecks(m, opt, sink).run();
}

// Lines over the pipe: "S\tmodel\tname" (starting) or "P|F\tmodel\tname\tdetail".
std::string escape(const std::string &s) {
    std::string o;
    for (char c : s)
        o += (c == '\n' ? '\x1f' : (c == '\t' ? ' ' : c));
    return o;
}
std::string unescape(const std::string &s) {
    std::string o = s;
    for (char &c : o)
        if (c == '\x1f') c = '\n';
    return o;
}

std::vector<std::string> split_tabs(const std::string &line) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    while (true) {
        const std::size_t t = line.find('\t', start);
        parts.push_back(line.substr(start, t == std::string::npos ? std::string::npos : t - start));
        if (t == std::string::npos) break;
        start = t + 1;
    }
    return parts;
}

} // namespace

ConformanceReport check_plugin(const std::filesystem::path &file, const CheckOptions &opt) {
    ConformanceReport rep;
    rep.library = file;
    if (!opt.isolate) {
        Sink sink{[&](const CheckOutcome &o) { rep.outcomes.push_back(o); },
                  [](const std::string &, const std::string &) {}};
        library_checks(file, opt, sink);
        return rep;
    }
    int fds[2];
    if (pipe(fds) != 0) throw Error("plugin check: cannot create a pipe");
    const pid_t pid = fork();
    if (pid < 0) throw Error("plugin check: cannot fork");
    if (pid == 0) {
        close(fds[0]);
        auto put = [&](const std::string &line) {
            const std::string l = line + "\n";
            std::size_t off = 0;
            while (off < l.size()) {
                const ssize_t w = write(fds[1], l.data() + off, l.size() - off);
                if (w <= 0) _exit(3);
                off += static_cast<std::size_t>(w);
            }
        };
        Sink sink{[&](const CheckOutcome &o) {
                      put(fmt::format("{}\t{}\t{}\t{}", o.passed ? 'P' : 'F', o.model, o.name,
                                      escape(o.detail)));
                  },
                  [&](const std::string &m, const std::string &n) {
                      put(fmt::format("S\t{}\t{}", m, n));
                  }};
        try {
            library_checks(file, opt, sink);
        } catch (const std::exception &e) {
            put(fmt::format("F\t\tchecker\t{}", escape(e.what())));
        }
        close(fds[1]);
        _exit(0); // no atexit handlers or static destructors of the parent's state
    }
    close(fds[1]);
    std::string buf, cur_model, cur_name;
    char chunk[4096];
    ssize_t n;
    while ((n = read(fds[0], chunk, sizeof chunk)) > 0)
        buf.append(chunk, static_cast<std::size_t>(n));
    close(fds[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    std::size_t pos = 0;
    while (true) {
        const std::size_t nl = buf.find('\n', pos);
        if (nl == std::string::npos) break;
        const std::vector<std::string> f = split_tabs(buf.substr(pos, nl - pos));
        pos = nl + 1;
        if (f.size() >= 3 && f[0] == "S") {
            cur_model = f[1];
            cur_name = f[2];
        } else if (f.size() >= 4) {
            rep.outcomes.push_back(CheckOutcome{f[1], f[2], f[0] == "P", unescape(f[3])});
            cur_name.clear();
        }
    }
    if (WIFSIGNALED(status) || (WIFEXITED(status) && WEXITSTATUS(status) != 0)) {
        const std::string how = WIFSIGNALED(status)
                                    ? fmt::format("crashed with signal {} ({})", WTERMSIG(status),
                                                  strsignal(WTERMSIG(status)))
                                    : fmt::format("exited with status {}", WEXITSTATUS(status));
        rep.outcomes.push_back(CheckOutcome{cur_model, cur_name.empty() ? "checker" : cur_name,
                                            false, "the plugin " + how + " during this check"});
    }
    return rep;
}

void print_report(std::ostream &out, const ConformanceReport &rep) {
    out << "talus plugin check: " << rep.library.string() << '\n';
    std::string model = "\x01";
    for (const CheckOutcome &o : rep.outcomes) {
        if (o.model != model) {
            model = o.model;
            if (!model.empty()) out << "model " << model << '\n';
        }
        std::string detail = o.detail;
        for (std::size_t p = 0; (p = detail.find('\n', p)) != std::string::npos; p += 9)
            detail.replace(p, 1, "\n        ");
        out << fmt::format("  {}  {:<16} {}\n", o.passed ? "PASS" : "FAIL", o.name, detail);
    }
    const std::size_t total = rep.outcomes.size(), bad = rep.failures();
    if (bad == 0)
        out << fmt::format("result: all {} checks passed\n", total);
    else
        out << fmt::format("result: {} of {} checks FAILED\n", bad, total);
}

} // namespace talus
