#include <talus/input/scenario_yaml.hpp>

#include <talus/input/error_list.hpp>
#include <talus/input/material_yaml.hpp>
#include <talus/input/time_function_yaml.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <unordered_set>

namespace talus {

namespace {

using Keys = std::vector<std::string_view>;

// The schema: the keys allowed in each mapping, by dotted path ('*' for a
// user-chosen name). The reader checks against this table and
// scenario_schema() lists it, so the documentation test and the reader can
// never disagree.
const std::vector<std::pair<std::string_view, Keys>> &schema() {
    static const std::vector<std::pair<std::string_view, Keys>> s = {
        {"",
         {"talus", "dimension", "plugins", "constants", "grid", "materials", "groups", "boundaries",
          "gravity", "damping", "nodal_velocities", "particle_velocities", "loads", "solver",
          "time", "stages", "output", "checkpoint"}},
        {"grid", {"origin", "size", "cell"}},
        {"materials.*", {"model", "density", "initial_state"}},
        {"groups.*",
         {"material", "shape", "particles_per_cell", "velocity", "angular_velocity",
          "initial_stress", "initial_state"}},
        {"groups.*.velocity", {"x", "y", "z"}},
        {"groups.*.shape", {"box", "sphere", "cylinder", "polygon"}},
        {"groups.*.shape.box", {"min", "max"}},
        {"groups.*.shape.sphere", {"center", "radius"}},
        {"groups.*.shape.cylinder", {"center", "radius", "axis", "length"}},
        {"groups.*.initial_stress", {"uniform", "field", "geostatic"}},
        {"groups.*.initial_stress.field", {"xx", "yy", "zz", "xy", "yz", "xz"}},
        {"groups.*.initial_stress.geostatic", {"k0", "surface"}},
        {"boundaries", {"x-", "x+", "y-", "y+", "z-", "z+"}},
        {"boundaries.*", {"friction"}},
        {"gravity", {"value", "ramp"}},
        {"damping", {"type", "coefficient"}},
        {"nodal_velocities[]", {"box", "velocity"}},
        {"nodal_velocities[].box", {"min", "max"}},
        {"nodal_velocities[].velocity", {"x", "y", "z"}},
        {"particle_velocities[]", {"group", "box", "velocity"}},
        {"particle_velocities[].box", {"min", "max"}},
        {"particle_velocities[].velocity", {"x", "y", "z"}},
        {"loads[]", {"point", "traction", "group", "box"}},
        {"loads[].box", {"min", "max"}},
        {"solver",
         {"scheme", "transfer", "shape", "cfl", "dt", "position_update", "cell_averaged_dilation",
          "leaving_grid", "load_balance"}},
        {"solver.transfer", {"type", "alpha"}},
        {"solver.load_balance", {"imbalance", "every"}},
        {"time", {"end"}},
        {"stages[]",
         {"name", "duration", "until", "boundaries", "gravity", "damping", "nodal_velocities",
          "particle_velocities", "loads", "activate", "remove", "set_material", "reset"}},
        {"stages[].until", {"kinetic_energy_ratio", "hold", "otherwise"}},
        {"checkpoint", {"every", "steps", "wall", "keep"}},
        {"output", {"every", "vtk", "state", "probes"}},
        {"output.probes[]", {"name", "particle", "centre_of_mass"}},
    };
    return s;
}

const Keys &keys(std::string_view path) {
    for (const auto &[p, k] : schema())
        if (p == path) return k;
    throw std::logic_error("scenario schema has no entry for " + std::string(path));
}

void allow(const yaml::Node &n, std::string_view path) { n.allow_keys(keys(path)); }

// One value out of a fixed set of words, with a suggestion for a typo.
template <class E>
E choose(const yaml::Node &n, const std::vector<std::pair<std::string_view, E>> &options) {
    const std::string word = n.as_string();
    std::vector<std::string_view> names;
    for (const auto &[name, value] : options) {
        if (word == name) return value;
        names.push_back(name);
    }
    const std::string guess = yaml::closest_match(word, names);
    std::string list;
    for (auto nm : names)
        list += (list.empty() ? "" : ", ") + std::string(nm);
    n.fail(fmt::format("unknown value '{}'{}; expected one of: {}", clip(word),
                       guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess), list));
}

// A vector of `dim` numbers.
Vec3 vec(const yaml::Node &n, int dim, const char *unit) {
    const std::vector<double> v = n.as_doubles();
    if (static_cast<int>(v.size()) != dim)
        n.fail(fmt::format("expected {} numbers ({}), one per dimension, got {}", dim, unit,
                           v.size()));
    Vec3 out{0, 0, 0};
    for (int d = 0; d < dim; ++d)
        out[static_cast<std::size_t>(d)] = v[static_cast<std::size_t>(d)];
    return out;
}

double positive(const yaml::Node &n, const char *what) {
    const double v = n.as_double();
    if (!(v > 0.0)) n.fail(fmt::format("expected {} > 0, got {:g}", what, v));
    return v;
}

Origin origin_of(const yaml::Node &n, std::string key = {}) {
    return Origin{n.where(), key.empty() ? n.path() : std::move(key)};
}

// A velocity above the speed of light is a typo (or a unit error), and its
// square overflows the energy diagnostics long before that matters.
void check_speed(const yaml::Node &n, const Vec3 &v) {
    const double speed = std::hypot(v[0], v[1], v[2]);
    if (!(speed < kSpeedOfLight))
        n.fail(fmt::format("a speed of {:g} m/s is not a velocity of a continuum (faster than "
                           "light); check the value and its units",
                           speed));
}

Box read_box(const yaml::Node &n, std::string_view path, int dim) {
    n.expect_map();
    allow(n, path);
    Box b;
    b.min = vec(n.require("min"), dim, "m");
    b.max = vec(n.require("max"), dim, "m");
    for (int d = 0; d < dim; ++d)
        if (!(b.max[static_cast<std::size_t>(d)] > b.min[static_cast<std::size_t>(d)]))
            n.fail(fmt::format("expected max > min in every direction (direction {})", "xyz"[d]));
    return b;
}

ComponentFunctions read_components(const yaml::Node &n, std::string_view path, int dim) {
    n.expect_map();
    allow(n, path);
    ComponentFunctions f;
    for (int d = 0; d < 3; ++d) {
        const char name[2] = {"xyz"[d], 0};
        const yaml::Node c = n.get(name);
        if (!c.raw().IsDefined()) continue;
        if (d >= dim) c.fail(fmt::format("a {}D scenario has no '{}' component", dim, name));
        f.c[static_cast<std::size_t>(d)] = read_piecewise_linear(c);
    }
    return f;
}

// A number, or an expression of the position in the scenario's constants
// (SpatialField). A mistake in an expression is reported at its character:
// the node's column, past an opening quote, plus the offset muParser gives.
SpatialField read_field(const yaml::Node &n, const Scenario &s) {
    if (!n.is_scalar())
        n.fail("expected a number or an expression of the position, e.g. \"0.1*sin(pi*x/L)\"");
    const std::string text = n.as_string();
    // A number, also one out of range (1e400), is read as one: as_double
    // refuses what is not finite, at the node.
    char *end = nullptr;
    (void)std::strtod(text.c_str(), &end);
    if (!text.empty() && end == text.c_str() + text.size()) return SpatialField(n.as_double());
    try {
        return SpatialField::expression(text, s.dim, s.constants);
    } catch (const ExpressionError &e) {
        const YAML::Mark m = n.raw().Mark();
        // yaml-cpp tags a quoted scalar "!", a plain one "?".
        const std::size_t quote = n.raw().Tag() == "!" ? 1 : 0;
        throw Error(fmt::format("{}:{}:{}: error: '{}': {}", n.file(), m.line + 1,
                                static_cast<std::size_t>(m.column) + 1 + quote + e.position,
                                n.path(), e.what()));
    }
}

// A group's initial velocity: [vx, vy(, vz)] or {x: .., y: .., z: ..} (an
// absent component is 0), each a number or an expression.
std::array<SpatialField, 3> read_velocity(const yaml::Node &n, const Scenario &s) {
    std::array<SpatialField, 3> v{};
    if (n.is_map()) {
        allow(n, "groups.*.velocity");
        for (int d = 0; d < 3; ++d) {
            const char name[2] = {"xyz"[d], 0};
            const yaml::Node c = n.get(name);
            if (!c.raw().IsDefined()) continue;
            if (d >= s.dim)
                c.fail(fmt::format("a {}D scenario has no '{}' component", s.dim, name));
            v[static_cast<std::size_t>(d)] = read_field(c, s);
        }
    } else {
        if (!n.is_sequence())
            n.fail(fmt::format("expected [vx, vy{}] or {{x: .., y: ..}} in m/s (numbers or "
                               "expressions of the position)",
                               s.dim == 3 ? ", vz" : ""));
        if (static_cast<int>(n.size()) != s.dim)
            n.fail(fmt::format("expected {} components (m/s), one per dimension, got {}", s.dim,
                               n.size()));
        for (std::size_t d = 0; d < n.size(); ++d)
            v[d] = read_field(n.at(d), s);
    }
    Vec3 constant{0, 0, 0};
    for (std::size_t d = 0; d < 3; ++d)
        constant[d] = v[d].constant();
    check_speed(n, constant);
    return v;
}

// A group's `initial_state`: values, or expressions, for the material's
// user-initialisable state variables (a list for a variable of several
// components, or one value for all of them).
std::vector<GroupSpec::StateValue> read_group_state(const yaml::Node &n, const Scenario &s,
                                                    const NamedMaterial &m) {
    n.expect_map();
    std::vector<std::string_view> settable;
    for (const StateInfo &v : m.spec.state.vars)
        if (v.user_initialisable()) settable.push_back(v.name);
    if (settable.empty())
        n.fail(fmt::format("material '{}' ({}) has no state variable a user may initialise", m.name,
                           m.spec.model->qualified_id()));
    n.allow_keys(settable);
    std::vector<GroupSpec::StateValue> out;
    for (const StateInfo &v : m.spec.state.vars) {
        const yaml::Node c = n.get(v.name);
        if (!c.raw().IsDefined()) continue;
        if (c.is_sequence()) {
            if (c.size() != v.size)
                c.fail(fmt::format("expected {} values for state variable '{}', got {}", v.size,
                                   v.name, c.size()));
            for (std::uint32_t k = 0; k < v.size; ++k)
                out.push_back({v.offset + k, read_field(c.at(k), s)});
        } else {
            const SpatialField f = read_field(c, s);
            for (std::uint32_t k = 0; k < v.size; ++k)
                out.push_back({v.offset + k, f});
        }
    }
    return out;
}

// The group called `name`; an unknown name fails at `n`.
std::size_t group_named(const std::string &name, const yaml::Node &n, const Scenario &s) {
    for (std::size_t g = 0; g < s.groups.size(); ++g)
        if (s.groups[g].name == name) return g;
    std::vector<std::string> names; // for the "did you mean", only on a miss
    for (const GroupSpec &g : s.groups)
        names.push_back(g.name);
    const std::string guess = yaml::closest_match(name, std::span<const std::string>(names));
    n.fail(fmt::format("no group named '{}'{}", name,
                       guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess)));
}

std::size_t group_index(const yaml::Node &n, const Scenario &s) {
    return group_named(n.as_string(), n, s);
}

GroupShape read_shape(const yaml::Node &n, int dim) {
    n.expect_map();
    allow(n, "groups.*.shape");
    if (n.keys().size() != 1) n.fail("expected exactly one of box, sphere, cylinder, polygon");
    GroupShape s;
    if (const yaml::Node b = n.get("box"); b.defined()) {
        s.kind = GroupShape::Kind::box;
        s.box = read_box(b, "groups.*.shape.box", dim);
    } else if (const yaml::Node sp = n.get("sphere"); sp.defined()) {
        s.kind = GroupShape::Kind::sphere;
        allow(sp, "groups.*.shape.sphere");
        s.center = vec(sp.require("center"), dim, "m");
        s.radius = positive(sp.require("radius"), "radius (m)");
    } else if (const yaml::Node c = n.get("cylinder"); c.defined()) {
        if (dim != 3) c.fail("a cylinder needs a 3D scenario (in 2D use sphere, a disk)");
        s.kind = GroupShape::Kind::cylinder;
        allow(c, "groups.*.shape.cylinder");
        s.center = vec(c.require("center"), dim, "m");
        s.radius = positive(c.require("radius"), "radius (m)");
        s.axis = choose<int>(c.require("axis"), {{"x", 0}, {"y", 1}, {"z", 2}});
        const double len = positive(c.require("length"), "length (m)");
        s.zmin = s.center[static_cast<std::size_t>(s.axis)] - len / 2;
        s.zmax = s.center[static_cast<std::size_t>(s.axis)] + len / 2;
    } else {
        const yaml::Node p = n.require("polygon");
        if (dim != 2) p.fail("a polygon needs a 2D scenario");
        s.kind = GroupShape::Kind::polygon;
        p.expect_sequence();
        for (std::size_t i = 0; i < p.size(); ++i) {
            const Vec3 v = vec(p.at(i), 2, "m");
            s.polygon.push_back({v[0], v[1]});
        }
        if (s.polygon.size() < 3) p.fail("expected at least 3 vertices [x, y]");
        // The shoelace area against the square of its extent: a polygon
        // whose vertices lie on a line (to round-off) encloses nothing,
        // though a point on its boundary may still count as inside it.
        double area2 = 0.0, lo_x = s.polygon[0][0], hi_x = lo_x, lo_y = s.polygon[0][1],
               hi_y = lo_y;
        for (std::size_t i = 0; i < s.polygon.size(); ++i) {
            const auto &a = s.polygon[i], &next = s.polygon[(i + 1) % s.polygon.size()];
            area2 += a[0] * next[1] - next[0] * a[1];
            lo_x = std::min(lo_x, a[0]), hi_x = std::max(hi_x, a[0]);
            lo_y = std::min(lo_y, a[1]), hi_y = std::max(hi_y, a[1]);
        }
        const double extent = std::max(hi_x - lo_x, hi_y - lo_y);
        if (!(std::abs(area2) > 1e-12 * extent * extent))
            p.fail(fmt::format("the polygon encloses no area (its {} vertices lie on a line{})",
                               s.polygon.size(), extent > 0.0 ? "" : ", or on one point"));
    }
    return s;
}

InitialStress read_initial_stress(const yaml::Node &n, const Scenario &sc) {
    n.expect_map();
    allow(n, "groups.*.initial_stress");
    if (n.keys().size() != 1) n.fail("expected exactly one of uniform, field, geostatic");
    InitialStress s;
    if (const yaml::Node u = n.get("uniform"); u.defined()) {
        s.kind = InitialStress::Kind::given;
        const std::vector<double> v = u.as_doubles();
        if (v.size() != 6)
            u.fail(fmt::format("expected 6 components [xx, yy, zz, xy, yz, xz] in Pa, got {}",
                               v.size()));
        std::copy(v.begin(), v.end(), s.components.begin());
    } else if (const yaml::Node f = n.get("field"); f.raw().IsDefined()) {
        s.kind = InitialStress::Kind::given;
        f.expect_map();
        allow(f, "groups.*.initial_stress.field");
        constexpr std::array<std::string_view, 6> names = {"xx", "yy", "zz", "xy", "yz", "xz"};
        for (std::size_t k = 0; k < 6; ++k) {
            const yaml::Node c = f.get(names[k]);
            if (!c.raw().IsDefined()) continue;
            if (sc.dim == 2 && k >= 4)
                c.fail(fmt::format("'{}' is zero in plane strain (2D)", names[k]));
            s.components[k] = read_field(c, sc);
        }
    } else {
        const yaml::Node g = n.require("geostatic");
        s.kind = InitialStress::Kind::geostatic;
        if (g.is_map()) {
            allow(g, "groups.*.initial_stress.geostatic");
            if (const yaml::Node k = g.get("k0"); k.defined()) {
                s.k0 = k.as_double();
                if (!(s.k0 >= 0.0)) k.fail(fmt::format("expected k0 >= 0, got {:g}", s.k0));
            }
            if (const yaml::Node sf = g.get("surface"); sf.defined()) s.surface = sf.as_double();
        } else if (!(g.is_scalar() && g.raw().Scalar().empty()) && g.defined()) {
            g.fail("expected a mapping {k0: ..., surface: ...} (both optional)");
        }
    }
    return s;
}

// The conditions a mapping gives (the top level, or a stage): each key it
// has replaces what `c` held; `prefix` is the mapping's path for messages.
void read_conditions(const yaml::Node &m, const std::string &prefix, const Scenario &s,
                     Conditions &c) {
    // Boundaries.
    if (const yaml::Node b = m.get("boundaries"); b.defined()) {
        allow(b, "boundaries");
        const char *faces[6] = {"x-", "x+", "y-", "y+", "z-", "z+"};
        for (int f = 0; f < 6; ++f) {
            const yaml::Node face = b.get(faces[f]);
            if (!face.raw().IsDefined()) continue;
            if (f / 2 >= s.dim)
                face.fail(fmt::format("a {}D scenario has no face '{}'", s.dim, faces[f]));
            FaceCondition &fc = c.faces[static_cast<std::size_t>(f)];
            fc = FaceCondition{};
            if (face.is_map()) {
                allow(face, "boundaries.*");
                fc.type = FaceType::friction;
                const yaml::Node mu = face.require("friction");
                fc.friction = mu.as_double();
                if (!(fc.friction >= 0.0))
                    mu.fail(fmt::format("expected friction >= 0, got {:g}", fc.friction));
            } else {
                fc.type = choose<FaceType>(face, {{"free", FaceType::free},
                                                  {"fixed", FaceType::fixed},
                                                  {"slip", FaceType::slip},
                                                  {"roller", FaceType::roller}});
            }
        }
    }

    // Gravity.
    if (m.has("gravity")) c.gravity_ramp = 0.0;
    if (const yaml::Node g = m.get("gravity"); g.defined()) {
        if (g.is_map()) {
            allow(g, "gravity");
            c.gravity = vec(g.require("value"), s.dim, "m/s^2");
            if (const yaml::Node r = g.get("ramp"); r.defined()) {
                c.gravity_ramp = r.as_double();
                if (!(c.gravity_ramp >= 0.0)) r.fail("expected ramp >= 0 (s)");
            }
        } else {
            c.gravity = vec(g, s.dim, "m/s^2");
        }
    }

    if (const yaml::Node d = m.get("damping"); d.defined() && d.is_scalar()) {
        // `damping: none` ends a previous stage's damping.
        if (d.as_string() != "none")
            d.fail(fmt::format(
                "expected a mapping {{type: local|viscous, coefficient: a}} or 'none', got '{}'",
                d.as_string()));
        c.damping = DampingSpec{};
    } else if (d.defined()) {
        allow(d, "damping");
        c.damping.kind = choose<DampingKind>(
            d.require("type"), {{"local", DampingKind::local}, {"viscous", DampingKind::viscous}});
        const yaml::Node cn = d.require("coefficient");
        c.damping.coefficient = cn.as_double();
        if (c.damping.kind == DampingKind::local &&
            !(c.damping.coefficient >= 0.0 && c.damping.coefficient < 1.0))
            cn.fail(fmt::format("expected 0 <= coefficient < 1 for local damping (the fraction of "
                                "each unbalanced force removed), got {}",
                                c.damping.coefficient));
        if (c.damping.kind == DampingKind::viscous &&
            !(c.damping.coefficient >= 0.0 && std::isfinite(c.damping.coefficient)))
            cn.fail(fmt::format("expected a coefficient >= 0 (1/s) for viscous damping, got {}",
                                c.damping.coefficient));
    }

    if (m.has("nodal_velocities")) c.nodal_velocities.clear();
    if (const yaml::Node nv = m.get("nodal_velocities"); nv.defined()) {
        nv.expect_sequence();
        for (std::size_t i = 0; i < nv.size(); ++i) {
            const yaml::Node e = nv.at(i);
            allow(e, "nodal_velocities[]");
            NodalVelocity v;
            v.origin = origin_of(e, fmt::format("{}nodal_velocities[{}]", prefix, i));
            v.box = read_box(e.require("box"), "nodal_velocities[].box", s.dim);
            v.velocity =
                read_components(e.require("velocity"), "nodal_velocities[].velocity", s.dim);
            c.nodal_velocities.push_back(std::move(v));
        }
    }
    if (m.has("particle_velocities")) c.particle_velocities.clear();
    if (const yaml::Node pv = m.get("particle_velocities"); pv.defined()) {
        pv.expect_sequence();
        for (std::size_t i = 0; i < pv.size(); ++i) {
            const yaml::Node e = pv.at(i);
            allow(e, "particle_velocities[]");
            if (i >= kMaxLoads)
                e.fail(fmt::format("at most {} particle_velocities entries", kMaxLoads));
            ParticleVelocity v;
            v.origin = origin_of(e, fmt::format("{}particle_velocities[{}]", prefix, i));
            if (const yaml::Node g = e.get("group"); g.defined()) v.group = group_index(g, s);
            if (const yaml::Node b = e.get("box"); b.defined())
                v.box = read_box(b, "particle_velocities[].box", s.dim);
            if (!v.group && !v.box) e.fail("expected a group, a box, or both (their intersection)");
            v.velocity =
                read_components(e.require("velocity"), "particle_velocities[].velocity", s.dim);
            c.particle_velocities.push_back(std::move(v));
        }
    }
    if (m.has("loads")) c.loads.clear();
    if (const yaml::Node loads = m.get("loads"); loads.defined()) {
        loads.expect_sequence();
        for (std::size_t i = 0; i < loads.size(); ++i) {
            const yaml::Node e = loads.at(i);
            allow(e, "loads[]");
            if (i >= kMaxLoads)
                e.fail(fmt::format("at most {} loads (combine those on the same particles)",
                                   kMaxLoads));
            Load l;
            l.origin = origin_of(e, fmt::format("{}loads[{}]", prefix, i));
            const bool point = e.has("point"), traction = e.has("traction");
            if (point == traction)
                e.fail("expected exactly one of point (N per particle) or traction (Pa)");
            l.kind = point ? Load::Kind::point : Load::Kind::traction;
            const yaml::Node val = e.require(point ? "point" : "traction");
            val.expect_sequence();
            if (static_cast<int>(val.size()) != s.dim)
                val.fail(fmt::format(
                    "expected {} components, each a number or a [time, value] table", s.dim));
            for (int d = 0; d < s.dim; ++d)
                l.value[static_cast<std::size_t>(d)] =
                    read_piecewise_linear(val.at(static_cast<std::size_t>(d)));
            if (const yaml::Node g = e.get("group"); g.defined()) l.group = group_index(g, s);
            if (const yaml::Node b = e.get("box"); b.defined())
                l.box = read_box(b, "loads[].box", s.dim);
            if (!l.group && !l.box) e.fail("expected a group, a box, or both (their intersection)");
            c.loads.push_back(std::move(l));
        }
    }
}

std::vector<std::size_t> group_list(const yaml::Node &n, const Scenario &s) {
    n.expect_sequence();
    std::vector<std::size_t> out;
    for (std::size_t i = 0; i < n.size(); ++i) {
        const std::size_t g = group_index(n.at(i), s);
        if (std::find(out.begin(), out.end(), g) != out.end())
            n.at(i).fail(fmt::format("group '{}' is listed twice", s.groups[g].name));
        out.push_back(g);
    }
    return out;
}

std::size_t material_index(const yaml::Node &n, const Scenario &s) {
    const std::string name = n.as_string();
    std::vector<std::string> names;
    for (std::size_t m = 0; m < s.materials.size(); ++m) {
        if (s.materials[m].name == name) return m;
        names.push_back(s.materials[m].name);
    }
    const std::string guess = yaml::closest_match(name, std::span<const std::string>(names));
    n.fail(fmt::format("no material named '{}' under materials{}", name,
                       guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess)));
}

// A stage's end at rest: stages[].until.
Quiescence read_until(const yaml::Node &u, const std::string &prefix) {
    allow(u, "stages[].until");
    Quiescence q;
    q.origin = origin_of(u, prefix + "until");
    const yaml::Node r = u.require("kinetic_energy_ratio");
    q.kinetic_energy_ratio = r.as_double();
    if (!(q.kinetic_energy_ratio > 0.0 && q.kinetic_energy_ratio < 1.0))
        r.fail(fmt::format("expected 0 < kinetic_energy_ratio < 1 (1e-5 is usual), got {}",
                           q.kinetic_energy_ratio));
    if (const yaml::Node h = u.get("hold"); h.defined()) q.hold = positive(h, "hold (s)");
    if (const yaml::Node o = u.get("otherwise"); o.defined())
        q.stop_if_not_met = choose<bool>(o, {{"stop", true}, {"continue", false}});
    return q;
}

// What a stage resets as it begins: stages[].reset.
void read_reset(const yaml::Node &r, StageSpec &st) {
    r.expect_sequence();
    for (std::size_t i = 0; i < r.size(); ++i) {
        const bool disp = choose<bool>(r.at(i), {{"displacement", true}, {"velocity", false}});
        (disp ? st.reset_displacement : st.reset_velocity) = true;
    }
}

void read_stages(const yaml::Node &list, Scenario &s) {
    list.expect_sequence();
    if (list.size() == 0) list.fail("expected at least one stage");
    const std::size_t G = s.groups.size(), never = static_cast<std::size_t>(-1);
    // First pass over the activations: a group some stage activates is
    // absent until then.
    std::vector<std::size_t> appears(G, 0), removed(G, never), material(G);
    for (std::size_t g = 0; g < G; ++g)
        material[g] = s.groups[g].material;
    Conditions current = s.conditions;
    double total = 0.0;
    std::unordered_set<std::string> stage_names;
    for (std::size_t k = 0; k < list.size(); ++k) {
        const yaml::Node e = list.at(k);
        e.expect_map();
        allow(e, "stages[]");
        const std::string prefix = fmt::format("stages[{}].", k);
        StageSpec st;
        st.origin = origin_of(e, fmt::format("stages[{}]", k));
        const yaml::Node name = e.require("name");
        st.name = name.as_string();
        if (st.name.empty()) name.fail("expected a name (it marks the stage in the output)");
        if (!stage_names.insert(st.name).second)
            name.fail(fmt::format("stage name '{}' used twice (it marks the stage in the "
                                  "output)",
                                  st.name));
        st.duration = positive(e.require("duration"), "duration (s)");
        total += st.duration;
        if (const yaml::Node u = e.get("until"); u.defined()) st.until = read_until(u, prefix);
        read_conditions(e, prefix, s, current);
        st.conditions = current;
        const bool changes =
            e.has("activate") || e.has("remove") || e.has("set_material") || e.has("reset");
        if (k == 0 && changes)
            e.fail("the first stage starts from the groups as the file defines them: activate, "
                   "remove, set_material and reset belong to later stages (give a group its "
                   "first material under groups)");
        if (const yaml::Node a = e.get("activate"); a.defined()) {
            st.activate = group_list(a, s);
            for (std::size_t i = 0; i < st.activate.size(); ++i) {
                const std::size_t g = st.activate[i];
                if (appears[g] != 0)
                    a.at(i).fail(fmt::format("group '{}' is activated twice (first in stage "
                                             "'{}')",
                                             s.groups[g].name, s.stages[appears[g]].name));
                appears[g] = k;
            }
        }
        s.stages.push_back(std::move(st));
    }
    // Second pass, now that every group's first stage is known: removals
    // and switches act on present groups only, and so do the stage's loads
    // and fixities.
    for (std::size_t k = 0; k < list.size(); ++k) {
        const yaml::Node e = list.at(k);
        StageSpec &st = s.stages[k];
        auto present = [&](std::size_t g) { return appears[g] <= k && removed[g] > k; };
        auto absent_why = [&](std::size_t g) {
            return removed[g] <= k
                       ? fmt::format("it was removed in stage '{}'", s.stages[removed[g]].name)
                       : fmt::format("it appears in stage '{}'", s.stages[appears[g]].name);
        };
        if (const yaml::Node r = e.get("remove"); r.defined()) {
            st.remove = group_list(r, s);
            for (std::size_t i = 0; i < st.remove.size(); ++i) {
                const std::size_t g = st.remove[i];
                if (!present(g) || appears[g] == k)
                    r.at(i).fail(
                        fmt::format("group '{}' is not there to remove in stage '{}': "
                                    "{}",
                                    s.groups[g].name, st.name,
                                    appears[g] == k ? "it appears in this stage" : absent_why(g)));
            }
            for (std::size_t g : st.remove)
                removed[g] = k;
        }
        if (const yaml::Node m = e.get("set_material"); m.defined()) {
            m.expect_map();
            for (const auto &[gname, v] : m.entries()) {
                const std::size_t g = group_named(gname, v, s);
                const std::size_t to = material_index(v, s);
                if (!present(g) || appears[g] == k)
                    v.fail(fmt::format("group '{}' is not there to change in stage '{}': {}", gname,
                                       st.name,
                                       appears[g] == k ? "it appears in this stage, give it "
                                                         "its material under groups"
                                                       : absent_why(g)));
                const NamedMaterial &from = s.materials[material[g]], &mt = s.materials[to];
                if (to == material[g])
                    v.fail(fmt::format("group '{}' has material '{}' already", gname, mt.name));
                if (from.spec.density != mt.spec.density)
                    v.fail(fmt::format(
                        "material '{}' has density {:g} kg/m^3 and group '{}' has '{}' of "
                        "{:g} kg/m^3: a switch keeps the particles' mass and volume, so the "
                        "two densities must be equal",
                        mt.name, mt.spec.density, gname, from.name, from.spec.density));
                material[g] = to;
                st.set_material.push_back({g, to});
            }
        }
        if (const yaml::Node r = e.get("reset"); r.defined()) read_reset(r, st);
        bool any = false;
        for (std::size_t g = 0; g < G; ++g)
            any = any || present(g);
        if (!any) e.fail(fmt::format("no group is left in stage '{}': nothing to run", st.name));
        const std::size_t up = static_cast<std::size_t>(s.dim - 1);
        for (std::size_t g : st.activate)
            if (s.groups[g].stress.kind == InitialStress::Kind::geostatic &&
                !(st.conditions.gravity[up] < 0.0))
                e.get("activate")
                    .fail(fmt::format(
                        "group '{}' has a geostatic initial stress, which needs gravity pointing "
                        "down "
                        "the last axis when it appears; stage '{}' has {:g} m/s^2 along {}",
                        s.groups[g].name, st.name, st.conditions.gravity[up],
                        s.dim == 2 ? "y" : "z"));
        if (st.until && st.until->hold && *st.until->hold >= st.duration)
            e.get("until").get("hold").fail(fmt::format(
                "the hold time {:g} s is not shorter than the stage's duration {:g} s: the stage "
                "could never end at rest",
                *st.until->hold, st.duration));
        for (const Load &l : st.conditions.loads)
            if (l.group && !present(*l.group))
                throw Error(l.origin.error(
                    fmt::format("acts on group '{}', which is not there in stage '{}': {}",
                                s.groups[*l.group].name, st.name, absent_why(*l.group))));
        for (const ParticleVelocity &f : st.conditions.particle_velocities)
            if (f.group && !present(*f.group))
                throw Error(f.origin.error(
                    fmt::format("acts on group '{}', which is not there in stage '{}': {}",
                                s.groups[*f.group].name, st.name, absent_why(*f.group))));
    }
    s.end_time = total;
    s.end_origin = origin_of(list, "stages");
}

// The uniform grid: origin, size (whole cells) and cell size.
void read_grid(const yaml::Node &root, Scenario &s) {
    const yaml::Node grid = root.require("grid");
    allow(grid, "grid");
    s.grid_origin = origin_of(grid);
    s.origin = vec(grid.require("origin"), s.dim, "m");
    s.size = vec(grid.require("size"), s.dim, "m");
    const yaml::Node cell = grid.require("cell");
    s.cell = positive(cell, "cell (m)");
    for (int d = 0; d < s.dim; ++d) {
        const double n = s.size[static_cast<std::size_t>(d)] / s.cell;
        if (!(s.size[static_cast<std::size_t>(d)] > 0.0))
            grid.require("size").fail("expected every size > 0 (m)");
        // The grid is uniform: the size must be a whole number of cells.
        if (std::abs(n - std::round(n)) > 1e-9 * std::max(1.0, n))
            cell.fail(
                fmt::format("size {:g} in direction {} is not a whole number of cells of {:g} "
                            "({:.6g} cells)",
                            s.size[static_cast<std::size_t>(d)], "xyz"[d], s.cell, n));
        if (std::round(n) > 1e6) cell.fail("more than 1e6 cells in one direction");
    }
}

// Named constants, for the expressions of position.
void read_constants(const yaml::Node &root, Scenario &s) {
    if (const yaml::Node cs = root.get("constants"); cs.defined()) {
        cs.expect_map();
        for (const auto &[name, c] : cs.entries()) {
            if (const std::string why = SpatialField::check_constant_name(name); !why.empty())
                c.fail(why);
            s.constants.push_back({name, c.as_double()});
        }
    }
}

// Each material: its model, parameters checked by the plugin at their place.
// Each one read on its own: the errors of several are all reported, and
// the names of those that failed are kept in `failed`.
void read_materials(const yaml::Node &root, PluginRegistry &registry, Scenario &s,
                    yaml::ErrorList &errors, std::unordered_set<std::string> &failed) {
    const yaml::Node mats = root.require("materials");
    mats.expect_map();
    const auto entries = mats.entries();
    // Named copies, not structured bindings: clang 14 (Debian 12) does not
    // capture those in a lambda.
    for (const auto &entry : entries) {
        const std::string &name = entry.first;
        const yaml::Node &m = entry.second;
        const bool ok = errors.attempt([&] {
            NamedMaterial nm;
            nm.name = name;
            nm.spec = read_material(m, registry);
            nm.origin = origin_of(m);
            instantiate(nm.spec, m); // the plugin's verdict on the parameters, at their place
            s.materials.push_back(std::move(nm));
        });
        if (!ok) failed.insert(name);
    }
    if (entries.empty()) mats.fail("expected at least one material");
}

// One group: its material, shape, particles per cell and initial fields.
GroupSpec read_group(const yaml::Node &g, const std::string &name, const Scenario &s) {
    allow(g, "groups.*");
    GroupSpec gs;
    gs.name = name;
    gs.origin = origin_of(g, "groups." + name);
    const yaml::Node mat = g.require("material");
    const std::string mname = mat.as_string();
    std::vector<std::string> mnames;
    bool found = false;
    for (std::size_t i = 0; i < s.materials.size(); ++i) {
        mnames.push_back(s.materials[i].name);
        if (s.materials[i].name == mname) {
            gs.material = i;
            found = true;
        }
    }
    if (!found) {
        const std::string guess = yaml::closest_match(mname, std::span<const std::string>(mnames));
        mat.fail(fmt::format("no material named '{}' under materials{}", mname,
                             guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess)));
    }
    gs.shape = read_shape(g.require("shape"), s.dim);
    gs.shape_origin = origin_of(g.require("shape"), "groups." + name + ".shape");
    if (const yaml::Node ppc = g.get("particles_per_cell"); ppc.defined()) {
        const long long n = ppc.as_integer();
        if (n < 1 || n > 16)
            ppc.fail(fmt::format("expected 1 <= particles_per_cell <= 16, got {}", n));
        gs.particles_per_cell = static_cast<int>(n);
    }
    if (const yaml::Node v = g.get("velocity"); v.defined()) {
        gs.velocity = read_velocity(v, s);
        gs.velocity_origin = origin_of(v, "groups." + name + ".velocity");
    }
    if (const yaml::Node w = g.get("angular_velocity"); w.defined()) {
        if (s.dim == 2)
            gs.angular_velocity = {0.0, 0.0, w.as_double()};
        else
            gs.angular_velocity = vec(w, 3, "rad/s");
        // The fastest point of the rigid rotation: |w| times the largest
        // distance from the centre of the shape's bounding box.
        const Box bb = gs.shape.bounds(s.dim);
        double r2 = 0.0;
        for (int d = 0; d < s.dim; ++d)
            r2 += std::pow(
                0.5 * (bb.max[static_cast<std::size_t>(d)] - bb.min[static_cast<std::size_t>(d)]),
                2);
        const Vec3 &wv = gs.angular_velocity;
        const double wn = std::sqrt(wv[0] * wv[0] + wv[1] * wv[1] + wv[2] * wv[2]);
        check_speed(w, {wn * std::sqrt(r2), 0.0, 0.0});
    }
    if (const yaml::Node st = g.get("initial_stress"); st.defined()) {
        gs.stress = read_initial_stress(st, s);
        gs.stress_origin = origin_of(st, "groups." + name + ".initial_stress");
    }
    if (const yaml::Node st = g.get("initial_state"); st.defined()) {
        gs.initial_state = read_group_state(st, s, s.materials[gs.material]);
        gs.state_origin = origin_of(st, "groups." + name + ".initial_state");
    }
    return gs;
}

// Each one read on its own, as the materials; a group of a material that
// failed says nothing more (its material's error is the one to fix).
// Returns whether every group was read.
bool read_groups(const yaml::Node &root, Scenario &s, yaml::ErrorList &errors,
                 const std::unordered_set<std::string> &failed_materials) {
    const yaml::Node groups = root.require("groups");
    groups.expect_map();
    const auto entries = groups.entries();
    bool all = true;
    for (const auto &entry : entries) {
        const std::string &name = entry.first;
        const yaml::Node &group = entry.second;
        const yaml::Node mat = group.is_map() ? group.get("material") : yaml::Node(group);
        if (mat.defined() && mat.is_scalar() && failed_materials.count(mat.as_string())) {
            all = false;
            continue;
        }
        all &= errors.attempt([&] { s.groups.push_back(read_group(group, name, s)); });
    }
    if (entries.empty()) groups.fail("expected at least one group");
    return all;
}

// The scheme, transfer, shape function, time step and rank balance.
void read_solver(const yaml::Node &root, Scenario &s) {
    if (const yaml::Node sv = root.get("solver"); sv.defined()) {
        allow(sv, "solver");
        SolverSpec &p = s.solver;
        if (const yaml::Node n = sv.get("scheme"); n.defined())
            p.scheme = choose<Scheme>(n, {{"usl", Scheme::usl},
                                          {"usf", Scheme::usf},
                                          {"musl", Scheme::musl},
                                          {"usavg", Scheme::usavg}});
        if (const yaml::Node n = sv.get("transfer"); n.defined()) {
            const std::vector<std::pair<std::string_view, Transfer>> kinds = {
                {"flip", Transfer::flip},
                {"pic", Transfer::flip},
                {"apic", Transfer::apic},
                {"tpic", Transfer::tpic}};
            if (n.is_map()) {
                allow(n, "solver.transfer");
                const yaml::Node t = n.require("type");
                p.transfer = choose<Transfer>(t, kinds);
                if (t.as_string() == "pic") p.alpha = 0.0;
                if (const yaml::Node a = n.get("alpha"); a.defined()) {
                    if (t.as_string() == "pic")
                        a.fail("pic is the blend with alpha = 0; for a FLIP/PIC blend write "
                               "{type: flip, alpha: A}");
                    if (p.transfer != Transfer::flip)
                        a.fail("alpha applies to the flip transfer only");
                    p.alpha = a.as_double();
                    if (!(p.alpha >= 0.0 && p.alpha <= 1.0))
                        a.fail(fmt::format("expected 0 <= alpha <= 1 (0: PIC, 1: FLIP), got {:g}",
                                           p.alpha));
                }
            } else {
                p.transfer = choose<Transfer>(n, kinds);
                if (n.as_string() == "pic") p.alpha = 0.0;
            }
        }
        if (const yaml::Node n = sv.get("shape"); n.defined())
            p.shape = choose<ShapeKind>(n, {{"linear", ShapeKind::linear},
                                            {"gimp", ShapeKind::gimp},
                                            {"bspline2", ShapeKind::bspline2},
                                            {"bspline3", ShapeKind::bspline3}});
        if (const yaml::Node n = sv.get("cfl"); n.defined()) {
            p.cfl = n.as_double();
            if (!(p.cfl > 0.0 && p.cfl <= 1.0))
                n.fail(fmt::format("expected 0 < cfl <= 1, got {:g}", p.cfl));
        }
        if (const yaml::Node n = sv.get("dt"); n.defined()) {
            p.dt = positive(n, "dt (s)");
            p.dt_origin = origin_of(n);
        }
        // The particles move with the grid velocity field whose gradient
        // advanced F in the step (docs/theory.md, "Kinematic consistency"):
        // USF has only the start field when it updates the stress, USAVG
        // uses both halves, so each has one position update (the solver
        // applies it whatever this flag says).
        if (const yaml::Node n = sv.get("position_update"); n.defined()) {
            p.second_order_position =
                choose<bool>(n, {{"first_order", false}, {"second_order", true}});
            if (p.scheme == Scheme::usf && p.second_order_position)
                n.fail("usf updates the stress from the start-of-step grid velocities, before the "
                       "forces are known, and moves the particles with the same velocities, so "
                       "its position update is first_order; second_order needs usl, musl or "
                       "usavg");
            if (p.scheme == Scheme::usavg && !p.second_order_position)
                n.fail("usavg advances the deformation half with the start and half with the "
                       "updated grid velocities, and moves the particles with their mean, so its "
                       "position update is second_order; first_order needs usl, musl or usf");
        }
        if (const yaml::Node n = sv.get("cell_averaged_dilation"); n.defined())
            p.cell_averaged_dilation = n.as_bool();
        if (const yaml::Node n = sv.get("leaving_grid"); n.defined())
            p.leave = choose<LeavePolicy>(
                n, {{"stop", LeavePolicy::stop}, {"remove", LeavePolicy::remove}});
        if (const yaml::Node lb = sv.get("load_balance"); lb.defined()) {
            allow(lb, "solver.load_balance");
            if (const yaml::Node n = lb.get("imbalance"); n.defined()) {
                p.rebalance_imbalance = n.as_double();
                if (!(p.rebalance_imbalance >= 1.0))
                    n.fail(fmt::format("expected imbalance >= 1 (the most particles on a rank "
                                       "over the mean), got {:g}",
                                       p.rebalance_imbalance));
            }
            if (const yaml::Node n = lb.get("every"); n.defined()) {
                const long long every = n.as_integer();
                if (every < 1 || every > 1000000000)
                    n.fail(
                        fmt::format("expected every >= 1 (steps between checks), got {}", every));
                p.rebalance_every = static_cast<int>(every);
            }
        }
    }
}

// The run's end: time.end, or the stages' durations.
void read_time(const yaml::Node &root, Scenario &s) {
    if (const yaml::Node st = root.get("stages"); st.defined()) {
        if (const yaml::Node time = root.get("time"); time.defined())
            time.fail("with stages, each stage gives its duration and the run ends with the last "
                      "one; remove time");
        read_stages(st, s);
    } else {
        const yaml::Node time = root.require("time");
        allow(time, "time");
        s.end_time = positive(time.require("end"), "end (s)");
        s.end_origin = origin_of(time.require("end"));
    }
}

void read_checkpoint(const yaml::Node &root, Scenario &s) {
    if (const yaml::Node ck = root.get("checkpoint"); ck.defined()) {
        allow(ck, "checkpoint");
        CheckpointSpec &c = s.checkpoint;
        if (const yaml::Node n = ck.get("every"); n.defined()) {
            c.every = positive(n, "every (s)");
            c.every_origin = origin_of(n);
        }
        if (const yaml::Node n = ck.get("steps"); n.defined()) {
            c.steps = n.as_integer();
            if (*c.steps < 1) n.fail(fmt::format("expected steps >= 1, got {}", *c.steps));
        }
        if (const yaml::Node n = ck.get("wall"); n.defined()) c.wall = positive(n, "wall (s)");
        if (!c.every && !c.steps && !c.wall)
            ck.fail("expected at least one of every (s of simulated time), steps, wall (s of "
                    "wall-clock time)");
        if (const yaml::Node n = ck.get("keep"); n.defined()) {
            const long long k = n.as_integer();
            if (k < 1 || k > 1000) n.fail(fmt::format("expected 1 <= keep <= 1000, got {}", k));
            c.keep = static_cast<int>(k);
        }
    }
}

// The state variables written to the VTK output.
void read_output_state(const yaml::Node &st, Scenario &s) {
    st.expect_sequence();
    s.output.all_flagged_state = false;
    for (std::size_t i = 0; i < st.size(); ++i) {
        const yaml::Node e = st.at(i);
        const std::string name = e.as_string();
        std::vector<std::string> known;
        for (const auto &m : s.materials)
            for (const auto &v : m.spec.state.vars)
                known.push_back(v.name);
        if (std::find(known.begin(), known.end(), name) == known.end()) {
            const std::string guess =
                yaml::closest_match(name, std::span<const std::string>(known));
            e.fail(fmt::format("no material of this scenario has a state variable '{}'{}", name,
                               guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess)));
        }
        s.output.state_fields.push_back(name);
    }
}

void read_probes(const yaml::Node &pr, Scenario &s) {
    pr.expect_sequence();
    std::unordered_set<std::string> probe_names;
    for (std::size_t i = 0; i < pr.size(); ++i) {
        const yaml::Node e = pr.at(i);
        allow(e, "output.probes[]");
        Probe p;
        p.name = e.require("name").as_string();
        p.origin = origin_of(e, fmt::format("output.probes[{}]", i));
        const bool part = e.has("particle"), com = e.has("centre_of_mass");
        if (part == com)
            e.fail("expected exactly one of particle: [x, y(, z)] or centre_of_mass: group");
        if (part) {
            p.kind = Probe::Kind::particle;
            p.point = vec(e.require("particle"), s.dim, "m");
        } else {
            p.kind = Probe::Kind::centre_of_mass;
            p.group = group_index(e.require("centre_of_mass"), s);
        }
        if (!probe_names.insert(p.name).second)
            e.require("name").fail(fmt::format("probe name '{}' used twice", p.name));
        s.output.probes.push_back(std::move(p));
    }
}

void read_output(const yaml::Node &root, Scenario &s) {
    if (const yaml::Node out = root.get("output"); out.defined()) {
        allow(out, "output");
        if (const yaml::Node n = out.get("every"); n.defined()) {
            s.output.every = positive(n, "every (s)");
            s.output.every_origin = origin_of(n);
        }
        if (const yaml::Node n = out.get("vtk"); n.defined()) s.output.vtk = n.as_bool();
        if (const yaml::Node st = out.get("state"); st.defined()) read_output_state(st, s);
        if (const yaml::Node pr = out.get("probes"); pr.defined()) read_probes(pr, s);
    }
}

} // namespace

std::vector<std::string> scenario_schema() {
    std::vector<std::string> out;
    for (const auto &[path, ks] : schema())
        for (auto k : ks)
            out.push_back(path.empty() ? std::string(k) : std::string(path) + "." + std::string(k));
    return out;
}

Scenario read_scenario(const yaml::Node &root, PluginRegistry &registry) {
    Scenario s;
    s.file = root.file();
    allow(root, "");
    const yaml::Node version = root.require("talus");
    if (version.as_integer() != 1)
        version.fail(fmt::format("unsupported file format version {}; this talus reads version 1",
                                 version.as_integer()));
    const yaml::Node dim = root.require("dimension");
    s.dim = static_cast<int>(dim.as_integer());
    if (s.dim != 2 && s.dim != 3)
        dim.fail(fmt::format("expected 2 (plane strain) or 3, got {}", s.dim));

    // The parts read on their own, every error kept (ErrorList); a part
    // is not read where one it depends on failed: the groups need the
    // grid, the constants and their materials; the boundaries and loads,
    // the stages and the outputs name groups and materials.
    yaml::ErrorList errors;
    bool plugins_ok = true;
    if (const yaml::Node plugins = root.get("plugins"); plugins.defined())
        plugins_ok = errors.attempt([&] { load_plugin_list(plugins, registry); });
    const bool grid_ok = errors.attempt([&] { read_grid(root, s); });
    const bool constants_ok = errors.attempt([&] { read_constants(root, s); });
    std::unordered_set<std::string> failed_materials;
    bool parts_ok = false;
    // The block itself (missing, not a mapping, empty): no group can name
    // a material then.
    const bool materials_ok = plugins_ok && errors.attempt([&] {
        read_materials(root, registry, s, errors, failed_materials);
    });
    if (materials_ok && grid_ok && constants_ok)
        errors.attempt([&] {
            parts_ok = read_groups(root, s, errors, failed_materials) && failed_materials.empty();
        });
    parts_ok = parts_ok && errors.empty();
    bool conditions_ok = false;
    if (parts_ok)
        conditions_ok = errors.attempt([&] { read_conditions(root, "", s, s.conditions); });
    errors.attempt([&] { read_solver(root, s); });
    if (conditions_ok) errors.attempt([&] { read_time(root, s); });
    errors.attempt([&] { read_checkpoint(root, s); });
    if (parts_ok) errors.attempt([&] { read_output(root, s); });
    errors.throw_if_any();
    return s;
}

// ------------------------------------------------------------- geometry --

} // namespace talus
