// The shipped Mohr-Coulomb plugin: the peer's test vectors
// (tests/data/cbgeo_mohr_coulomb_vectors.csv), the partition of the trial
// space among the return candidates, the consistent tangent at each kind of
// return, implicit softening, the parameter bounds and the treatment of a
// start stress outside the surface.
#include "batches.hpp"
#include "test_paths.hpp"

#include "mohr_coulomb/plane_lanes.hpp"
#include "mohr_coulomb/principal_return.hpp"

#include <talus/sdk/spectral.hpp>

#include <talus/error.hpp>
#include <talus/material/plugin_loader.hpp>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
using RowMat6 = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;
constexpr double kDeg = std::numbers::pi / 180.0;

const talus::Model &model(talus::PluginRegistry &reg) {
    return reg.load((talus::test::plugin_dir() / "talus_mohr_coulomb.so").string()).models()[0];
}

// An instance from the named parameter values, the rest at their defaults.
std::unique_ptr<talus::MaterialInstance> make(const talus::Model &m,
                                              const std::map<std::string, double> &given) {
    std::vector<double> v;
    for (const talus::ParamInfo &p : m.params()) {
        const auto it = given.find(p.key);
        v.push_back(it != given.end() ? it->second : p.default_value);
    }
    for (const auto &kv : given) {
        bool known = false;
        for (const talus::ParamInfo &p : m.params())
            known |= p.key == kv.first;
        EXPECT_TRUE(known) << kv.first;
    }
    return m.create(v);
}

// phi = 30 deg, psi = 0, c = 0, E = 10 MPa, nu = 0.3.
std::unique_ptr<talus::MaterialInstance> cohesionless(talus::PluginRegistry &reg) {
    return make(model(reg), {{"youngs_modulus", 1e7},
                             {"poisson_ratio", 0.3},
                             {"friction_angle", 30},
                             {"dilation_angle", 0},
                             {"cohesion", 0}});
}

struct Out {
    Vec6 stress;
    RowMat6 D;
    std::vector<double> state;
    talus::MaterialInstance::Result res;
};

// `setup`: the set-up call (init_state) instead of an update.
Out call(const talus::MaterialInstance &mi, const Vec6 &s0, const Vec6 &de,
         std::vector<double> q0 = {0.0, 0.0, 0.0}, bool setup = false) {
    Out o;
    o.state.assign(q0.size(), 0.0);
    const RowMat3 I = RowMat3::Identity();
    const double rho = 2000.0;
    double c = 0.0;
    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED | TALUS_BATCH_WANT_TANGENT;
    b.n_points = 1;
    b.dt = 1.0;
    b.strain_increment = de.data();
    b.F_start = I.data();
    b.F_end = I.data();
    b.density = &rho;
    b.stress_start = s0.data();
    b.state_start = q0.data();
    b.stress_end = o.stress.data();
    b.state_end = o.state.data();
    b.wave_speed = &c;
    b.tangent = o.D.data();
    const std::int64_t id = 41;
    b.point_id = &id;
    o.res = setup ? mi.start(b) : mi.update(b);
    return o;
}

talus_mc::V3 principal(const Vec6 &s) {
    Eigen::Matrix3d m;
    m << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
    const Eigen::Vector3d e = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m).eigenvalues();
    return talus_mc::V3(e[2], e[1], e[0]);
}

// Strength as a test computes it: linear interpolation of the angles and
// the cohesion between the two softening strains (the peer's law too).
talus_mc::Strength strength(double phi, double psi, double c, double T, double kappa = 0.0,
                            double phir = 0.0, double psir = 0.0, double cr = 0.0, double k0 = 0.0,
                            double k1 = 0.0) {
    double w = 0.0;
    if (k1 > k0) w = std::clamp((kappa - k0) / (k1 - k0), 0.0, 1.0);
    phi = (phi + (phir - phi) * w) * kDeg;
    psi = (psi + (psir - psi) * w) * kDeg;
    c = c + (cr - c) * w;
    talus_mc::Strength s;
    s.sin_phi = std::sin(phi);
    s.cos_phi = std::cos(phi);
    s.sin_psi = std::sin(psi);
    s.cohesion = c;
    s.tension = T;
    s.tension_active = !(s.sin_phi > 0 && T * s.sin_phi > c * s.cos_phi);
    return s;
}

std::vector<std::map<std::string, std::string>> read_csv(const std::string &file) {
    std::ifstream in(talus::test::data_dir() / file);
    EXPECT_TRUE(in) << file;
    std::vector<std::map<std::string, std::string>> rows;
    std::string line;
    std::vector<std::string> header;
    // RFC 4180: quoted fields may hold commas, and "" is a quote inside one
    // (the JSON of the state-variable column).
    auto split = [](const std::string &l) {
        std::vector<std::string> out;
        std::string cur;
        bool quoted = false;
        for (std::size_t i = 0; i < l.size(); ++i) {
            const char ch = l[i];
            if (ch == '"') {
                if (quoted && i + 1 < l.size() && l[i + 1] == '"') {
                    cur += '"';
                    ++i;
                } else
                    quoted = !quoted;
            } else if (ch == ',' && !quoted) {
                out.push_back(cur);
                cur.clear();
            } else
                cur += ch;
        }
        out.push_back(cur);
        return out;
    };
    while (std::getline(in, line)) {
        if (!line.empty() && line.back() == '\r') line.pop_back(); // the file has CRLF
        if (line.empty() || line[0] == '#') continue;
        const auto f = split(line);
        if (header.empty()) {
            header = f;
            continue;
        }
        std::map<std::string, std::string> r;
        for (std::size_t i = 0; i < header.size() && i < f.size(); ++i)
            r[header[i]] = f[i];
        rows.push_back(r);
    }
    return rows;
}

// The value of "key": number in the peer's state-variable JSON, or `def`.
double json_number(const std::string &json, const std::string &key, double def) {
    const std::string k = "\"" + key + "\":";
    const auto at = json.find(k);
    if (at == std::string::npos) return def;
    return std::stod(json.substr(at + k.size()));
}

Vec6 vec(const std::map<std::string, std::string> &r, const std::string &prefix) {
    const char *c[] = {"xx", "yy", "zz", "xy", "yz", "xz"};
    Vec6 v;
    for (int i = 0; i < 6; ++i)
        v[i] = std::stod(r.at(prefix + c[i]));
    return v;
}

} // namespace

// The peer's 21 vectors. Trial stress, Haigh-Westergaard invariants and the
// two yield-function values are deterministic functions of the inputs, so
// they are compared to 1e-9 of the stress scale: the CSV prints 16-17
// digits and the eigen decomposition loses a few ulps. The returned stress
// depends on the algorithm (the peer smooths its potential and updates the
// strength explicitly), so only its defining property is compared: on the
// surface of the strength at the end of the increment, on the same surface
// (shear or tension) as the peer's where the peer's is on one.
TEST(MohrCoulomb, PeerVectorsTrialInvariantsYieldValuesAndReturnOnTheSurface) {
    talus::PluginRegistry reg;
    const talus::Model &m = model(reg);
    const auto rows = read_csv("cbgeo_mohr_coulomb_vectors.csv");
    ASSERT_EQ(rows.size(), 21u);
    int n = 0;
    for (const auto &r : rows) {
        SCOPED_TRACE("row " + std::to_string(n++) + ": " + r.at("section"));
        const double E = std::stod(r.at("E")), nu = std::stod(r.at("nu"));
        const double phi = std::stod(r.at("phi_deg")), psi = std::stod(r.at("psi_deg"));
        const double c = std::stod(r.at("c")), T = std::stod(r.at("T"));
        const bool soft = r.at("softening") == "True";
        const double phir = std::stod(r.at("phi_r_deg")), psir = std::stod(r.at("psi_r_deg"));
        const double cr = std::stod(r.at("c_r")), k0 = std::stod(r.at("pdstrain_peak")),
                     k1 = std::stod(r.at("pdstrain_res"));
        const double kappa0 = json_number(r.at("sv_override"), "pdstrain", 0.0);
        const Vec6 s0 = vec(r, "s0_"), trial_ref = vec(r, "trial_");
        // The peer's increments are engineering shear (header: de_gxy).
        Vec6 de;
        de << std::stod(r.at("de_xx")), std::stod(r.at("de_yy")), std::stod(r.at("de_zz")),
            std::stod(r.at("de_gxy")), std::stod(r.at("de_gyz")), std::stod(r.at("de_gxz"));
        const double scale = trial_ref.cwiseAbs().maxCoeff();

        // Trial stress: the plugin's elastic predictor, seen by making the
        // strength unreachable.
        const auto elastic = make(m, {{"youngs_modulus", E},
                                      {"poisson_ratio", nu},
                                      {"friction_angle", phi},
                                      {"cohesion", 1e30},
                                      {"tension_cutoff", 1e30}});
        const Out tr = call(*elastic, s0, de);
        ASSERT_TRUE(tr.res.ok()) << tr.res.message;
        for (int i = 0; i < 6; ++i)
            EXPECT_NEAR(tr.stress[i], trial_ref[i], 1e-9 * scale) << "trial component " << i;

        // Invariants: epsilon = I1 / sqrt 3, rho = sqrt(2 J2), Lode angle
        // theta in [0, pi/3] with cos 3 theta = 3 sqrt 3 / 2 J3 / J2^1.5.
        const talus_mc::V3 p = principal(tr.stress);
        const double I1 = p.sum();
        const talus_mc::V3 d = p - talus_mc::V3::Constant(I1 / 3.0);
        const double J2 = 0.5 * d.squaredNorm(), J3 = d.prod();
        const double theta =
            std::acos(std::clamp(1.5 * std::sqrt(3.0) * J3 / std::pow(J2, 1.5), -1.0, 1.0)) / 3.0;
        EXPECT_NEAR(I1 / std::sqrt(3.0), std::stod(r.at("trial_epsilon")), 1e-9 * scale);
        EXPECT_NEAR(std::sqrt(2.0 * J2), std::stod(r.at("trial_rho")), 1e-9 * scale);
        // theta near 0 or pi/3 is ill-conditioned in acos: 1e-6 rad.
        EXPECT_NEAR(theta, std::stod(r.at("trial_theta")), 1e-6);

        // Yield values, the plugin's planes at the start state's strength:
        // the peer's shear function is the plane divided by 2 cos phi.
        const talus_mc::Strength st = soft
                                          ? strength(phi, psi, c, T, kappa0, phir, psir, cr, k0, k1)
                                          : strength(phi, psi, c, T);
        const double fs_trial = talus_mc::shear_yield(p, st) / (2.0 * st.cos_phi);
        EXPECT_NEAR(fs_trial, std::stod(r.at("F_shear_trial")), 1e-9 * scale);
        EXPECT_NEAR(p[0] - T, std::stod(r.at("F_tens_trial")), 1e-9 * scale);
        const talus_mc::V3 p0 = principal(s0);
        EXPECT_NEAR(talus_mc::shear_yield(p0, st) / (2.0 * st.cos_phi),
                    std::stod(r.at("F_shear_s0")), 1e-9 * scale);

        // The return.
        std::map<std::string, double> params = {{"youngs_modulus", E},   {"poisson_ratio", nu},
                                                {"friction_angle", phi}, {"dilation_angle", psi},
                                                {"cohesion", c},         {"tension_cutoff", T}};
        if (soft) {
            params["softening"] = 1.0;
            params["residual_friction_angle"] = phir;
            params["residual_dilation_angle"] = psir;
            params["residual_cohesion"] = cr;
            params["softening_start"] = k0;
            params["softening_end"] = k1;
        }
        const auto mc = make(m, params);
        const Out o = call(*mc, s0, de, {kappa0, 0.0, 0.0});
        ASSERT_TRUE(o.res.ok()) << o.res.message;
        const double kappa1 = o.state[0];
        EXPECT_GT(kappa1, kappa0); // every row is plastic
        const talus_mc::Strength st1 =
            soft ? strength(phi, psi, c, T, kappa1, phir, psir, cr, k0, k1) : st;
        const talus_mc::V3 q = principal(o.stress);
        const double fs = talus_mc::shear_yield(q, st1) / (2.0 * st1.cos_phi);
        const double ft = st1.tension_active ? q[0] - T : -1.0;
        // On the surface: the larger of the two values is zero and neither
        // is positive, to the rounding of the linear solves.
        EXPECT_NEAR(std::max(fs, ft), 0.0, 1e-9 * scale);
        const double peer_fs = std::stod(r.at("F_shear_at_expected"));
        const double peer_ft = std::stod(r.at("F_tens_at_expected"));
        if (std::abs(peer_fs) < 1e-6 * scale) {
            EXPECT_NEAR(fs, 0.0, 1e-9 * scale) << "shear";
        }
        if (std::abs(peer_ft) < 1e-6 * scale) {
            EXPECT_NEAR(ft, 0.0, 1e-9 * scale) << "tension";
        }
    }
}

// The elasticity of the return's tests (E = 1e7 Pa, nu = 0.3), and a
// strength's parameters (degrees, Pa).
talus_mc::Elastic elastic_of_the_return_tests() {
    talus_mc::Elastic el;
    el.shear = 1e7 / 2.6;
    el.lambda = 1e7 * 0.3 / (1.3 * 0.4);
    return el;
}
struct Set {
    double phi, psi, c, T;
};

// The plane pass's lanes (plane_lanes.hpp) against the full return
// (return_map), and the four-lane vector form against the one-lane form
// bit for bit: at random ordered trial stresses and directions, for the
// strengths below, each lane is admissible (verdict 1: the return_map is
// elastic), returned onto the shear or the cut-off plane (2: return_map's
// stress, composed as SymmetricEigen does, and its plastic strain), or left
// to the full update (0: return_map goes elsewhere, or it would try the
// last return's candidate first, an edge's or a point's). The reference
// is the model's own full path, so this checks that both paths agree; the
// return itself is checked against the peer's vectors and the partition
// of the trial space (the tests around this one).
TEST(MohrCoulomb, PlaneLanesAreTheFullReturnOnTheirPlanes) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const talus_mc::Elastic el = elastic_of_the_return_tests();
    const Set sets[] = {{30, 0, 2000, 0}, {30, 10, 1e4, 5e3}, {35, 0, 0, 0}, {20, 5, 2e4, 1e9}};
    std::map<int, int> verdicts;
    for (const Set &set : sets) {
        const talus_mc::Strength st = strength(set.phi, set.psi, set.c, set.T);
        const talus_mc::Systems systems(st, el);
        for (int round = 0; round < 500; ++round) {
            talus_mc::PlaneLanes in;
            for (std::size_t lane = 0; lane < in.kLanes; ++lane) {
                talus_mc::V3 t(u(rng), u(rng), u(rng));
                t *= 2e4;
                std::sort(t.data(), t.data() + 3, std::greater<>());
                const Eigen::Matrix3d q =
                    Eigen::HouseholderQR<Eigen::Matrix3d>(Eigen::Matrix3d::NullaryExpr([&] {
                        return u(rng);
                    })).householderQ();
                for (int i = 0; i < 3; ++i) {
                    in.trial.values[i][lane] = t[i];
                    for (int j = 0; j < 3; ++j)
                        in.trial.vectors[i][j][lane] = q(i, j);
                }
                // Mostly the planes' modes, also others (whose candidate
                // return_map tries first).
                const int lasts[] = {talus_mc::kElastic,         talus_mc::kShearPlane,
                                     talus_mc::kTensionPlane,    talus_mc::kElastic,
                                     talus_mc::kShearPlane,      talus_mc::kTensionPlane,
                                     talus_mc::kCompressionEdge, talus_mc::kTensionEdge,
                                     talus_mc::kShearTensionLine};
                in.last[lane] = lasts[rng() % 9];
                in.kappa[lane] = 1e-3 * (1.0 + u(rng));
                in.vol[lane] = 1e-3 * u(rng);
            }
            talus_mc::PlaneLanes each = in;
            talus_mc::plane_lanes_each(systems, st, el, each, in.kLanes);
#if defined(TALUS_MC_HAS_PLANE_QUAD)
            if (talus_mc::quad::available()) {
                talus_mc::PlaneLanes vec = in;
                talus_mc::quad::plane_lanes(systems, st, el, vec, 0);
                talus_mc::quad::plane_lanes(systems, st, el, vec, 4);
                for (std::size_t lane = 0; lane < in.kLanes; ++lane) {
                    // Exactly (==); a lane whose verdict is 0 has no result.
                    ASSERT_EQ(vec.verdict[lane], each.verdict[lane]);
                    if (each.verdict[lane] == 0.0) continue;
                    for (int e = 0; e < 6; ++e)
                        EXPECT_EQ(vec.stress[e][lane], each.stress[e][lane]);
                    EXPECT_EQ(vec.kappa_end[lane], each.kappa_end[lane]);
                    EXPECT_EQ(vec.vol_end[lane], each.vol_end[lane]);
                    EXPECT_EQ(vec.mode_end[lane], each.mode_end[lane]);
                }
            }
#endif
            for (std::size_t lane = 0; lane < in.kLanes; ++lane) {
                const talus_mc::V3 t(in.trial.values[0][lane], in.trial.values[1][lane],
                                     in.trial.values[2][lane]);
                const double last = in.last[lane];
                const int hint = last == 0.0 ? talus_mc::kNone
                                             : talus_mc::candidate_of(static_cast<talus_mc::Mode>(
                                                   static_cast<int>(last)));
                const talus_mc::Return r = talus_mc::return_map(t, st, systems, hint);
                const double verdict = each.verdict[lane];
                ++verdicts[static_cast<int>(verdict)];
                if (r.mode == talus_mc::kElastic) {
                    EXPECT_EQ(verdict, 1.0);
                    EXPECT_EQ(each.mode_end[lane],
                              talus_mc::on_surface(t, st) ? last : double(talus_mc::kElastic));
                    continue;
                }
                const int mode = static_cast<int>(last);
                const bool plane_hint = mode == talus_mc::kElastic ||
                                        mode == talus_mc::kShearPlane ||
                                        mode == talus_mc::kTensionPlane;
                if ((r.candidate != 0 && r.candidate != 1) || !plane_hint) {
                    EXPECT_EQ(verdict, 0.0) << r.candidate << " " << last;
                    continue;
                }
                ASSERT_EQ(verdict, 2.0);
                EXPECT_EQ(each.mode_end[lane], double(r.mode));
                talus::sdk::SymmetricEigen sp;
                sp.values = t;
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j)
                        sp.vectors(i, j) = in.trial.vectors[i][j][lane];
                const Vec6 s = sp.compose_stress(r.stress);
                for (int e = 0; e < 6; ++e)
                    EXPECT_EQ(each.stress[e][lane], s[e]);
                const talus_mc::V3 x = el.solve(t - r.stress);
                EXPECT_EQ(each.kappa_end[lane], in.kappa[lane] + talus_mc::deviatoric_measure(x));
                EXPECT_EQ(each.vol_end[lane], in.vol[lane] + ((x[0] + x[1]) + x[2]));
            }
        }
    }
    // Every verdict, often: of the 16,000 lanes these strengths give 8,556
    // left to the full update, 5,561 admissible and 1,883 returned; 500 of
    // each is well below that and far above a handful, so the test cannot
    // pass with one kind of lane missing.
    EXPECT_GT(verdicts[0], 500);
    EXPECT_GT(verdicts[1], 500);
    EXPECT_GT(verdicts[2], 500);
}

// The candidates partition the trial space: at random trial stresses, for
// associated and non-associated flow, with and without an active cut-off,
// every valid candidate returns the same stress (so the order of trial does
// not choose the answer), and where none is valid the return goes to the
// apex from beyond it.
TEST(MohrCoulomb, ReturnCandidatesPartitionTheTrialSpace) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const talus_mc::Elastic el = elastic_of_the_return_tests();
    const Set sets[] = {{30, 30, 1e4, 0},  {30, 10, 1e4, 5e3}, {35, 0, 0, 0},
                        {20, 5, 2e4, 1e9}, {0, 0, 1e4, 5e3},   {40, 40, 0, 0}};
    int checked = 0;
    std::map<int, int> modes;
    for (const Set &s : sets) {
        const talus_mc::Strength st = strength(s.phi, s.psi, s.c, s.T);
        const talus_mc::Planes pl(st);
        const talus_mc::Systems systems(st, el); // the plugin's path without softening
        for (int k = 0; k < 4000; ++k) {
            talus_mc::V3 t(u(rng), u(rng), u(rng));
            t *= 1e5;
            std::sort(t.data(), t.data() + 3, std::greater<>());
            const double tol = talus_mc::stress_tolerance(t, st);
            if (talus_mc::admissible(t, st, tol)) continue;
            std::vector<talus_mc::Return> valid;
            for (const auto &c : talus_mc::kCandidates) {
                if (!talus_mc::enabled(c, st)) continue;
                talus_mc::Return r;
                if (talus_mc::try_candidate(c, talus_mc::make_system(c, pl, el), t, pl, st, tol, r))
                    valid.push_back(r);
            }
            const talus_mc::Return chosen = talus_mc::return_map(t, st, el);
            // The systems solved once or per return: the same operations.
            const talus_mc::Return pre = talus_mc::return_map(t, st, systems);
            EXPECT_EQ(pre.stress, chosen.stress);
            EXPECT_EQ(pre.P, chosen.P);
            EXPECT_EQ(pre.candidate, chosen.candidate);
            if (valid.empty()) {
                // The apex, and only beyond it: a return to the apex has
                // non-negative plastic volume change (the potentials'
                // volumetric part 2 sin psi and the cut-off's are >= 0).
                EXPECT_EQ(chosen.candidate, talus_mc::kApex);
                EXPECT_GE(t.mean(), talus_mc::apex(st)[0] - tol) << t.transpose();
                ++modes[chosen.mode];
                ++checked;
                continue;
            }
            EXPECT_LT((chosen.stress - valid[0].stress).norm(), 1e-8 * t.norm());
            // The plugin tries the last return's candidate first: whichever
            // it is, the stress is the same (same bound).
            for (int hint = 0; hint < static_cast<int>(talus_mc::kCandidates.size()); ++hint) {
                EXPECT_LT((talus_mc::return_map(t, st, el, hint).stress - chosen.stress).norm(),
                          1e-8 * t.norm())
                    << "hint " << hint;
                EXPECT_EQ(talus_mc::return_map(t, st, systems, hint).stress,
                          talus_mc::return_map(t, st, el, hint).stress)
                    << "hint " << hint;
            }
            for (const auto &r : valid)
                // 1e-8 of the trial: the linear solves of different
                // candidates reach the same point with different rounding.
                EXPECT_LT((r.stress - valid[0].stress).norm(), 1e-8 * t.norm())
                    << "trial " << t.transpose() << ": modes " << valid[0].mode << " and "
                    << r.mode;
            ++modes[valid[0].mode];
            ++checked;
        }
    }
    EXPECT_GT(checked, 10000);
    // Every kind of return occurred at least once.
    for (int mode = 1; mode < talus_mc::kModeCount; ++mode)
        EXPECT_GT(modes[mode], 0) << "mode " << mode << " never reached";
}

// The plugin decides most elastic steps from the invariants (p, J2), with a
// bound on the yield function over the Lode angle, before any eigenvalue:
// trial stresses just outside the surface, at every Lode angle and in a
// rotated frame, must still be returned onto it, and those just inside
// must stay as they are. Outside by 1e-8 to 1e-3 of the stress (the
// return's tolerance is 1e-10), inside by 1e-3 to 1e-1. From a zero start
// stress with the trial as the elastic image of the increment. The same
// points again in one batch, where the quick pass screens four at a time
// (elastic_screen.hpp) and the verdicts near its threshold meet every lane
// of the vector: each point's result the bits of its own call.
TEST(MohrCoulomb, NearTheSurfaceTheElasticShortcutNeverDecidesWrongly) {
    talus::PluginRegistry reg;
    const double E = 1e7, nu = 0.3;
    const auto mi = make(model(reg), {{"youngs_modulus", E},
                                      {"poisson_ratio", nu},
                                      {"friction_angle", 30},
                                      {"cohesion", 1e4},
                                      {"tension_cutoff", 5e3}});
    const talus_mc::Strength st = strength(30, 0, 1e4, 5e3);
    const double G = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int outside = 0, inside = 0;
    talus::test::PointsIn all{0, 3, {}, {}, {}, {}, {}};
    std::vector<double> alone_s, alone_q;
    for (int k = 0; k < 4000; ++k) {
        // An ordered principal trial on the shear surface (or the cut-off
        // where it is lower) at a random Lode angle and mean stress.
        const double p = -2e5 * u(rng);
        const double theta = (u(rng) - 0.5) * std::numbers::pi / 3.0;
        talus_mc::V3 dir(std::sin(theta + 2 * std::numbers::pi / 3), std::sin(theta),
                         std::sin(theta - 2 * std::numbers::pi / 3));
        // Scale the deviator until the trial reaches the surface.
        auto f = [&](double r) {
            const talus_mc::V3 s = talus_mc::V3::Constant(p) + r * dir;
            return std::max(talus_mc::shear_yield(s, st), s[0] - st.tension);
        };
        double lo = 0.0, hi = 1e7;
        if (f(lo) >= 0.0) continue; // the mean stress alone is beyond the apex
        for (int it = 0; it < 200; ++it) {
            const double mid = 0.5 * (lo + hi);
            (f(mid) < 0.0 ? lo : hi) = mid;
        }
        const bool out = k % 2 == 0;
        const double rel = out ? std::pow(10.0, -8 + 5 * u(rng)) : std::pow(10.0, -3 + 2 * u(rng));
        const double r = hi * (out ? 1.0 + rel : 1.0 - rel);
        const talus_mc::V3 s = talus_mc::V3::Constant(p) + r * dir;
        const double scale = s.cwiseAbs().maxCoeff();
        if (out && f(r) < 1e-9 * scale) continue; // too close to tell from the tolerance
        // Rotated frame, then the strain increment whose elastic image it is.
        const Eigen::Quaterniond q(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
        const Eigen::Matrix3d S = R * s.asDiagonal() * R.transpose();
        const double tr = S.trace() / (3 * lambda + 2 * G);
        const Eigen::Matrix3d eps = (S - lambda * tr * Eigen::Matrix3d::Identity()) / (2 * G);
        Vec6 de;
        de << eps(0, 0), eps(1, 1), eps(2, 2), 2 * eps(0, 1), 2 * eps(1, 2), 2 * eps(0, 2);
        const Out o = call(*mi, Vec6::Zero(), de);
        ASSERT_TRUE(o.res.ok()) << o.res.message;
        ++all.n;
        all.s0.insert(all.s0.end(), 6, 0.0);
        all.q0.insert(all.q0.end(), 3, 0.0);
        all.de.insert(all.de.end(), de.data(), de.data() + 6);
        all.rho.push_back(2000.0);
        for (int i = 0; i < 9; ++i)
            all.F.push_back(i % 4 == 0 ? 1.0 : 0.0);
        alone_s.insert(alone_s.end(), o.stress.data(), o.stress.data() + 6);
        alone_q.insert(alone_q.end(), o.state.begin(), o.state.end());
        const talus_mc::V3 after = principal(o.stress);
        const double f_after = std::max(talus_mc::shear_yield(after, st), after[0] - st.tension);
        if (out) {
            // On the surface: the return's 1e-10 tolerance and the eigen
            // decomposition's rounding, 1e-9 of the stress.
            EXPECT_LT(f_after, 1e-9 * scale) << "trial outside by " << rel << " left as is";
            EXPECT_NE(static_cast<int>(o.state[2]), talus_mc::kElastic);
            ++outside;
        } else {
            EXPECT_EQ(static_cast<int>(o.state[2]), talus_mc::kElastic);
            // The trial itself (the elastic image of de, to rounding).
            EXPECT_LT((after - s).cwiseAbs().maxCoeff(), 1e-9 * scale);
            ++inside;
        }
    }
    EXPECT_GT(outside, 1000);
    EXPECT_GT(inside, 1000);
    // Exactly: == on every double.
    for (const bool in_place : {false, true}) {
        const talus::test::PointsOut batch =
            talus::test::update_in_batches(*mi, all, all.n, in_place);
        EXPECT_EQ(batch.s, alone_s) << (in_place ? "in place" : "");
        EXPECT_EQ(batch.q, alone_q) << (in_place ? "in place" : "");
    }
}

namespace {

// Central differences of the plugin's stress in the strain increment.
RowMat6 fd_tangent(const talus::MaterialInstance &mi, const Vec6 &s0, const Vec6 &de,
                   const std::vector<double> &q0, double h) {
    RowMat6 fd;
    for (int j = 0; j < 6; ++j) {
        Vec6 a = de, b = de;
        a[j] += h;
        b[j] -= h;
        fd.col(j) = (call(mi, s0, a, q0).stress - call(mi, s0, b, q0).stress) / (2.0 * h);
    }
    return fd;
}

} // namespace

// The consistent tangent against central differences at every kind of
// return, each reached on purpose (the yield_mode state says which), with a
// rotated principal frame so that every shear term is exercised, and with
// and without softening. Each state lies inside its region of the trial
// space, where the return is smooth: h = 1e-9 on increments of ~1e-3 has
// truncation ~(h/de)^2 ~ 1e-12 and round-off ~1e-16 |sigma| / (h E) ~ 1e-9
// of the modulus; 1e-6 of the modulus separates those from a wrong term
// (the spin term alone is 2G (1 - ratio), order one where the return is
// large).
TEST(MohrCoulomb, TangentIsTheDerivativeAtEveryKindOfReturn) {
    talus::PluginRegistry reg;
    const talus::Model &m = model(reg);
    // A rotation that mixes all axes, so principal frames are not the axes.
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    auto rotate_strain = [&](const Eigen::Vector3d &principal) {
        const Eigen::Matrix3d e = R * principal.asDiagonal() * R.transpose();
        Vec6 v;
        v << e(0, 0), e(1, 1), e(2, 2), 2 * e(0, 1), 2 * e(1, 2), 2 * e(0, 2);
        return v;
    };
    auto rotate_stress = [&](const Eigen::Vector3d &principal) {
        const Eigen::Matrix3d s = R * principal.asDiagonal() * R.transpose();
        Vec6 v;
        v << s(0, 0), s(1, 1), s(2, 2), s(0, 1), s(1, 2), s(0, 2);
        return v;
    };
    struct Case {
        const char *what;
        std::map<std::string, double> params;
        Eigen::Vector3d s0; // principal start stress
        Eigen::Vector3d de; // principal strain increment (same frame)
        int mode;
        double kappa0 = 0.0;
    };
    const std::map<std::string, double> base = {{"youngs_modulus", 1e7}, {"poisson_ratio", 0.3},
                                                {"friction_angle", 30},  {"dilation_angle", 10},
                                                {"cohesion", 1e4},       {"tension_cutoff", 1e9}};
    auto with = [&](std::map<std::string, double> extra) {
        std::map<std::string, double> p = base;
        for (const auto &kv : extra)
            p[kv.first] = kv.second;
        return p;
    };
    const auto soft = with({{"softening", 1},
                            {"residual_friction_angle", 20},
                            {"residual_dilation_angle", 0},
                            {"residual_cohesion", 2e3},
                            {"softening_start", 0},
                            {"softening_end", 0.01}});
    const Eigen::Vector3d p0(-1e4, -1e4, -1e4);
    const auto cut = with({{"tension_cutoff", 5e3}});
    const std::vector<Case> cases = {
        {"elastic", base, p0, {-1e-4, 2e-5, 1e-5}, talus_mc::kElastic},
        {"shear plane", base, p0, {-1e-2, -2e-3, 8e-3}, talus_mc::kShearPlane},
        {"compression edge", base, p0, {-1e-2, 3e-3, 3.2e-3}, talus_mc::kCompressionEdge},
        {"extension edge", base, p0, {-3.2e-3, -3e-3, 1e-2}, talus_mc::kExtensionEdge},
        {"shear apex", base, p0, {2e-2, 2.1e-2, 2.2e-2}, talus_mc::kShearApex},
        {"tension plane", cut, p0, {1.46e-3, 1.6e-4, -1e-4}, talus_mc::kTensionPlane},
        {"tension edge", cut, p0, {1.19e-3, 1.06e-3, -3.7e-4}, talus_mc::kTensionEdge},
        {"tension apex", cut, p0, {2e-2, 2.1e-2, 2.2e-2}, talus_mc::kTensionApex},
        {"shear-tension line", cut, p0, {4e-3, -1e-3, -1.5e-3}, talus_mc::kShearTensionLine},
        {"softening plane", soft, p0, {-1e-2, -2e-3, 8e-3}, talus_mc::kShearPlane, 1e-3},
        {"softening compression edge",
         soft,
         p0,
         {-1e-2, 3e-3, 3.2e-3},
         talus_mc::kCompressionEdge,
         2e-3},
        {"softening apex", soft, p0, {2e-2, 2.1e-2, 2.2e-2}, talus_mc::kShearApex, 1e-3},
    };
    for (const Case &c : cases) {
        SCOPED_TRACE(c.what);
        const auto mi = make(m, c.params);
        const Vec6 s0 = rotate_stress(c.s0), de = rotate_strain(c.de);
        const std::vector<double> q0 = {c.kappa0, 0.0, 0.0};
        const Out o = call(*mi, s0, de, q0);
        ASSERT_TRUE(o.res.ok()) << o.res.message;
        EXPECT_EQ(static_cast<int>(o.state[2]), c.mode);
        if (c.mode != talus_mc::kElastic && c.params.count("softening")) {
            EXPECT_GT(o.state[0], c.kappa0) << "softening case must be plastic";
        }
        const RowMat6 fd = fd_tangent(*mi, s0, de, q0, 1e-9);
        // Relative to the P-wave modulus lambda + 2G = 1.35e7: at the
        // apex the tangent is zero.
        const double scale = 1e7 * 0.7 / (1.3 * 0.4);
        EXPECT_LT((o.D - fd).cwiseAbs().maxCoeff(), 1e-6 * scale) << "D\n" << o.D << "\nfd\n" << fd;
    }
}

// Implicit softening: the returned stress lies on the surface of the
// strength at the END of the increment (kappa_n+1), not at its start, and
// kappa_n+1 - kappa_n is the deviatoric measure of the plastic strain of
// that same return (computed here from the elastic law).
TEST(MohrCoulomb, SofteningIsImplicit) {
    talus::PluginRegistry reg;
    const auto mi = make(model(reg), {{"youngs_modulus", 1e7},
                                      {"poisson_ratio", 0.25},
                                      {"friction_angle", 35},
                                      {"dilation_angle", 10},
                                      {"cohesion", 2e4},
                                      {"softening", 1},
                                      {"residual_friction_angle", 25},
                                      {"residual_dilation_angle", 0},
                                      {"residual_cohesion", 0},
                                      {"softening_start", 1e-3},
                                      {"softening_end", 2e-2}});
    Vec6 s0;
    s0 << -2e4, -2.4e4, -1.8e4, 2e3, -1e3, 4e2;
    Vec6 de;
    de << -2e-2, 6e-3, 3e-3, 6e-3, 2e-3, -4e-3;
    const double kappa0 = 1.5e-3;
    const Out o = call(*mi, s0, de, {kappa0, 0.0, 0.0});
    ASSERT_TRUE(o.res.ok()) << o.res.message;
    const double k1 = o.state[0];
    ASSERT_GT(k1, kappa0 + 1e-4) << "the case must soften noticeably";
    const talus_mc::Strength st1 = strength(35, 10, 2e4, 0, k1, 25, 0, 0, 1e-3, 2e-2);
    const talus_mc::V3 q = principal(o.stress);
    const double scale = s0.cwiseAbs().maxCoeff();
    // 1e-9 of the stress: the kappa iteration stops at 1e-14 of the strain
    // range (a strength change of ~1e-12) and the solves lose a few ulps.
    EXPECT_NEAR(talus_mc::shear_yield(q, st1), 0.0, 1e-9 * scale);
    // Not on the surface of the start strength (which is stronger).
    const talus_mc::Strength st0 = strength(35, 10, 2e4, 0, kappa0, 25, 0, 0, 1e-3, 2e-2);
    EXPECT_LT(talus_mc::shear_yield(q, st0), -1e-3 * scale);
    // The plastic strain is the total increment minus the elastic one.
    const double E = 1e7, G = E / 2.5, K = E / 1.5; // nu = 0.25
    const Vec6 ds = o.stress - s0;
    const double mean = (ds[0] + ds[1] + ds[2]) / 3.0;
    Eigen::Matrix3d ee;
    ee << ds[0] - mean, ds[3], ds[5], ds[3], ds[1] - mean, ds[4], ds[5], ds[4], ds[2] - mean;
    ee /= 2.0 * G;
    ee += Eigen::Matrix3d::Identity() * mean / (3.0 * K);
    Eigen::Matrix3d e;
    e << de[0], de[3] / 2, de[5] / 2, de[3] / 2, de[1], de[4] / 2, de[5] / 2, de[4] / 2, de[2];
    const Eigen::Matrix3d ep = e - ee;
    const Eigen::Matrix3d dev = ep - Eigen::Matrix3d::Identity() * ep.trace() / 3.0;
    // 1e-9 relative: the same rounding as above, in strain.
    EXPECT_NEAR(k1 - kappa0, std::sqrt(2.0 / 3.0 * dev.squaredNorm()), 1e-9 * (k1 - kappa0));
    EXPECT_NEAR(o.state[1], ep.trace(), 1e-9 * std::abs(ep.trace()));
}

// Bounds that reject nonsense, each message naming the parameter.
TEST(MohrCoulomb, RejectsNonsenseNamingTheParameter) {
    talus::PluginRegistry reg;
    const talus::Model &m = model(reg);
    const std::map<std::string, double> ok = {
        {"youngs_modulus", 1e7}, {"poisson_ratio", 0.3}, {"friction_angle", 30}};
    auto message = [&](std::map<std::string, double> extra) -> std::string {
        std::map<std::string, double> p = ok;
        for (const auto &kv : extra)
            p[kv.first] = kv.second;
        try {
            make(m, p);
        } catch (const talus::Error &e) {
            return e.what();
        }
        return "";
    };
    EXPECT_TRUE(talus::test::contains(message({{"dilation_angle", 35}}), "dilation_angle"));
    EXPECT_TRUE(talus::test::contains(message({{"dilation_angle", 35}}), "friction_angle"));
    EXPECT_TRUE(talus::test::contains(message({{"softening", 1},
                                               {"softening_end", 0.01},
                                               {"residual_friction_angle", 10},
                                               {"residual_dilation_angle", 12}}),
                                      "residual_dilation_angle"));
    EXPECT_TRUE(talus::test::contains(message({{"softening", 1}}), "softening_end"));
    EXPECT_TRUE(talus::test::contains(message({{"residual_cohesion", 5}}), "softening: true"));
    EXPECT_EQ(message({}), "");
}

// A start stress outside the surface (a user's initial stress) is
// projected onto it by the return, without plastic strain; a zero
// increment then returns the projected stress, and that stress is a fixed
// point (a second zero increment changes nothing).
TEST(MohrCoulomb, StartStressOutsideTheSurfaceIsProjectedWithoutPlasticStrain) {
    talus::PluginRegistry reg;
    const auto mi = cohesionless(reg);
    Vec6 s0;
    s0 << -1e5, -4e5, -1e5, 5e4, 0, 0; // q far beyond the c = 0 cone
    const Out o = call(*mi, s0, Vec6::Zero(), {0.0, 0.0, 0.0});
    ASSERT_TRUE(o.res.ok()) << o.res.message;
    EXPECT_EQ(o.state[0], 0.0);
    EXPECT_EQ(o.state[1], 0.0);
    const talus_mc::V3 q = principal(o.stress);
    // 1e-9 of the largest start stress: the return is a linear solve (a few
    // ulps) and its own surface test allows 1e-10 of the stress.
    EXPECT_NEAR(talus_mc::shear_yield(q, strength(30, 0, 0, 0)), 0.0, 1e-9 * 4e5);
    const Out again = call(*mi, o.stress, Vec6::Zero(), {0.0, 0.0, 0.0});
    EXPECT_LT((again.stress - o.stress).cwiseAbs().maxCoeff(), 1e-9 * 4e5); // as above
    EXPECT_EQ(static_cast<int>(again.state[2]), talus_mc::kElastic);
}

// The start-stress check runs only for yield_mode 0: a stress this model
// returned (yield_mode > 0) is taken as admissible. That holds when every
// returned stress lies inside the return's own tolerance, so the same
// stress given back with yield_mode 0 (where the check runs and would
// project anything outside) must give the same step. Random strain paths,
// with and without cohesion and a cut-off, at every kind of return.
TEST(MohrCoulomb, AReturnedStressNeedsNoStartCheck) {
    talus::PluginRegistry reg;
    const auto &m = model(reg);
    const auto cohesive = make(m, {{"youngs_modulus", 1e7},
                                   {"poisson_ratio", 0.3},
                                   {"friction_angle", 30},
                                   {"dilation_angle", 10},
                                   {"cohesion", 1e4},
                                   {"tension_cutoff", 2e3}});
    const auto sand = cohesionless(reg);
    std::mt19937_64 rng(3);
    std::normal_distribution<double> n;
    std::map<int, int> modes;
    for (const talus::MaterialInstance *mi : {cohesive.get(), sand.get()})
        for (int path = 0; path < 200; ++path) {
            Vec6 s;
            s << -1e5, -1e5, -1e5, 0, 0, 0;
            std::vector<double> q = {0.0, 0.0, 0.0};
            for (int step = 0; step < 20; ++step) {
                Vec6 de;
                for (int i = 0; i < 6; ++i)
                    de[i] = 2e-3 * n(rng);
                const Out kept = call(*mi, s, de, q);
                const Out zeroed = call(*mi, s, de, {q[0], q[1], 0.0});
                ASSERT_TRUE(kept.res.ok() && zeroed.res.ok());
                // 1e-9 of the stress: the two calls try the candidates in
                // another order (the hint), which moves the result by the
                // linear solves' rounding only; a projection of a start
                // stress outside the surface by more than the return's
                // tolerance (1e-10 of the stress) would show above it only
                // if it moved the start by more, which is what is tested.
                const double scale = std::max(s.cwiseAbs().maxCoeff(), 1e4);
                EXPECT_LT((kept.stress - zeroed.stress).cwiseAbs().maxCoeff(), 1e-9 * scale)
                    << "path " << path << " step " << step;
                EXPECT_NEAR(kept.state[0], zeroed.state[0], 1e-9 * std::max(kept.state[0], 1e-3));
                ++modes[static_cast<int>(kept.state[2])];
                s = kept.stress;
                q = kept.state;
            }
        }
    // The paths reach the planes, the edges and the cut-off.
    for (int mode : {1, 2, 3, 5})
        EXPECT_GT(modes[mode], 0) << "mode " << mode;
}

// The set-up call (ABI 1.1) returns an initial stress outside the surface to
// it, exactly as a zero increment does, and says so in the host's log; an
// admissible one passes unchanged and unreported.
TEST(MohrCoulomb, InitialStressOutsideTheSurfaceIsReturnedAndReported) {
    talus::PluginRegistry reg;
    const auto mi = cohesionless(reg);
    EXPECT_TRUE(mi->model().has_init_state());
    std::vector<std::string> log;
    const auto previous =
        talus::set_plugin_log_sink([&](const std::string &l) { log.push_back(l); });
    Vec6 s0;
    s0 << -1e5, -4e5, -1e5, 5e4, 0, 0; // q far beyond the c = 0 cone
    const Out o = call(*mi, s0, Vec6::Zero(), {0.0, 0.0, 0.0}, true);
    ASSERT_TRUE(o.res.ok()) << o.res.message;
    const Out zero = call(*mi, s0, Vec6::Zero(), {0.0, 0.0, 0.0});
    EXPECT_EQ(o.stress, zero.stress); // the same projection, to the bit
    EXPECT_EQ(o.state[1], 0.0);       // no plastic strain
    ASSERT_EQ(log.size(), 1u);
    EXPECT_TRUE(talus::test::contains(log[0],
                                      "warning: plugin talus_mohr_coulomb: point 41: the initial "
                                      "stress lies outside the yield surface; returned to it"))
        << log[0];
    Vec6 inside;
    inside << -1e5, -1.2e5, -1e5, 0, 0, 0;
    const Out ok = call(*mi, inside, Vec6::Zero(), {0.0, 0.0, 0.0}, true);
    ASSERT_TRUE(ok.res.ok());
    EXPECT_EQ(ok.stress, inside);
    EXPECT_EQ(log.size(), 1u);
    talus::set_plugin_log_sink(previous);
}

// A batch's points are independent: a point's outputs must not depend on
// its batch or its neighbours, bit for bit (the solver's results do not
// change with the number of threads or the batch size). The model finishes
// the clearly elastic points of a batch in a quick pass over its arrays and
// decomposes the other points' trial stresses two at a time, so a point's
// path depends on its neighbours; its result must not. Also the quick
// pass's results against the closed form: Hooke's stress, yield mode 0,
// the elastic tangent and the P-wave speed.
TEST(MohrCoulomb, APointsResultDoesNotDependOnItsBatch) {
    talus::PluginRegistry reg;
    const double E = 1e7, nu = 0.3;
    const double G = E / (2.0 * (1.0 + nu)), lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    for (const bool softening : {false, true}) {
        SCOPED_TRACE(softening ? "softening" : "perfectly plastic");
        std::map<std::string, double> p = {{"youngs_modulus", E},  {"poisson_ratio", nu},
                                           {"friction_angle", 30}, {"dilation_angle", 5},
                                           {"cohesion", 2000},     {"tension_cutoff", 500}};
        if (softening)
            p.insert({{"softening", 1},
                      {"residual_friction_angle", 25},
                      {"residual_cohesion", 200},
                      {"softening_end", 0.01}});
        const auto mi = make(model(reg), p);
        // 4 kinds of point in turn: deep inside (the quick pass), pulled
        // into tension, sheared, and anything. 250 points: 3 full chunks
        // of the quick pass and a partial one, odd numbers of points left
        // to the full update.
        const std::size_t n = 250;
        std::mt19937 gen(5);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        std::vector<double> s0(6 * n), de(6 * n), q0(3 * n), rho(n), F(9 * n, 0.0);
        std::vector<int> deep(n, 0);
        for (std::size_t k = 0; k < n; ++k) {
            double *s = &s0[6 * k], *d = &de[6 * k];
            const std::size_t kind = k % 4 == 3 ? std::size_t(gen() % 4) : k % 4;
            for (int i = 0; i < 6; ++i) {
                s[i] = 1e3 * u(gen);
                d[i] = 1e-4 * u(gen);
            }
            if (kind == 0) { // deep in compression, a small increment
                deep[k] = 1;
                for (int i = 0; i < 3; ++i)
                    s[i] -= 1e5;
                for (int i = 0; i < 6; ++i)
                    d[i] *= 1e-2;
            } else if (kind == 1) { // stretched
                for (int i = 0; i < 3; ++i)
                    d[i] = 1e-3 * (1.0 + u(gen));
            } else if (kind == 2) { // sheared from a confined state
                for (int i = 0; i < 3; ++i)
                    s[i] -= 2e4;
                for (int i = 3; i < 6; ++i)
                    d[i] = 4e-3 * u(gen);
            } else { // anything, also a start stress outside the surface
                for (int i = 0; i < 6; ++i)
                    s[i] *= 10.0;
            }
            q0[3 * k] = softening ? 0.005 * (1.0 + u(gen)) : 0.0;
            q0[3 * k + 1] = 0.0;
            q0[3 * k + 2] = double(gen() % 3 == 0 ? 0 : gen() % 2 == 0 ? 1 : 5); // hints
            rho[k] = 2000.0 + 100.0 * u(gen);
            for (int i = 0; i < 3; ++i)
                F[9 * k + 4 * static_cast<std::size_t>(i)] = 1.0;
        }
        const talus::test::PointsIn points{n, 3, s0, q0, de, rho, F};
        auto run = [&](std::size_t size, bool in_place, bool tangent = true) {
            return talus::test::update_in_batches(*mi, points, size, in_place, tangent);
        };
        const talus::test::PointsOut whole = run(n, false);
        int plastic = 0, quick = 0;
        for (std::size_t k = 0; k < n; ++k)
            plastic += whole.q[3 * k + 2] != 0.0;
        // Enough of each path to matter.
        EXPECT_GT(plastic, 60);
        for (const auto &[size, in_place] :
             {std::pair<std::size_t, bool>{1, false}, {7, false}, {64, false}, {n, true}}) {
            SCOPED_TRACE(testing::Message()
                         << "batches of " << size << (in_place ? ", in place" : ""));
            const talus::test::PointsOut other = run(size, in_place);
            // Exactly: == on every double (a NaN would fail, as it should).
            EXPECT_EQ(other.s, whole.s);
            EXPECT_EQ(other.q, whole.q);
            EXPECT_EQ(other.c, whole.c);
            EXPECT_EQ(other.D, whole.D);
        }
        // Without the tangent (the solver's explicit steps) the points the
        // screen leaves that stay elastic or return onto the shear or the
        // cut-off plane take the model's plane pass, the others update():
        // the same stresses, states and wave speeds, bit for bit.
        for (const auto &[size, in_place] :
             {std::pair<std::size_t, bool>{1, false}, {7, false}, {n, false}, {n, true}}) {
            SCOPED_TRACE(testing::Message() << "without the tangent, batches of " << size
                                            << (in_place ? ", in place" : ""));
            const talus::test::PointsOut other = run(size, in_place, false);
            EXPECT_EQ(other.s, whole.s);
            EXPECT_EQ(other.q, whole.q);
            EXPECT_EQ(other.c, whole.c);
        }
        // The deep points against the closed form. Hooke's increment is
        // exact up to the rounding of its few products and sums: 1e-15 of
        // the stress; the tangent's entries are the moduli themselves.
        for (std::size_t k = 0; k < n; ++k) {
            if (!deep[k]) continue;
            ++quick;
            const double *d = &de[6 * k];
            const double tr = d[0] + d[1] + d[2];
            for (int i = 0; i < 6; ++i) {
                const double ref =
                    s0[6 * k + i] + (i < 3 ? lambda * tr + 2.0 * G * d[i] : G * d[i]);
                EXPECT_NEAR(whole.s[6 * k + i], ref, 1e-15 * 1e5) << k << " " << i;
            }
            EXPECT_EQ(whole.q[3 * k], q0[3 * k]);
            EXPECT_EQ(whole.q[3 * k + 1], q0[3 * k + 1]);
            EXPECT_EQ(whole.q[3 * k + 2], 0.0);
            for (int i = 0; i < 6; ++i)
                for (int j = 0; j < 6; ++j) {
                    const double ref =
                        i < 3 && j < 3 ? lambda + (i == j ? 2.0 * G : 0.0) : (i == j ? G : 0.0);
                    EXPECT_NEAR(whole.D[36 * k + 6 * i + j], ref, 1e-15 * E) << k << " " << i << j;
                }
            // A division and a square root, each correctly rounded, of
            // moduli computed as the model does: a few ulps (2.2e-16 each).
            EXPECT_NEAR(whole.c[k], std::sqrt((lambda + 2.0 * G) / rho[k]), 1e-15 * whole.c[k]);
        }
        EXPECT_GT(quick, 60);
    }
}
