// The material-point driver's run (talus/driver/point_driver.hpp): each
// increment's six conditions solved by Newton iteration on the strain
// increment, with the plugin's stress and tangent.
#include <talus/driver/point_driver.hpp>

#include <talus/material/cut_step.hpp>
#include <talus/sdk/kinematics.hpp>
#include <talus/sdk/voigt.hpp>

#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <ostream>

namespace talus {

using Vec6 = PointVec6;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat3 = Eigen::Matrix3d;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

namespace {

// Rotation by `angle` about the unit vector n (Rodrigues).
Mat3 rotation(const Eigen::Vector3d &axis, double angle) {
    return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

struct PointState {
    Vec6 eps = Vec6::Zero(); // accumulated Hencky increments, tensor components
    Mat3 F = Mat3::Identity();
    Vec6 stress = Vec6::Zero();
    std::vector<double> state;
};

// Engineering-shear Voigt from tensor components and back.
Vec6 to_engineering(const Vec6 &e) {
    Vec6 g = e;
    g.tail<3>() *= 2.0;
    return g;
}

struct Call {
    Vec6 stress;
    std::vector<double> state;
    Mat6 D; // d stress / d tensor-component strain increment
    MaterialInstance::Result result;
};

class Runner {
  public:
    Runner(const PointCase &pc, std::vector<PointRow> &rows) : pc_(pc), rows_(rows) {}

    void run() {
        PointState s;
        s.stress = pc_.initial_stress;
        s.state = pc_.material.initial_state;
        double t = 0.0;
        // A model with init_state brings the initial stress and state to a
        // start it accepts, as in the solver (material_abi.h). Without it
        // the driver starts from the case's values as given.
        if (model().has_init_state()) {
            const Call c = call(s, Vec6::Zero(), s.F, 0.0, 0.0, false, Mat3::Identity(), true);
            if (!c.result.ok())
                throw Error(fmt::format("{}: error: the initial state: model '{}' (init_state): "
                                        "{}",
                                        pc_.file, model().id(), c.result.message));
            s.stress = c.stress;
            s.state = c.state;
        }
        record(t, 0, s);
        for (std::size_t k = 0; k < pc_.stages.size(); ++k) {
            stage_index_ = static_cast<int>(k);
            t = run_stage(pc_.stages[k], t, s);
        }
    }

  private:
    const PointCase &pc_;
    std::vector<PointRow> &rows_;
    int stage_index_ = 0;
    Vec6 last_de_ = Vec6::Zero();

    const Model &model() const { return pc_.instance->model(); }

    void record(double t, int stage, const PointState &s) {
        rows_.push_back(PointRow{t, stage, s.eps, s.stress, s.state});
    }

    [[noreturn]] void fail(const Stage &st, double t, const std::string &why) const {
        throw Error(fmt::format("{}: error: stage '{}' (number {}), t = {:.9g}: {}", st.where,
                                st.name, stage_index_ + 1, t, why));
    }

    // One plugin call from `s` with the tensor strain increment de and the
    // end deformation gradient F1.
    // R: the increment's rotation (talus_batch.rotation); setup: the set-up
    // call (init_state).
    Call call(const PointState &s, const Vec6 &de, const Mat3 &F1, double t, double dt,
              bool want_tangent, const Mat3 &R = Mat3::Identity(), bool setup = false) const {
        return call_with_density(s, de, F1, t, dt, pc_.material.density / F1.determinant(),
                                 want_tangent, R, setup);
    }
    Call call_with_density(const PointState &s, const Vec6 &de, const Mat3 &F1, double t, double dt,
                           double rho, bool want_tangent = false, const Mat3 &R = Mat3::Identity(),
                           bool setup = false) const {
        Call c;
        c.state.resize(s.state.size());
        const Vec6 g = to_engineering(de);
        const RowMat3 F0r = s.F, F1r = F1, Rr = R;
        // One point: its id is 0; the driver numbers its increments from 1
        // in the order it computes them (a retried one keeps its number).
        const std::int64_t id = 0;
        const double length = pc_.characteristic_length;
        double wave = 0.0;
        Eigen::Matrix<double, 6, 6, Eigen::RowMajor> D;
        talus_batch b{};
        b.flags = TALUS_BATCH_WANT_WAVE_SPEED | (want_tangent ? TALUS_BATCH_WANT_TANGENT : 0u);
        b.n_points = 1;
        b.time = t;
        b.dt = dt;
        b.strain_increment = g.data();
        b.F_start = F0r.data();
        b.F_end = F1r.data();
        b.density = &rho;
        b.stress_start = s.stress.data();
        b.state_start = s.state.empty() ? nullptr : s.state.data();
        b.stress_end = c.stress.data();
        b.state_end = c.state.empty() ? nullptr : c.state.data();
        b.wave_speed = &wave;
        b.tangent = D.data();
        b.step = setup ? 0 : static_cast<std::int64_t>(rows_.size());
        b.point_id = &id;
        b.characteristic_length = &length;
        b.rotation = Rr.data();
        c.result = setup ? pc_.instance->start(b) : pc_.instance->update(b);
        if (want_tangent) {
            // The plugin differentiates by engineering shear; the driver's
            // unknowns are tensor components: columns 3..5 double.
            c.D = D;
            c.D.rightCols<3>() *= 2.0;
        }
        return c;
    }

    // Values of the six conditions at stage time tau.
    static double value_at(const Condition &c, double v0, double tau, double duration) {
        switch (c.value.kind) {
        case ControlValue::Kind::change: return v0 + c.value.amount * tau / duration;
        case ControlValue::Kind::target: return v0 + (c.value.amount - v0) * tau / duration;
        case ControlValue::Kind::rate: return v0 + c.value.amount * tau;
        case ControlValue::Kind::table: return c.value.table(tau);
        }
        return v0;
    }

    // Solves one increment of a condition stage from `s` to the targets at
    // stage time tau1; splits it on cut-step requests and Newton failures.
    void increment(const Stage &st, const std::array<double, 6> &v0, double t_stage0, double tau0,
                   double tau1, PointState &s, double fraction) {
        const double dt = tau1 - tau0;
        const double t0 = t_stage0 + tau0;
        Eigen::Matrix<double, 6, 6> A, B;
        Vec6 v;
        for (int r = 0; r < 6; ++r) {
            const Condition &c = st.conditions[static_cast<std::size_t>(r)];
            A.row(r) = c.a.transpose();
            B.row(r) = c.b.transpose();
            v[r] = value_at(c, v0[static_cast<std::size_t>(r)], tau1, st.duration);
        }
        const bool pure_strain = B.isZero();
        Attempt at;
        Vec6 de = Vec6::Zero();
        Call c;
        if (pure_strain) {
            const Eigen::FullPivLU<Mat6> lu(A);
            if (!lu.isInvertible())
                fail(st, t0, "the strain conditions do not determine the strain (singular)");
            de = lu.solve(v - A * s.eps);
            c = call(s, de, sdk::exp_symmetric(sdk::stress_to_matrix(de)) * s.F, t0, dt, false);
            at = classify(c);
        } else {
            at = newton(A, B, v, s, t0, dt, de, c);
        }
        if (at.outcome == Outcome::ok) {
            s.F = sdk::exp_symmetric(sdk::stress_to_matrix(de)) * s.F;
            s.eps += de;
            s.stress = c.stress;
            s.state = std::move(c.state);
            last_de_ = de;
            return;
        }
        if (at.outcome == Outcome::failed)
            fail(st, t0,
                 fmt::format("model '{}' ({}) failed: {}", model().id(),
                             model().library().path().string(), at.why));
        // Cut-step request or Newton failure: split the increment, by the
        // hosts' one policy (cut_step.hpp; a Newton failure halves).
        const long n = cut_step::parts(at.cut, fraction);
        if (n == 0)
            fail(st, t0,
                 fmt::format("gave up after cutting the increment to {:.3g} of the stage's "
                             "increment (now {:.3g} s): {}",
                             fraction, dt, at.why));
        last_de_ /= static_cast<double>(n);
        for (long k = 0; k < n; ++k) {
            const double a = tau0 + dt * static_cast<double>(k) / static_cast<double>(n);
            const double b =
                k + 1 == n ? tau1 : tau0 + dt * static_cast<double>(k + 1) / static_cast<double>(n);
            increment(st, v0, t_stage0, a, b, s, fraction / static_cast<double>(n));
        }
    }

    enum class Outcome { ok, cut, newton, failed };
    struct Attempt {
        Outcome outcome = Outcome::ok;
        std::string why;
        double cut = 0.5;
    };

    static Attempt classify(const Call &c) {
        if (c.result.ok()) return {};
        if (c.result.status == TALUS_STATUS_CUT_STEP)
            return {Outcome::cut, "the model asked for a smaller step: " + c.result.message,
                    c.result.cut_factor};
        return {Outcome::failed, c.result.message, 0.5};
    }

    // Newton iteration on the tensor strain increment for the mixed
    // conditions A (eps0 + de) + B sigma(de) = v. The Jacobian is A + B D,
    // D the plugin's tangent or forward differences.
    Attempt newton(const Mat6 &A, const Mat6 &B, const Vec6 &v, const PointState &s, double t0,
                   double dt, Vec6 &de, Call &c) {
        const bool tangent = model().has_tangent();
        // Start from the previous increment: near-exact on smooth paths.
        de = last_de_;
        double residual = 0.0;
        bool singular = false;
        for (int it = 0; it < 40; ++it) {
            c = call(s, de, sdk::exp_symmetric(sdk::stress_to_matrix(de)) * s.F, t0, dt, tangent);
            if (!c.result.ok()) return classify(c);
            if (!tangent) c.D = fd_tangent(s, de, c.stress, t0, dt);
            const Vec6 R = A * (s.eps + de) + B * c.stress - v;
            // Convergence in stress units: strain rows are weighted by the
            // largest diagonal modulus M; 1e-10 of the stress (or of
            // M * 1e-6 near zero stress) is far below any measurement and
            // above the rounding of the model.
            const double M = std::max(c.D.diagonal().cwiseAbs().maxCoeff(), 1e-300);
            Vec6 Rs = R;
            for (int r = 0; r < 6; ++r)
                if (B.row(r).isZero()) Rs[r] *= M;
            const double scale =
                std::max({c.stress.cwiseAbs().maxCoeff(), s.stress.cwiseAbs().maxCoeff(),
                          v.cwiseAbs().maxCoeff(), 1e-6 * M});
            residual = Rs.cwiseAbs().maxCoeff();
            if (residual <= 1e-10 * scale) return {};
            // The minimum-norm Newton step: at an edge of a perfectly
            // plastic surface the conditions can leave part of the strain
            // increment undetermined (e.g. the split of the lateral strains
            // of a drained triaxial test between two active planes); the
            // smallest correction picks the symmetric solution there.
            // Conditions that contradict each other leave a residual that
            // the loop below reports.
            const Mat6 J = A + B * c.D;
            Eigen::CompleteOrthogonalDecomposition<Mat6> cod(J);
            cod.setThreshold(1e-12);
            if (cod.rank() == 0)
                return {Outcome::newton,
                        fmt::format("the conditions do not determine the strain increment "
                                    "(Jacobian A + B D is zero); residual {:.3g} (stress units)",
                                    residual),
                        0.5};
            singular = cod.rank() < 6;
            de -= cod.solve(R);
        }
        return {Outcome::newton,
                fmt::format("Newton iteration did not converge in 40 iterations: largest "
                            "residual {:.3g} (stress units){}",
                            residual,
                            singular ? "; the Jacobian A + B D is singular: the conditions may "
                                       "ask for a stress beyond the material's strength"
                                     : ""),
                0.5};
    }

    Mat6 fd_tangent(const PointState &s, const Vec6 &de, const Vec6 &sig, double t0,
                    double dt) const {
        Mat6 D;
        for (int j = 0; j < 6; ++j) {
            Vec6 d = de;
            // Forward differences: h ~ sqrt(eps) of the strain scale.
            const double h = 1e-8 * std::max(1.0, 1e4 * std::abs(de[j]));
            d[j] += h;
            const Call c =
                call(s, d, sdk::exp_symmetric(sdk::stress_to_matrix(d)) * s.F, t0, dt, false);
            D.col(j) = c.result.ok() ? Vec6((c.stress - sig) / h) : Vec6::Zero();
        }
        return D;
    }

    // A rigid rotation increment: the strain-increment models get a zero
    // strain increment and the start stress rotated exactly by the
    // increment's rotation (the finite-strain ones compute from F).
    // One increment of a prescribed motion to F1. The increment dF = F1
    // F_n^-1 = V R (polar decomposition, from its SVD) is a stretch V after
    // a rotation R: a strain-increment model gets its start stress rotated
    // exactly, R sigma R^T, and the strain increment ln V; a finite-strain
    // model computes from F1.
    void deform(const Stage &st, const Mat3 &F1, double t0, double dt, PointState &s) {
        const Mat3 dF = F1 * s.F.inverse();
        const Eigen::JacobiSVD<Mat3> svd(dF, Eigen::ComputeFullU | Eigen::ComputeFullV);
        if (!(dF.determinant() > 0.0))
            fail(st, t0,
                 fmt::format("the prescribed F inverts the material (det dF = {:.6g})",
                             dF.determinant()));
        const Mat3 &U = svd.matrixU();
        const Mat3 R = U * svd.matrixV().transpose();
        const Mat3 lnV =
            U * svd.singularValues().array().log().matrix().asDiagonal() * U.transpose();
        const Vec6 de = sdk::matrix_to_stress(lnV); // tensor components
        PointState start = s;
        if (!model().finite_strain())
            start.stress =
                sdk::matrix_to_stress(R * sdk::stress_to_matrix(s.stress) * R.transpose());
        const Call c = call(start, de, F1, t0, dt, false, R);
        if (c.result.status == TALUS_STATUS_CUT_STEP)
            fail(st, t0,
                 fmt::format("model '{}' asks for a smaller step; a prescribed-F stage "
                             "does not cut its increments: give more increments ({})",
                             model().id(), c.result.message));
        if (!c.result.ok())
            fail(st, t0, fmt::format("model '{}' failed: {}", model().id(), c.result.message));
        s.F = F1;
        s.eps += de;
        s.stress = c.stress;
        s.state = c.state;
    }

    // The replayed call: exactly the recorded inputs, one call, no cuts.
    double replay(const Stage &st, double t, PointState &s) {
        const ReplayCall &r = *st.replay;
        PointState start;
        start.stress = r.stress;
        start.state = r.state;
        start.F = Eigen::Map<const RowMat3>(r.F_start.data());
        start.eps = s.eps;
        Vec6 de = r.strain_increment;
        de.tail<3>() *= 0.5; // call() takes tensor components
        const Mat3 F1 = Eigen::Map<const RowMat3>(r.F_end.data());
        Call c = call_with_density(start, de, F1, r.time, r.dt, r.density);
        if (c.result.status == TALUS_STATUS_CUT_STEP)
            fail(st, r.time,
                 fmt::format("model '{}' ({}) asks for a smaller step (factor {:g}): {}",
                             model().id(), model().library().path().string(), c.result.cut_factor,
                             c.result.message));
        if (!c.result.ok())
            fail(st, r.time,
                 fmt::format("model '{}' ({}) failed: {}", model().id(),
                             model().library().path().string(), c.result.message));
        s = start;
        s.F = F1;
        s.eps += de;
        s.stress = c.stress;
        s.state = c.state;
        record(t + r.dt, stage_index_ + 1, s);
        return t + r.dt;
    }

    // Runs one stage from global time t; returns the time at its end.
    double run_stage(const Stage &st, double t, PointState &s) {
        const int number = stage_index_ + 1;
        if (st.replay) return replay(st, t, s);
        if (st.zero_strain) {
            // The lab's reset after consolidation: strains count from here
            // (F, and so the density, keeps the whole history).
            s.eps.setZero();
            record(t, number, s);
        }
        if (st.rotation) {
            const Eigen::Vector3d axis(st.rotation->axis[0], st.rotation->axis[1],
                                       st.rotation->axis[2]);
            const double angle = st.rotation->angle;
            const double dt = st.duration / static_cast<double>(st.increments);
            const Mat3 step = rotation(axis, angle / static_cast<double>(st.increments));
            for (long n = 0; n < st.increments; ++n) {
                deform(st, step * s.F, t + dt * static_cast<double>(n), dt, s);
                if ((n + 1) % pc_.output_every == 0 || n + 1 == st.increments)
                    record(t + dt * static_cast<double>(n + 1), number, s);
            }
            return t + st.duration;
        }
        if (st.deformation) {
            const double dt = st.duration / static_cast<double>(st.increments);
            for (long n = 0; n < st.increments; ++n) {
                const double tau =
                    n + 1 == st.increments ? st.duration : dt * static_cast<double>(n + 1);
                Mat3 F1;
                for (int k = 0; k < 9; ++k)
                    F1(k / 3, k % 3) = (*st.deformation)[static_cast<std::size_t>(k)](tau);
                deform(st, F1, t + dt * static_cast<double>(n), dt, s);
                if ((n + 1) % pc_.output_every == 0 || n + 1 == st.increments)
                    record(t + tau, number, s);
            }
            return t + st.duration;
        }
        std::array<double, 6> v0{};
        for (std::size_t r = 0; r < 6; ++r)
            v0[r] = st.conditions[r].a.dot(s.eps) + st.conditions[r].b.dot(s.stress);
        auto met = [&](const PointState &x, double time) {
            if (!st.until) return false;
            const PointRow row{time, number, x.eps, x.stress, x.state};
            const double q =
                st.until->variable == "stage_time"
                    ? time - t
                    : *point_quantity(row, *pc_.instance, pc_.axis, st.until->variable);
            const std::string &op = st.until->op;
            const double th = st.until->threshold;
            return op == ">=" ? q >= th : op == "<=" ? q <= th : op == ">" ? q > th : q < th;
        };
        if (met(s, t)) return t; // already satisfied: nothing to do
        const double dtau = st.duration / static_cast<double>(st.increments);
        for (long n = 0; n < st.increments; ++n) {
            const double tau0 = dtau * static_cast<double>(n);
            const double tau1 = n + 1 == st.increments ? st.duration : tau0 + dtau;
            PointState before = s;
            increment(st, v0, t, tau0, tau1, s, 1.0);
            if (met(s, t + tau1)) {
                // Land on the crossing: bisect the increment's fraction
                // (the conditions are linear in tau within it) to 1e-12 of
                // the increment.
                double lo = 0.0, hi = 1.0;
                PointState at_hi = s;
                for (int it = 0; it < 45; ++it) {
                    const double mid = 0.5 * (lo + hi);
                    PointState x = before;
                    last_de_.setZero();
                    increment(st, v0, t, tau0, tau0 + mid * (tau1 - tau0), x, 1.0);
                    if (met(x, t + tau0 + mid * (tau1 - tau0))) {
                        hi = mid;
                        at_hi = x;
                    } else
                        lo = mid;
                }
                s = at_hi;
                const double tend = t + tau0 + hi * (tau1 - tau0);
                record(tend, number, s);
                return tend;
            }
            if ((n + 1) % pc_.output_every == 0 || n + 1 == st.increments)
                record(t + tau1, number, s);
        }
        if (st.until) {
            const PointRow row{t + st.duration, number, s.eps, s.stress, s.state};
            const auto q = st.until->variable == "stage_time"
                               ? std::optional<double>(st.duration)
                               : point_quantity(row, *pc_.instance, pc_.axis, st.until->variable);
            fail(st, t + st.duration,
                 fmt::format("the stage ended (duration {:g}) without reaching '{}' ({} = {:.9g}); "
                             "lengthen the stage or change the condition",
                             st.duration, st.until->text, st.until->variable, q.value_or(0.0)));
        }
        return t + st.duration;
    }
};

} // namespace

void run_point_case(const PointCase &pc, std::vector<PointRow> &rows) {
    rows.clear();
    Runner(pc, rows).run();
}

std::vector<PointRow> run_point_case(const PointCase &pc) {
    std::vector<PointRow> rows;
    run_point_case(pc, rows);
    return rows;
}

} // namespace talus
