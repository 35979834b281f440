// The driver-case reader (talus/input/point_case.hpp): a case file's keys,
// its stages (general conditions, presets, laboratory files, replays), its
// exit conditions and its `compare:` block, each error at file:line:column.
#include <talus/input/point_case.hpp>

#include <talus/input/csv_table.hpp>
#include <talus/input/material_yaml.hpp>
#include <talus/input/time_function_yaml.hpp>

#include <Eigen/LU>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

namespace talus {

namespace {

int component_index(const yaml::Node &key_node, const std::string &name) {
    for (std::size_t c = 0; c < 6; ++c)
        if (name == kVoigtNames[c]) return static_cast<int>(c);
    const std::string near = yaml::closest_match(name, kVoigtNames);
    key_node.fail(fmt::format("unknown component '{}'; expected one of xx, yy, zz, xy, yz, xz{}",
                              name,
                              near.empty() ? "" : fmt::format(" (did you mean '{}'?)", near)));
}

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

// The six conditions a eps + b sig = value of a stage must fix the six
// strains and stresses together: a condition that is a combination of the
// others (a constraint repeating a control, two proportional constraints)
// leaves the increment undetermined whatever the material, and the solve
// would fail, or pick an answer, in the first step. Rows of [a b], the
// controls and held stresses first, then the constraints in their order:
// the first row that adds nothing to the rank of those before is named.
void refuse_dependent(const Stage &st, const std::vector<int> &free, const yaml::Node &where) {
    std::vector<int> order;
    for (int c = 0; c < 6; ++c)
        if (std::find(free.begin(), free.end(), c) == free.end()) order.push_back(c);
    order.insert(order.end(), free.begin(), free.end());
    auto named = [&](int c) {
        const Condition &k = st.conditions[static_cast<std::size_t>(c)];
        const bool constraint = std::find(free.begin(), free.end(), c) != free.end();
        return constraint ? fmt::format("the constraint '{}' (in place of {})", k.label,
                                        kVoigtNames[static_cast<std::size_t>(c)])
                          : fmt::format("'{}'", k.label);
    };
    Eigen::MatrixXd m(6, 12);
    for (int r = 0; r < 6; ++r) {
        const Condition &k =
            st.conditions[static_cast<std::size_t>(order[static_cast<std::size_t>(r)])];
        m.row(r) << k.a.transpose(), k.b.transpose();
    }
    // Strain and stress weights differ in scale (a compliance-like stress
    // weight is 1e-9 /Pa): each block scaled to its largest entry, which
    // leaves the rank as it is, before a threshold relative to 1.
    for (const int block : {0, 6}) {
        const double big = m.middleCols(block, 6).cwiseAbs().maxCoeff();
        if (big > 0.0) m.middleCols(block, 6) /= big;
    }
    for (int rows = 1; rows <= 6; ++rows) {
        Eigen::FullPivLU<Eigen::MatrixXd> lu(m.topRows(rows));
        lu.setThreshold(1e-10);
        if (lu.rank() == rows) continue;
        std::string before;
        for (int r = 0; r + 1 < rows; ++r)
            before += (r ? ", " : "") + named(order[static_cast<std::size_t>(r)]);
        where.fail(fmt::format("the stage's conditions are not independent: {} is a combination "
                               "of {}; the six must fix the strain and stress together: drop it, "
                               "or free another component",
                               named(order[static_cast<std::size_t>(rows - 1)]), before));
    }
}

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
    refuse_dependent(st, free, s);
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

} // namespace talus
