// The laboratory tests an engineer recognises, expanded into the driver's
// general form: six linear conditions on strain and stress per stage
// (point_driver.hpp). Quantities given to a preset follow the geotechnical
// convention (compression positive: a positive axial_strain shortens the
// sample, a positive pressure compresses it); the conditions themselves are
// in the plugin's convention (tension positive).
#include <talus/input/point_case.hpp>

#include <talus/sdk/voigt.hpp>

#include <fmt/format.h>

#include <algorithm>

namespace talus {

namespace {

Condition strain_change(int c, double amount) {
    Condition k;
    k.a[c] = 1.0;
    k.value.kind = ControlValue::Kind::change;
    k.value.amount = amount;
    k.label = fmt::format("eps_{}", kVoigtNames[static_cast<std::size_t>(c)]);
    return k;
}
Condition stress_change(int c, double amount) {
    Condition k;
    k.b[c] = 1.0;
    k.value.kind = ControlValue::Kind::change;
    k.value.amount = amount;
    k.label = fmt::format("sig_{}", kVoigtNames[static_cast<std::size_t>(c)]);
    return k;
}
Condition stress_target(int c, double value) {
    Condition k = stress_change(c, 0.0);
    k.value.kind = ControlValue::Kind::target;
    k.value.amount = value;
    return k;
}
// eps_xx + eps_yy + eps_zz held: constant volume (undrained, with an
// incompressible pore fluid and grains).
Condition volume_held() {
    Condition k;
    k.a.head<3>().setOnes();
    k.label = "eps_xx + eps_yy + eps_zz";
    return k;
}
// sig_l1 - sig_l2 held: the two lateral stresses stay equal (axisymmetry).
Condition laterals_equal(int l1, int l2) {
    Condition k;
    k.b[l1] = 1.0;
    k.b[l2] = -1.0;
    k.label = fmt::format("sig_{} - sig_{}", kVoigtNames[static_cast<std::size_t>(l1)],
                          kVoigtNames[static_cast<std::size_t>(l2)]);
    return k;
}
// sig_xx + sig_yy + sig_zz held: constant mean stress.
Condition mean_stress_held() {
    Condition k;
    k.b.head<3>().setOnes();
    k.label = "sig_xx + sig_yy + sig_zz";
    return k;
}
// q_a = -sig_a + (sig_l1 + sig_l2) / 2 (compression positive) changed.
Condition deviator_change(int a, int l1, int l2, double amount) {
    Condition k;
    k.b[a] = -1.0;
    k.b[l1] = 0.5;
    k.b[l2] = 0.5;
    k.value.amount = amount;
    k.label = fmt::format(
        "q_a = -sig_{} + (sig_{} + sig_{})/2", kVoigtNames[static_cast<std::size_t>(a)],
        kVoigtNames[static_cast<std::size_t>(l1)], kVoigtNames[static_cast<std::size_t>(l2)]);
    return k;
}

int voigt(int i, int j) { return sdk::voigt_index(i, j); }

// The common frame: every stress component not set below is held.
Stage held_stresses() {
    Stage s;
    for (int c = 0; c < 6; ++c)
        s.conditions[static_cast<std::size_t>(c)] = stress_change(c, 0.0);
    return s;
}

double number(const yaml::Node &n, std::string_view key) { return n.require(key).as_double(); }

// What a simple shear holds besides the lateral strains: `constant:`.
bool constant_volume(const yaml::Node &node) {
    const std::string constant =
        node.get("constant").defined() ? node.get("constant").as_string() : "volume";
    if (constant != "volume" && constant != "normal_stress")
        node.get("constant").fail("expected volume or normal_stress");
    return constant == "volume";
}

// The axes of a preset: the axis a, the laterals l1, l2, and the shear
// component on the plane normal to the axis.
struct Axes {
    int a, l1, l2, shear;
};

// N cycles 0 -> +A -> -A -> 0, `increments` per quarter cycle, from the
// stage `s` that `finish` read (its duration, increments, zero_strain).
std::vector<Stage> cyclic_stages(const yaml::Node &node, const Stage &s, bool triaxial, Axes x) {
    const int a = x.a, l1 = x.l1, l2 = x.l2, shear = x.shear;
    if (node.get("until").defined())
        node.get("until").fail("a cyclic preset runs its cycles; use a general stage with "
                               "until: to stop on a condition");
    const double A = number(node, "amplitude");
    const std::string control =
        node.get("control").defined() ? node.get("control").as_string() : "strain";
    if (control != "strain" && control != "stress")
        node.get("control").fail("expected strain or stress");
    const long cycles = node.require("cycles").as_integer();
    if (cycles < 1 || cycles > 100000) node.require("cycles").fail("expected 1 <= cycles <= 1e5");
    Stage base = s;
    if (triaxial) {
        const bool drained = node.get("drained").defined() && node.get("drained").as_bool();
        if (!drained) {
            base.conditions[static_cast<std::size_t>(l1)] = volume_held();
            base.conditions[static_cast<std::size_t>(l2)] = laterals_equal(l1, l2);
        }
    } else {
        const bool volume = constant_volume(node);
        base.conditions[static_cast<std::size_t>(l1)] = strain_change(l1, 0.0);
        base.conditions[static_cast<std::size_t>(l2)] = strain_change(l2, 0.0);
        if (volume) base.conditions[static_cast<std::size_t>(a)] = strain_change(a, 0.0);
    }
    // The driven condition for a change d of the cycled quantity.
    auto driven = [&](double d) {
        if (triaxial) {
            if (control == "strain") return strain_change(a, -d);
            // Undrained: q_a replaces the axial row (the laterals are
            // tied to it by the volume and equality rows); drained: the
            // cell pressure is held, so q_a changes with -sig_a alone.
            return deviator_change(a, l1, l2, d);
        }
        return control == "strain" ? strain_change(shear, 0.5 * d) : stress_change(shear, d);
    };
    const int row = triaxial ? a : shear;
    const double legs[3] = {A, -2.0 * A, A};
    const long mult[3] = {1, 2, 1};
    std::vector<Stage> out;
    for (long k = 0; k < cycles; ++k)
        for (int leg = 0; leg < 3; ++leg) {
            Stage st = base;
            st.conditions[static_cast<std::size_t>(row)] = driven(legs[leg]);
            st.duration = s.duration * static_cast<double>(mult[leg]) / 4.0;
            st.increments = s.increments * mult[leg];
            st.zero_strain = s.zero_strain && k == 0 && leg == 0;
            st.name = fmt::format("cycle {} {}", k + 1,
                                  leg == 0   ? "to +amplitude"
                                  : leg == 1 ? "to -amplitude"
                                             : "back to zero");
            out.push_back(st);
        }
    return out;
}

} // namespace

std::vector<Stage> expand_preset(const yaml::Node &node, int axis) {
    const std::string preset = node.require("preset").as_string();
    const int a = axis, l1 = (axis + 1) % 3, l2 = (axis + 2) % 3;
    const int shear = voigt(a, l1); // simple shear on the plane normal to the axis

    std::vector<std::string_view> keys = {"preset",     "name",  "duration",
                                          "increments", "until", "zero_strain"};
    std::vector<Stage> out;
    Stage s = held_stresses();
    auto finish = [&](std::vector<std::string_view> extra) {
        keys.insert(keys.end(), extra.begin(), extra.end());
        node.allow_keys(keys);
        s.where = node.where();
        if (const yaml::Node d = node.get("duration"); d.defined()) {
            s.duration = d.as_double();
            if (!(s.duration > 0.0)) d.fail("expected duration > 0 (s)");
        }
        if (const yaml::Node z = node.get("zero_strain"); z.defined()) s.zero_strain = z.as_bool();
        const yaml::Node inc = node.require("increments");
        s.increments = inc.as_integer();
        if (s.increments < 1 || s.increments > 100000000)
            inc.fail(fmt::format("expected 1 <= increments <= 1e8, got {}", s.increments));
    };
    auto until = [&]() {
        if (const yaml::Node u = node.get("until"); u.defined()) s.until = read_until(u);
    };

    if (preset == "isotropic") {
        // All three normal stresses to -pressure, shear stresses held.
        finish({"pressure"});
        const double p = number(node, "pressure");
        for (int c = 0; c < 3; ++c)
            s.conditions[static_cast<std::size_t>(c)] = stress_target(c, -p);
        until();
        out.push_back(s);
    } else if (preset == "oedometer") {
        // Lateral strains held (K0 conditions); the axis by strain or stress.
        finish({"axial_strain", "axial_stress"});
        const bool by_strain = node.get("axial_strain").defined();
        const bool by_stress = node.get("axial_stress").defined();
        if (by_strain == by_stress) node.fail("give exactly one of axial_strain, axial_stress");
        s.conditions[static_cast<std::size_t>(a)] =
            by_strain ? strain_change(a, -number(node, "axial_strain"))
                      : stress_target(a, -number(node, "axial_stress"));
        s.conditions[static_cast<std::size_t>(l1)] = strain_change(l1, 0.0);
        s.conditions[static_cast<std::size_t>(l2)] = strain_change(l2, 0.0);
        until();
        out.push_back(s);
    } else if (preset == "triaxial_drained" || preset == "triaxial_undrained" ||
               preset == "triaxial_constant_p") {
        // Axial strain imposed; drained: cell pressure held; undrained:
        // constant volume with equal lateral stresses; constant p': mean
        // stress held with equal lateral stresses.
        finish({"axial_strain"});
        s.conditions[static_cast<std::size_t>(a)] = strain_change(a, -number(node, "axial_strain"));
        if (preset != "triaxial_drained") {
            s.conditions[static_cast<std::size_t>(l1)] =
                preset == "triaxial_undrained" ? volume_held() : mean_stress_held();
            s.conditions[static_cast<std::size_t>(l2)] = laterals_equal(l1, l2);
        }
        until();
        out.push_back(s);
    } else if (preset == "simple_shear") {
        // Shear strain (engineering, on the plane normal to the axis) with
        // no lateral strain; constant volume (axial strain held) or constant
        // normal stress.
        finish({"shear_strain", "constant"});
        const bool volume = constant_volume(node);
        s.conditions[static_cast<std::size_t>(l1)] = strain_change(l1, 0.0);
        s.conditions[static_cast<std::size_t>(l2)] = strain_change(l2, 0.0);
        if (volume) s.conditions[static_cast<std::size_t>(a)] = strain_change(a, 0.0);
        s.conditions[static_cast<std::size_t>(shear)] =
            strain_change(shear, 0.5 * number(node, "shear_strain"));
        until();
        out.push_back(s);
    } else if (preset == "cyclic_triaxial" || preset == "cyclic_simple_shear") {
        const bool triaxial = preset == "cyclic_triaxial";
        finish(triaxial
                   ? std::vector<std::string_view>{"amplitude", "control", "cycles", "drained"}
                   : std::vector<std::string_view>{"amplitude", "control", "cycles", "constant"});
        out = cyclic_stages(node, s, triaxial, {a, l1, l2, shear});
    } else {
        constexpr std::array<std::string_view, 8> known = {
            "isotropic",           "oedometer",    "triaxial_drained", "triaxial_undrained",
            "triaxial_constant_p", "simple_shear", "cyclic_triaxial",  "cyclic_simple_shear"};
        const std::string near = yaml::closest_match(preset, known);
        node.require("preset").fail(fmt::format(
            "unknown preset '{}'{}; the presets are isotropic, oedometer, triaxial_drained, "
            "triaxial_undrained, triaxial_constant_p, simple_shear, cyclic_triaxial, "
            "cyclic_simple_shear",
            preset, near.empty() ? "" : fmt::format(" (did you mean '{}'?)", near)));
    }
    return out;
}

} // namespace talus
