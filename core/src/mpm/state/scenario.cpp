#include <talus/mpm/scenario.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace talus {

bool GroupShape::contains(const double *x, int dim) const {
    switch (kind) {
    case Kind::box: return box.contains(x, dim);
    case Kind::sphere: {
        double r2 = 0.0;
        for (int d = 0; d < dim; ++d)
            r2 += (x[d] - center[static_cast<std::size_t>(d)]) *
                  (x[d] - center[static_cast<std::size_t>(d)]);
        return r2 <= radius * radius;
    }
    case Kind::cylinder: {
        double r2 = 0.0;
        for (int d = 0; d < 3; ++d)
            if (d != axis)
                r2 += (x[d] - center[static_cast<std::size_t>(d)]) *
                      (x[d] - center[static_cast<std::size_t>(d)]);
        return r2 <= radius * radius && x[axis] >= zmin && x[axis] <= zmax;
    }
    case Kind::polygon: {
        // Even-odd rule by ray casting along +x.
        bool inside = false;
        const std::size_t n = polygon.size();
        for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
            const auto &a = polygon[i], &b = polygon[j];
            if ((a[1] > x[1]) != (b[1] > x[1]) &&
                x[0] < (b[0] - a[0]) * (x[1] - a[1]) / (b[1] - a[1]) + a[0])
                inside = !inside;
        }
        return inside;
    }
    }
    return false;
}

Box GroupShape::bounds(int dim) const {
    Box b;
    switch (kind) {
    case Kind::box: return box;
    case Kind::sphere:
        for (int d = 0; d < dim; ++d) {
            b.min[static_cast<std::size_t>(d)] = center[static_cast<std::size_t>(d)] - radius;
            b.max[static_cast<std::size_t>(d)] = center[static_cast<std::size_t>(d)] + radius;
        }
        return b;
    case Kind::cylinder:
        for (int d = 0; d < 3; ++d) {
            const std::size_t k = static_cast<std::size_t>(d);
            b.min[k] = d == axis ? zmin : center[k] - radius;
            b.max[k] = d == axis ? zmax : center[k] + radius;
        }
        return b;
    case Kind::polygon:
        b.min = {polygon[0][0], polygon[0][1], 0};
        b.max = b.min;
        for (const auto &p : polygon)
            for (std::size_t d = 0; d < 2; ++d) {
                b.min[d] = std::min(b.min[d], p[d]);
                b.max[d] = std::max(b.max[d], p[d]);
            }
        return b;
    }
    return b;
}

double GroupShape::measure(int dim) const {
    constexpr double pi = 3.14159265358979323846;
    switch (kind) {
    case Kind::box: {
        double m = 1.0;
        for (int d = 0; d < dim; ++d)
            m *= box.max[static_cast<std::size_t>(d)] - box.min[static_cast<std::size_t>(d)];
        return m;
    }
    case Kind::sphere:
        return dim == 2 ? pi * radius * radius : 4.0 / 3.0 * pi * std::pow(radius, 3);
    case Kind::cylinder: return pi * radius * radius * (zmax - zmin);
    case Kind::polygon: { // shoelace formula
        double a = 0.0;
        for (std::size_t i = 0; i < polygon.size(); ++i) {
            const auto &p = polygon[i], &q = polygon[(i + 1) % polygon.size()];
            a += p[0] * q[1] - q[0] * p[1];
        }
        return 0.5 * std::abs(a);
    }
    }
    return 0.0;
}

std::string Origin::error(std::string_view what) const {
    if (where.empty()) return fmt::format("error: {}", what);
    return fmt::format("{}: error: '{}' {}", where, key, what);
}

std::string Origin::warning(std::string_view what) const {
    if (where.empty()) return fmt::format("warning: {}", what);
    return fmt::format("{}: warning: '{}' {}", where, key, what);
}

std::string Origin::note(std::string_view what) const {
    if (where.empty()) return fmt::format("note: {}", what);
    return fmt::format("{}: note: '{}' {}", where, key, what);
}

std::vector<StageSpec> stages_of(const Scenario &sc) {
    if (!sc.stages.empty()) return sc.stages;
    StageSpec only;
    only.duration = sc.end_time;
    only.conditions = sc.conditions;
    only.origin = sc.end_origin;
    return {only};
}

std::vector<std::size_t> materials_in_use(const Scenario &sc) {
    std::vector<std::size_t> used;
    auto use = [&](std::size_t m) {
        if (std::find(used.begin(), used.end(), m) == used.end()) used.push_back(m);
    };
    for (const GroupSpec &g : sc.groups)
        use(g.material);
    for (const StageSpec &st : sc.stages)
        for (const MaterialSwitch &sw : st.set_material)
            use(sw.material);
    return used;
}

std::vector<std::size_t> first_stage_of_groups(const Scenario &sc) {
    std::vector<std::size_t> first(sc.groups.size(), 0);
    for (std::size_t k = 1; k < sc.stages.size(); ++k)
        for (std::size_t g : sc.stages[k].activate)
            first[g] = k;
    return first;
}

} // namespace talus
