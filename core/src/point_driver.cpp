#include <talus/point_driver.hpp>

#include <talus/sdk/voigt.hpp>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <sstream>
#include <unistd.h>

namespace talus {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;

// ------------------------------------------------------------- reading --

namespace {
constexpr std::array<std::string_view, 6> kComponents = {"xx", "yy", "zz", "xy", "yz", "xz"};
} // namespace

PointCase read_point_case(const yaml::Node &root, PluginRegistry &registry) {
    constexpr std::array<std::string_view, 7> top = {
        "talus", "plugins", "material", "initial_stress", "time", "strain", "output"};
    root.allow_keys(top);
    const yaml::Node version = root.require("talus");
    if (version.as_integer() != 1)
        version.fail(fmt::format("unsupported file format version {}; this talus reads version 1",
                                 version.as_integer()));

    if (const yaml::Node plugins = root.get("plugins"); plugins.defined())
        load_plugin_list(plugins, registry);

    PointCase pc;
    const yaml::Node mat = root.require("material");
    pc.material = read_material(mat, registry);
    pc.instance = instantiate(pc.material, mat);

    if (const yaml::Node s0 = root.get("initial_stress"); s0.defined()) {
        const std::vector<double> v = s0.as_doubles();
        if (v.size() != 6)
            s0.fail(fmt::format(
                "expected 6 stress components [xx, yy, zz, xy, yz, xz] in Pa, got {}", v.size()));
        for (int i = 0; i < 6; ++i)
            pc.initial_stress[i] = v[static_cast<std::size_t>(i)];
    }

    const yaml::Node time = root.require("time");
    constexpr std::array<std::string_view, 2> time_keys = {"end", "increments"};
    time.allow_keys(time_keys);
    const yaml::Node end = time.require("end");
    pc.end_time = end.as_double();
    if (!(pc.end_time > 0.0)) end.fail(fmt::format("expected end > 0 (s), got {:g}", pc.end_time));
    const yaml::Node inc = time.require("increments");
    pc.increments = inc.as_integer();
    if (pc.increments < 1 || pc.increments > 100000000)
        inc.fail(fmt::format("expected 1 <= increments <= 1e8, got {}", pc.increments));

    const yaml::Node strain = root.require("strain");
    strain.allow_keys(kComponents);
    for (std::size_t c = 0; c < 6; ++c)
        if (const yaml::Node f = strain.get(kComponents[c]); f.raw().IsDefined())
            pc.strain[c] = PiecewiseLinear::read(f);

    if (const yaml::Node out = root.get("output"); out.defined()) {
        constexpr std::array<std::string_view, 1> out_keys = {"every"};
        out.allow_keys(out_keys);
        if (const yaml::Node every = out.get("every"); every.defined()) {
            pc.output_every = every.as_integer();
            if (pc.output_every < 1) every.fail("expected every >= 1 (increments)");
        }
    }
    return pc;
}

// ------------------------------------------------------------- running --

namespace {

Mat3 strain_tensor(const PointCase &pc, double t) {
    Vec6 e;
    for (int c = 0; c < 6; ++c)
        e[c] = pc.strain[static_cast<std::size_t>(c)](t);
    return sdk::stress_to_matrix(e); // tensor shear components, as given
}

// exp of a symmetric matrix through its spectral decomposition.
Mat3 expm_symmetric(const Mat3 &a) {
    const Eigen::SelfAdjointEigenSolver<Mat3> es(a);
    return es.eigenvectors() * es.eigenvalues().array().exp().matrix().asDiagonal() *
           es.eigenvectors().transpose();
}

struct PointStateNow {
    Mat3 eps;
    Vec6 stress;
    std::vector<double> state;
};

// Advances from `now` to strain eps1 over dt, splitting on cut-step requests.
void advance(const PointCase &pc, double t0, double dt, const Mat3 &eps1, PointStateNow &now,
             int depth) {
    const Model &model = pc.instance->model();
    const Mat3 F0 = expm_symmetric(now.eps);
    const Mat3 F1 = expm_symmetric(eps1);
    const Vec6 de = sdk::matrix_to_strain(eps1 - now.eps);
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> F0r = F0, F1r = F1;
    const double rho = pc.material.density / F1.determinant();
    Vec6 s1;
    std::vector<double> q1(now.state.size());
    double c = 0.0;

    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED;
    b.n_points = 1;
    b.time = t0;
    b.dt = dt;
    b.strain_increment = de.data();
    b.F_start = F0r.data();
    b.F_end = F1r.data();
    b.density = &rho;
    b.stress_start = now.stress.data();
    b.state_start = now.state.empty() ? nullptr : now.state.data();
    b.stress_end = s1.data();
    b.state_end = q1.empty() ? nullptr : q1.data();
    b.wave_speed = &c;
    const MaterialInstance::Result r = pc.instance->update(b);
    if (r.status == TALUS_STATUS_CUT_STEP) {
        // Each level divides the increment by at least 2; 30 levels reach
        // dt / 1e9, beyond which the model is not converging, not cutting.
        if (depth >= 30)
            throw Error(fmt::format("model '{}' ({}) keeps asking for a smaller step at t = {:g}: "
                                    "gave up after 30 cuts (dt = {:g}): {}",
                                    model.id(), model.library().path().string(), t0, dt,
                                    r.message));
        const long n = std::max(2L, static_cast<long>(std::ceil(1.0 / r.cut_factor)));
        const Mat3 eps0 = now.eps;
        for (long k = 1; k <= n; ++k) {
            const double w = static_cast<double>(k) / static_cast<double>(n);
            advance(pc, t0 + (w - 1.0 / static_cast<double>(n)) * dt, dt / static_cast<double>(n),
                    eps0 + w * (eps1 - eps0), now, depth + 1);
        }
        return;
    }
    if (!r.ok())
        throw Error(fmt::format("model '{}' ({}) failed in the increment starting at t = {:g}: {}",
                                model.id(), model.library().path().string(), t0, r.message));
    now.eps = eps1;
    now.stress = s1;
    now.state = std::move(q1);
}

} // namespace

std::vector<PointRow> run_point_case(const PointCase &pc) {
    PointStateNow now{strain_tensor(pc, 0.0), pc.initial_stress, pc.material.initial_state};
    std::vector<PointRow> rows;
    auto record = [&](double t) {
        rows.push_back(PointRow{t, sdk::matrix_to_stress(now.eps), now.stress, now.state});
    };
    record(0.0);
    const double dt = pc.end_time / static_cast<double>(pc.increments);
    for (long n = 0; n < pc.increments; ++n) {
        const double t0 = dt * static_cast<double>(n);
        const double t1 = n + 1 == pc.increments ? pc.end_time : dt * static_cast<double>(n + 1);
        advance(pc, t0, t1 - t0, strain_tensor(pc, t1), now, 0);
        if ((n + 1) % pc.output_every == 0 || n + 1 == pc.increments) record(t1);
    }
    return rows;
}

void write_point_csv(std::ostream &out, const Model &model, const std::vector<PointRow> &rows) {
    out << "time";
    for (auto c : kComponents)
        out << ",eps_" << c;
    for (auto c : kComponents)
        out << ",sig_" << c;
    out << ",p,q";
    for (const StateInfo &s : model.state()) {
        if (s.size == 1)
            out << ',' << s.name;
        else
            for (std::uint32_t k = 0; k < s.size; ++k)
                out << ',' << s.name << '_' << k;
    }
    out << '\n';
    // 17 significant digits: the CSV round-trips every double exactly.
    for (const PointRow &r : rows) {
        out << fmt::format("{:.17g}", r.time);
        for (int c = 0; c < 6; ++c)
            out << fmt::format(",{:.17g}", r.strain[c]);
        for (int c = 0; c < 6; ++c)
            out << fmt::format(",{:.17g}", r.stress[c]);
        out << fmt::format(",{:.17g},{:.17g}", sdk::mean_pressure(r.stress),
                           sdk::von_mises(r.stress));
        for (double v : r.state)
            out << fmt::format(",{:.17g}", v);
        out << '\n';
    }
}

} // namespace talus
