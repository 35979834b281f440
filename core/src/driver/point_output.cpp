// What the material-point driver writes: its CSV (the columns of
// point_quantity), the stages as text (--print-stages), and the replay
// case of a run's failed call.
#include <talus/driver/point_driver.hpp>

#include <talus/sdk/voigt.hpp>

#include <fmt/format.h>

#include <cmath>
#include <ostream>

namespace talus {

using Vec6 = PointVec6;

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
