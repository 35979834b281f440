#include <talus/driver/point_driver.hpp>

#include <talus/input/material_yaml.hpp>
#include <talus/input/time_function_yaml.hpp>
#include <talus/io/csv_table.hpp>
#include <talus/material/cut_step.hpp>
#include <talus/sdk/kinematics.hpp>
#include <talus/sdk/voigt.hpp>

#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <ostream>

namespace talus {

using Vec6 = PointVec6;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat3 = Eigen::Matrix3d;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

namespace {

int component_index(const yaml::Node &key_node, const std::string &name) {
    for (std::size_t c = 0; c < 6; ++c)
        if (name == kVoigtNames[c]) return static_cast<int>(c);
    const std::string near = yaml::closest_match(name, kVoigtNames);
    key_node.fail(fmt::format("unknown component '{}'; expected one of xx, yy, zz, xy, yz, xz{}",
                              name,
                              near.empty() ? "" : fmt::format(" (did you mean '{}'?)", near)));
}

// ------------------------------------------------------------- reading --

ControlValue read_value(const yaml::Node &n, const std::string &kind) {
    ControlValue v;
    if (kind == "table") {
        v.kind = ControlValue::Kind::table;
        v.table = read_piecewise_linear(n);
        return v;
    }
    v.amount = n.as_double();
    if (kind == "change") v.kind = ControlValue::Kind::change;
    if (kind == "target") v.kind = ControlValue::Kind::target;
    if (kind == "rate") v.kind = ControlValue::Kind::rate;
    return v;
}

// A `control:` entry, e.g. zz: {strain_change: -0.1}.
Condition read_component_control(const yaml::Node &entry, int c) {
    entry.expect_map();
    constexpr std::array<std::string_view, 8> keys = {
        "strain", "strain_change", "strain_rate", "strain_table",
        "stress", "stress_change", "stress_rate", "stress_table"};
    entry.allow_keys(keys);
    const std::vector<std::string> given = entry.keys();
    if (given.size() != 1)
        entry.fail(fmt::format("give exactly one of strain, strain_change, strain_rate, "
                               "strain_table, stress, stress_change, stress_rate, stress_table "
                               "(got {})",
                               given.size()));
    const std::string &k = given[0];
    const bool strain = k.rfind("strain", 0) == 0;
    const std::string kind = k == "strain" || k == "stress" ? "target" : k.substr(k.find('_') + 1);
    Condition cond;
    (strain ? cond.a : cond.b)[c] = 1.0;
    cond.value = read_value(entry.get(k), kind);
    cond.label =
        fmt::format("{}_{}", strain ? "eps" : "sig", kVoigtNames[static_cast<std::size_t>(c)]);
    return cond;
}

// A `constraints:` entry: {strain: {xx: 1, ...}, stress: {...}, change: 0}.
Condition read_constraint(const yaml::Node &entry) {
    entry.expect_map();
    constexpr std::array<std::string_view, 6> keys = {"strain", "stress", "value",
                                                      "change", "rate",   "table"};
    entry.allow_keys(keys);
    Condition cond;
    std::string label;
    for (const char *side : {"strain", "stress"}) {
        const yaml::Node coeffs = entry.get(side);
        if (!coeffs.defined()) continue;
        coeffs.expect_map();
        for (const std::string &key : coeffs.keys()) {
            const int c = component_index(coeffs, key);
            const double w = coeffs.get(key).as_double();
            const bool strain = std::string_view(side) == "strain";
            (strain ? cond.a : cond.b)[c] += w;
            label += fmt::format("{}{:g} {}_{}", label.empty() ? "" : " + ", w,
                                 strain ? "eps" : "sig", key);
        }
    }
    if (cond.a.isZero() && cond.b.isZero())
        entry.fail("a constraint needs non-zero coefficients under strain: and/or stress:");
    int n_values = 0;
    for (const char *kind : {"value", "change", "rate", "table"})
        if (const yaml::Node v = entry.get(kind); v.defined()) {
            ++n_values;
            cond.value = read_value(v, std::string(kind) == "value" ? "target" : kind);
        }
    if (n_values > 1) entry.fail("give one of value, change, rate, table");
    // No value given: the combination is held at its value at the stage start.
    cond.label = label;
    return cond;
}

} // namespace

ExitCondition read_until(const yaml::Node &n) {
    const std::string text = n.as_string();
    ExitCondition e;
    e.text = text;
    std::size_t at = std::string::npos;
    for (const char *op : {">=", "<=", ">", "<"}) {
        at = text.find(op);
        if (at != std::string::npos) {
            e.op = op;
            break;
        }
    }
    if (at == std::string::npos)
        n.fail(fmt::format("expected 'VARIABLE >= NUMBER' (or <=, >, <), e.g. 'q >= 2e5' or "
                           "'eps_a >= 0.1'; got '{}'",
                           text));
    auto trim = [](std::string s) {
        s.erase(0, s.find_first_not_of(" \t"));
        s.erase(s.find_last_not_of(" \t") + 1);
        return s;
    };
    e.variable = trim(text.substr(0, at));
    const std::string rhs = trim(text.substr(at + e.op.size()));
    try {
        std::size_t used = 0;
        e.threshold = std::stod(rhs, &used);
        if (used != rhs.size()) throw std::invalid_argument(rhs);
    } catch (const std::exception &) {
        n.fail(fmt::format("'{}': the right-hand side '{}' is not a number", text, rhs));
    }
    return e;
}

namespace {

ReplayCall read_replay(const yaml::Node &n) {
    constexpr std::array<std::string_view, 8> keys = {
        "time", "dt", "density", "strain_increment", "F_start", "F_end", "stress", "state"};
    n.allow_keys(keys);
    ReplayCall r;
    r.time = n.require("time").as_double();
    r.dt = n.require("dt").as_double();
    r.density = n.require("density").as_double();
    if (!(r.density > 0.0)) n.require("density").fail("expected density > 0 (kg/m^3)");
    auto fixed = [&](const char *key, std::size_t size, double *out) {
        const std::vector<double> v = n.require(key).as_doubles();
        if (v.size() != size)
            n.require(key).fail(fmt::format("expected {} numbers, got {}", size, v.size()));
        std::copy(v.begin(), v.end(), out);
    };
    fixed("strain_increment", 6, r.strain_increment.data());
    fixed("stress", 6, r.stress.data());
    fixed("F_start", 9, r.F_start.data());
    fixed("F_end", 9, r.F_end.data());
    if (const yaml::Node q = n.get("state"); q.defined()) r.state = q.as_doubles();
    return r;
}

// A laboratory file drives some components: each named column, times a
// scale, is the absolute value of a strain or stress component at the
// file's times (counted from its first row). One increment per row by
// default, so every measured point is an increment end.
void read_lab_file(const yaml::Node &lab, const std::string &case_file, Stage &st,
                   std::array<bool, 6> &controlled) {
    constexpr std::array<std::string_view, 4> keys = {"file", "time", "columns",
                                                      "increments_per_row"};
    lab.allow_keys(keys);
    std::filesystem::path f(lab.require("file").as_string());
    if (f.is_relative()) f = std::filesystem::path(case_file).parent_path() / f;
    const CsvTable t = read_csv_table(f.lexically_normal().string(), lab.where());
    const std::string time_col = lab.require("time").as_string();
    const int tc = t.column(time_col);
    if (tc < 0)
        lab.require("time").fail(fmt::format("the file {} has no column '{}'", t.file, time_col));
    if (t.rows.size() < 2) lab.fail(fmt::format("{} needs at least two rows", t.file));
    const double t0 = t.rows.front()[static_cast<std::size_t>(tc)];
    for (std::size_t r = 1; r < t.rows.size(); ++r)
        if (!(t.rows[r][static_cast<std::size_t>(tc)] >
              t.rows[r - 1][static_cast<std::size_t>(tc)]))
            lab.require("time").fail(
                fmt::format("times in {} must increase (data row {})", t.file, r + 1));
    long per_row = 1;
    if (const yaml::Node n = lab.get("increments_per_row"); n.defined()) {
        per_row = n.as_integer();
        if (per_row < 1 || per_row > 100000) n.fail("expected 1 <= increments_per_row <= 1e5");
    }
    st.duration = t.rows.back()[static_cast<std::size_t>(tc)] - t0;
    st.increments = static_cast<long>(t.rows.size() - 1) * per_row;
    const yaml::Node cols = lab.require("columns");
    cols.expect_map();
    for (const std::string &key : cols.keys()) {
        const int c = component_index(cols, key);
        const yaml::Node e = cols.get(key);
        constexpr std::array<std::string_view, 3> ek = {"strain", "stress", "scale"};
        e.allow_keys(ek);
        const bool strain = e.get("strain").defined();
        if (strain == e.get("stress").defined())
            e.fail("give exactly one of strain: COLUMN, stress: COLUMN");
        const std::string name = e.get(strain ? "strain" : "stress").as_string();
        const int vc = t.column(name);
        if (vc < 0) e.fail(fmt::format("the file {} has no column '{}'", t.file, name));
        const double scale = e.get("scale").defined() ? e.get("scale").as_double() : 1.0;
        std::vector<std::array<double, 2>> pts;
        for (const auto &row : t.rows)
            pts.push_back({row[static_cast<std::size_t>(tc)] - t0,
                           scale * row[static_cast<std::size_t>(vc)]});
        Condition &cond = st.conditions[static_cast<std::size_t>(c)];
        cond = Condition{};
        (strain ? cond.a : cond.b)[c] = 1.0;
        cond.value.kind = ControlValue::Kind::table;
        cond.value.table = PiecewiseLinear(std::move(pts));
        cond.label = fmt::format("{}_{} = {} x column '{}' of {}", strain ? "eps" : "sig", key,
                                 scale, name, t.file);
        controlled[static_cast<std::size_t>(c)] = true;
    }
}

void read_duration(const yaml::Node &s, Stage &st) {
    if (const yaml::Node d = s.get("duration"); d.defined()) {
        st.duration = d.as_double();
        if (!(st.duration > 0.0))
            d.fail(fmt::format("expected duration > 0 (s), got {:g}", st.duration));
    }
    const yaml::Node inc = s.require("increments");
    st.increments = inc.as_integer();
    if (st.increments < 1 || st.increments > 100000000)
        inc.fail(fmt::format("expected 1 <= increments <= 1e8, got {}", st.increments));
}

// A stage written in the general form.
Stage read_general_stage(const yaml::Node &s) {
    constexpr std::array<std::string_view, 12> keys = {
        "name",  "duration", "increments", "control",     "constraints", "free",
        "until", "rotation", "replay",     "zero_strain", "lab_file",    "deformation_gradient"};
    s.allow_keys(keys);
    Stage st;
    st.where = s.where();
    if (const yaml::Node rp = s.get("replay"); rp.defined()) {
        st.replay = read_replay(rp);
        for (const char *k : {"control", "constraints", "free", "until", "rotation", "increments",
                              "duration", "zero_strain"})
            if (s.get(k).defined())
                s.get(k).fail("a replay stage is one plugin call with the given inputs: remove "
                              "this key");
        return st;
    }
    std::array<bool, 6> controlled{};
    if (const yaml::Node lab = s.get("lab_file"); lab.defined()) {
        if (s.get("duration").defined() || s.get("increments").defined())
            lab.fail("a lab_file stage takes its duration and increments from the file: remove "
                     "duration: and increments: (use increments_per_row)");
        read_lab_file(lab, s.file(), st, controlled);
    } else {
        read_duration(s, st);
    }
    if (const yaml::Node z = s.get("zero_strain"); z.defined()) st.zero_strain = z.as_bool();
    if (const yaml::Node fg = s.get("deformation_gradient"); fg.defined()) {
        // F(tau) component by component (a number or a [[tau, value], ...]
        // table), the identity where not given; absolute, from the
        // reference configuration.
        constexpr std::array<std::string_view, 9> fk = {"xx", "xy", "xz", "yx", "yy",
                                                        "yz", "zx", "zy", "zz"};
        fg.allow_keys(fk);
        std::array<PiecewiseLinear, 9> F;
        for (std::size_t k = 0; k < 9; ++k) {
            F[k] =
                PiecewiseLinear(std::vector<std::array<double, 2>>{{0.0, k % 4 == 0 ? 1.0 : 0.0}});
            if (const yaml::Node v = fg.get(fk[k]); v.defined()) F[k] = read_piecewise_linear(v);
        }
        st.deformation = F;
        for (const char *k : {"control", "constraints", "free", "until", "rotation", "lab_file"})
            if (s.get(k).defined())
                s.get(k).fail("a deformation_gradient stage prescribes the whole motion: remove "
                              "this key");
        return st;
    }
    if (const yaml::Node rot = s.get("rotation"); rot.defined()) {
        // A rigid rotation of the current configuration by `angle` degrees
        // about `axis` over the stage: F(tau) = R(angle tau / duration) F0.
        constexpr std::array<std::string_view, 2> rk = {"axis", "angle"};
        rot.allow_keys(rk);
        const std::vector<double> ax = rot.require("axis").as_doubles();
        if (ax.size() != 3 || std::hypot(ax[0], ax[1], ax[2]) == 0.0)
            rot.require("axis").fail("expected a non-zero vector [x, y, z]");
        RigidRotation r;
        for (int i = 0; i < 3; ++i)
            r.axis[static_cast<std::size_t>(i)] = ax[static_cast<std::size_t>(i)];
        r.angle = rot.require("angle").as_double() * std::numbers::pi / 180.0;
        st.rotation = r;
        for (const char *k : {"control", "constraints", "free", "until"})
            if (s.get(k).defined())
                s.get(k).fail("a rotation stage prescribes the whole deformation: remove this key");
        return st;
    }
    if (const yaml::Node ctrl = s.get("control"); ctrl.defined()) {
        ctrl.expect_map();
        for (const std::string &key : ctrl.keys()) {
            const int c = component_index(ctrl, key);
            if (controlled[static_cast<std::size_t>(c)])
                ctrl.get(key).fail(
                    fmt::format("component {} is already driven by the lab file", key));
            st.conditions[static_cast<std::size_t>(c)] = read_component_control(ctrl.get(key), c);
            controlled[static_cast<std::size_t>(c)] = true;
        }
    }
    std::vector<int> free;
    if (const yaml::Node fr = s.get("free"); fr.defined()) {
        fr.expect_sequence();
        for (std::size_t i = 0; i < fr.size(); ++i) {
            const int c = component_index(fr.at(i), fr.at(i).as_string());
            if (controlled[static_cast<std::size_t>(c)])
                fr.at(i).fail(fmt::format("component {} is both under control: and free",
                                          kVoigtNames[static_cast<std::size_t>(c)]));
            if (std::find(free.begin(), free.end(), c) != free.end()) fr.at(i).fail("listed twice");
            free.push_back(c);
        }
    }
    std::vector<Condition> extra;
    if (const yaml::Node cons = s.get("constraints"); cons.defined()) {
        cons.expect_sequence();
        for (std::size_t i = 0; i < cons.size(); ++i)
            extra.push_back(read_constraint(cons.at(i)));
    }
    if (extra.size() != free.size())
        s.fail(fmt::format("{} constraint(s) but {} free component(s): each constraint takes the "
                           "place of one component listed under free:",
                           extra.size(), free.size()));
    // Components neither controlled nor free keep their stress.
    for (std::size_t c = 0; c < 6; ++c)
        if (!controlled[c] &&
            std::find(free.begin(), free.end(), static_cast<int>(c)) == free.end()) {
            st.conditions[c].b[static_cast<int>(c)] = 1.0;
            st.conditions[c].label = fmt::format("sig_{}", kVoigtNames[c]);
        }
    for (std::size_t i = 0; i < free.size(); ++i)
        st.conditions[static_cast<std::size_t>(free[i])] = extra[i];
    if (const yaml::Node u = s.get("until"); u.defined()) st.until = read_until(u);
    return st;
}

void read_stages(const yaml::Node &list, int axis, std::vector<Stage> &out, int depth) {
    list.expect_sequence();
    for (std::size_t i = 0; i < list.size(); ++i) {
        const yaml::Node s = list.at(i);
        s.expect_map();
        if (const yaml::Node rep = s.get("repeat"); rep.defined()) {
            constexpr std::array<std::string_view, 2> keys = {"repeat", "stages"};
            s.allow_keys(keys);
            const long n = rep.as_integer();
            if (n < 1 || n > 100000)
                rep.fail(fmt::format("expected 1 <= repeat <= 1e5, got {}", n));
            if (depth > 4) s.fail("repeat blocks nest at most 5 deep");
            std::vector<Stage> body;
            read_stages(s.require("stages"), axis, body, depth + 1);
            for (long k = 0; k < n; ++k)
                for (Stage st : body) {
                    st.name += fmt::format(" (repeat {})", k + 1);
                    out.push_back(std::move(st));
                }
            continue;
        }
        std::vector<Stage> expanded;
        if (s.get("preset").defined())
            expanded = expand_preset(s, axis);
        else
            expanded.push_back(read_general_stage(s));
        const std::string name = s.get("name").defined() ? s.get("name").as_string()
                                                         : fmt::format("stage {}", out.size() + 1);
        for (std::size_t k = 0; k < expanded.size(); ++k) {
            if (expanded[k].name.empty())
                expanded[k].name = expanded.size() == 1 ? name : fmt::format("{} {}", name, k + 1);
            out.push_back(std::move(expanded[k]));
        }
    }
}

CompareSpec read_compare(const yaml::Node &n) {
    constexpr std::array<std::string_view, 5> keys = {"file", "x", "reference_x", "columns",
                                                      "stage"};
    n.allow_keys(keys);
    CompareSpec c;
    c.where = n.where();
    c.file = n.require("file").as_string();
    c.x = n.require("x").as_string();
    c.ref_x = n.get("reference_x").defined() ? n.get("reference_x").as_string() : c.x;
    if (n.get("stage").defined()) c.stage = n.get("stage").as_string();
    const yaml::Node cols = n.require("columns");
    cols.expect_map();
    for (const std::string &key : cols.keys()) {
        const yaml::Node e = cols.get(key);
        constexpr std::array<std::string_view, 3> ck = {"column", "relative", "absolute"};
        e.allow_keys(ck);
        CompareSpec::Column col;
        col.ours = key;
        col.theirs = e.get("column").defined() ? e.get("column").as_string() : key;
        if (e.get("relative").defined()) col.rel = e.get("relative").as_double();
        if (e.get("absolute").defined()) col.abs = e.get("absolute").as_double();
        if (col.rel < 0 || col.abs < 0 || (col.rel == 0 && col.abs == 0))
            e.fail("give a tolerance: relative and/or absolute, >= 0 and not both 0");
        c.columns.push_back(col);
    }
    if (c.columns.empty()) cols.fail("name at least one column to compare");
    return c;
}

} // namespace

PointCase read_point_case(const yaml::Node &root, PluginRegistry &registry) {
    constexpr std::array<std::string_view, 11> top = {
        "talus",  "plugins", "material", "initial_stress",       "axis", "stages", "time",
        "strain", "output",  "compare",  "characteristic_length"};
    root.allow_keys(top);
    const yaml::Node version = root.require("talus");
    if (version.as_integer() != 1)
        version.fail(fmt::format("unsupported file format version {}; this talus reads version 1",
                                 version.as_integer()));

    if (const yaml::Node plugins = root.get("plugins"); plugins.defined())
        load_plugin_list(plugins, registry);

    PointCase pc;
    pc.file = root.file();
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
    if (const yaml::Node h = root.get("characteristic_length"); h.defined()) {
        pc.characteristic_length = h.as_double();
        if (!(pc.characteristic_length > 0.0) || !std::isfinite(pc.characteristic_length))
            h.fail(fmt::format("expected a length > 0 in m, got {}", pc.characteristic_length));
    }
    if (const yaml::Node ax = root.get("axis"); ax.defined()) {
        const std::string a = ax.as_string();
        if (a != "x" && a != "y" && a != "z") ax.fail("expected x, y or z");
        pc.axis = a[0] - 'x';
    }

    const bool legacy = root.get("strain").defined() || root.get("time").defined();
    if (legacy && root.get("stages").defined())
        root.get("stages").fail("give either stages: or the single-path form time: + strain:");
    if (legacy) {
        // One stage: every component follows its absolute strain table.
        Stage st;
        st.name = "path";
        st.where = root.where();
        const yaml::Node time = root.require("time");
        constexpr std::array<std::string_view, 2> time_keys = {"end", "increments"};
        time.allow_keys(time_keys);
        const yaml::Node end = time.require("end");
        st.duration = end.as_double();
        if (!(st.duration > 0.0))
            end.fail(fmt::format("expected end > 0 (s), got {:g}", st.duration));
        const yaml::Node inc = time.require("increments");
        st.increments = inc.as_integer();
        if (st.increments < 1 || st.increments > 100000000)
            inc.fail(fmt::format("expected 1 <= increments <= 1e8, got {}", st.increments));
        const yaml::Node strain = root.require("strain");
        strain.allow_keys(kVoigtNames);
        for (std::size_t c = 0; c < 6; ++c) {
            Condition &cond = st.conditions[c];
            cond.a[static_cast<int>(c)] = 1.0;
            cond.value.kind = ControlValue::Kind::table;
            cond.label = fmt::format("eps_{}", kVoigtNames[c]);
            if (const yaml::Node f = strain.get(kVoigtNames[c]); f.raw().IsDefined())
                cond.value.table = read_piecewise_linear(f);
        }
        pc.stages.push_back(std::move(st));
    } else {
        const yaml::Node stages = root.require("stages");
        read_stages(stages, pc.axis, pc.stages, 0);
        if (pc.stages.empty()) stages.fail("expected at least one stage");
    }

    if (const yaml::Node out = root.get("output"); out.defined()) {
        constexpr std::array<std::string_view, 1> out_keys = {"every"};
        out.allow_keys(out_keys);
        if (const yaml::Node every = out.get("every"); every.defined()) {
            pc.output_every = every.as_integer();
            if (pc.output_every < 1) every.fail("expected every >= 1 (increments)");
        }
    }
    if (const yaml::Node cmp = root.get("compare"); cmp.defined()) {
        pc.compare = read_compare(cmp);
        const std::filesystem::path f(pc.compare->file);
        if (f.is_relative())
            pc.compare->file =
                (std::filesystem::path(pc.file).parent_path() / f).lexically_normal().string();
        // Every compared column must be one the driver writes.
        PointRow probe;
        probe.strain.setZero();
        probe.stress.setZero();
        probe.state = pc.material.initial_state;
        for (const auto &col : pc.compare->columns)
            if (!point_quantity(probe, *pc.instance, pc.axis, col.ours))
                cmp.get("columns").get(col.ours).fail(
                    fmt::format("'{}' is not an output column of this case", col.ours));
        if (!point_quantity(probe, *pc.instance, pc.axis, pc.compare->x))
            cmp.get("x").fail(fmt::format("'{}' is not an output column", pc.compare->x));
        if (!pc.compare->stage.empty() &&
            std::none_of(pc.stages.begin(), pc.stages.end(),
                         [&](const Stage &st) { return st.name == pc.compare->stage; }))
            cmp.get("stage").fail(fmt::format("no stage is named '{}'", pc.compare->stage));
    }
    for (const Stage &st : pc.stages)
        if (st.replay && st.replay->state.size() != pc.material.initial_state.size())
            throw Error(fmt::format("{}: error: stage '{}': replay state has {} values, model "
                                    "'{}' has {}",
                                    st.where, st.name, st.replay->state.size(),
                                    pc.instance->model().id(), pc.material.initial_state.size()));
    // Exit conditions must name a quantity the driver knows.
    for (const Stage &st : pc.stages)
        if (st.until) {
            PointRow probe;
            probe.strain.setZero();
            probe.stress.setZero();
            probe.state = pc.material.initial_state;
            if (!point_quantity(probe, *pc.instance, pc.axis, st.until->variable) &&
                st.until->variable != "stage_time")
                throw Error(fmt::format("{}: error: stage '{}': until '{}' names an unknown "
                                        "quantity '{}'; use an output column (p, q, eps_a, eps_v, "
                                        "sig_xx, ..., a state variable) or stage_time",
                                        st.where, st.name, st.until->text, st.until->variable));
        }
    return pc;
}

// ---------------------------------------------------------- quantities --

namespace {

// Deviatoric-strain invariant sqrt(2/3 e:e) of a tensor-component vector.
double shear_strain_invariant(const Vec6 &e) {
    const double m = (e[0] + e[1] + e[2]) / 3.0;
    const double d0 = e[0] - m, d1 = e[1] - m, d2 = e[2] - m;
    return std::sqrt(
        2.0 / 3.0 *
        (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (e[3] * e[3] + e[4] * e[4] + e[5] * e[5])));
}

} // namespace

std::optional<double> point_quantity(const PointRow &r, const MaterialInstance &material, int axis,
                                     const std::string &name) {
    for (std::size_t c = 0; c < 6; ++c) {
        if (name == fmt::format("eps_{}", kVoigtNames[c])) return r.strain[static_cast<int>(c)];
        if (name == fmt::format("sig_{}", kVoigtNames[c])) return r.stress[static_cast<int>(c)];
    }
    const int l1 = (axis + 1) % 3, l2 = (axis + 2) % 3;
    if (name == "time") return r.time;
    if (name == "stage") return r.stage;
    // 0.0 - x: a negated zero prints as 0, not -0.
    if (name == "p") return 0.0 - (r.stress[0] + r.stress[1] + r.stress[2]) / 3.0;
    if (name == "q") return sdk::von_mises(r.stress);
    if (name == "eps_v") return 0.0 - (r.strain[0] + r.strain[1] + r.strain[2]);
    if (name == "eps_q") return shear_strain_invariant(r.strain);
    if (name == "eps_a") return 0.0 - r.strain[axis];
    if (name == "sig_a") return 0.0 - r.stress[axis];
    if (name == "sig_r") return 0.0 - 0.5 * (r.stress[l1] + r.stress[l2]);
    if (name == "q_a") return 0.5 * (r.stress[l1] + r.stress[l2]) - r.stress[axis];
    if (name == "eta") {
        const double p = sdk::mean_pressure(r.stress);
        return p != 0.0 ? sdk::von_mises(r.stress) / p : 0.0;
    }
    std::size_t k = 0;
    for (const StateInfo &s : material.state().vars) {
        for (std::uint32_t j = 0; j < s.size; ++j, ++k) {
            const std::string col = s.size == 1 ? s.name : fmt::format("{}_{}", s.name, j);
            if (name == col && k < r.state.size()) return r.state[k];
        }
    }
    return std::nullopt;
}

// ------------------------------------------------------------- running --

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

// -------------------------------------------------------------- output --

void write_point_csv(std::ostream &out, const MaterialInstance &material, int axis,
                     const std::vector<PointRow> &rows) {
    out << "time,stage";
    for (auto c : kVoigtNames)
        out << ",eps_" << c;
    for (auto c : kVoigtNames)
        out << ",sig_" << c;
    out << ",p,q,eps_v,eps_q,eps_a,sig_a,sig_r,q_a";
    for (const StateInfo &s : material.state().vars) {
        if (s.size == 1)
            out << ',' << s.name;
        else
            for (std::uint32_t k = 0; k < s.size; ++k)
                out << ',' << s.name << '_' << k;
    }
    out << '\n';
    // 17 significant digits: the CSV round-trips every double exactly.
    for (const PointRow &r : rows) {
        out << fmt::format("{:.17g},{}", r.time, r.stage);
        for (int c = 0; c < 6; ++c)
            out << fmt::format(",{:.17g}", r.strain[c]);
        for (int c = 0; c < 6; ++c)
            out << fmt::format(",{:.17g}", r.stress[c]);
        for (const char *q : {"p", "q", "eps_v", "eps_q", "eps_a", "sig_a", "sig_r", "q_a"})
            out << fmt::format(",{:.17g}", *point_quantity(r, material, axis, q));
        for (double v : r.state)
            out << fmt::format(",{:.17g}", v);
        out << '\n';
    }
}

namespace {
std::string one_line(std::string s) {
    std::replace(s.begin(), s.end(), '\n', ' ');
    return s;
}
// YAML single-quoted scalar body: a quote is written twice.
std::string single_quoted(const std::string &s) {
    std::string out;
    for (char c : s)
        out += c == '\'' ? std::string("''") : std::string(1, c);
    return out;
}
} // namespace

std::string replay_case_yaml(const FailedCall &fc, const Scenario &sc) {
    const NamedMaterial &m = sc.materials.at(fc.material);
    const Model &model = *m.spec.model;
    auto list = [](const auto &v) {
        std::string s = "[";
        for (std::size_t i = 0; i < v.size(); ++i)
            s += fmt::format("{}{:.17g}", i ? ", " : "", v[i]);
        return s + "]";
    };
    std::string y = fmt::format(
        "# Replays the plugin call that failed in `talus run {}`: material '{}', particle {}, "
        "step {},\n# t = {:.17g} s. The inputs are those the plugin received (engineering shear, "
        "row-major F,\n# stress tension positive). Run: talus point THIS_FILE\n"
        "# The plugin said: {}\n",
        sc.file, m.name, fc.particle, fc.step, fc.time, one_line(fc.message));
    y += "talus: 1\n";
    y += fmt::format("plugins: ['{}']\n", single_quoted(model.library().path().string()));
    y += fmt::format("material:\n  model: {}\n  density: {:.17g}\n", model.id(), m.spec.density);
    for (std::size_t i = 0; i < model.params().size(); ++i) {
        const ParamInfo &p = model.params()[i];
        const double v = m.spec.params[i].scalar;
        if (p.type == TALUS_PARAM_REAL_ARRAY)
            y += fmt::format("  {}: {}\n", p.key, list(m.spec.params[i].reals));
        else if (p.type == TALUS_PARAM_STRING)
            y += fmt::format("  {}: '{}'\n", p.key, single_quoted(m.spec.params[i].text));
        else if (p.type == TALUS_PARAM_BOOLEAN)
            y += fmt::format("  {}: {}\n", p.key, v != 0.0 ? "true" : "false");
        else if (p.type == TALUS_PARAM_INTEGER)
            y += fmt::format("  {}: {}\n", p.key, static_cast<long long>(v));
        else
            y += fmt::format("  {}: {:.17g}\n", p.key, v);
    }
    y += "stages:\n  - name: failed call\n    replay:\n";
    y += fmt::format("      time: {:.17g}\n      dt: {:.17g}\n      density: {:.17g}\n", fc.time,
                     fc.dt, fc.density);
    y += fmt::format("      strain_increment: {}\n", list(fc.strain_increment));
    y += fmt::format("      F_start: {}\n      F_end: {}\n", list(fc.F_start), list(fc.F_end));
    y += fmt::format("      stress: {}\n", list(fc.stress));
    y += fmt::format("      state: {}\n", list(fc.state));
    return y;
}

void print_stages(std::ostream &out, const PointCase &pc) {
    auto value_text = [](const ControlValue &v) {
        switch (v.kind) {
        case ControlValue::Kind::change:
            return v.amount == 0.0 ? std::string("held") : fmt::format("change by {:g}", v.amount);
        case ControlValue::Kind::target: return fmt::format("to {:g}", v.amount);
        case ControlValue::Kind::rate: return fmt::format("at rate {:g} per s", v.amount);
        case ControlValue::Kind::table: return std::string("table of stage time");
        }
        return std::string();
    };
    for (std::size_t k = 0; k < pc.stages.size(); ++k) {
        const Stage &st = pc.stages[k];
        out << fmt::format("stage {} '{}': duration {:g}, {} increments{}\n", k + 1, st.name,
                           st.duration, st.increments,
                           st.until ? fmt::format(", until {}", st.until->text) : "");
        if (st.replay) {
            out << "  one plugin call with the recorded inputs\n";
            continue;
        }
        if (st.deformation) {
            out << "  prescribed deformation gradient F(tau)\n";
            continue;
        }
        if (st.rotation) {
            out << fmt::format("  rigid rotation by {:g} deg about [{:g}, {:g}, {:g}]\n",
                               st.rotation->angle * 180.0 / std::numbers::pi, st.rotation->axis[0],
                               st.rotation->axis[1], st.rotation->axis[2]);
            continue;
        }
        for (const Condition &c : st.conditions)
            out << fmt::format("  {}: {}\n", c.label, value_text(c.value));
    }
}

} // namespace talus
