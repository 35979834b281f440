// What a plugin declares of its parameters and state, as the host keeps
// it: ParamInfo (a parameter's bounds, its checks, its typical value) and
// StateLayout (the state variables and their offsets).
#include <talus/material/plugin_loader.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace talus {

bool ParamInfo::in_bounds(double v) const {
    const bool lo = (flags & TALUS_PARAM_MIN_EXCLUSIVE) ? v > min_value : v >= min_value;
    const bool hi = (flags & TALUS_PARAM_MAX_EXCLUSIVE) ? v < max_value : v <= max_value;
    return lo && hi;
}

std::string ParamInfo::bounds_text() const {
    const bool has_lo = std::isfinite(min_value);
    const bool has_hi = std::isfinite(max_value);
    const char *lo_op = (flags & TALUS_PARAM_MIN_EXCLUSIVE) ? "<" : "<=";
    const char *hi_op = (flags & TALUS_PARAM_MAX_EXCLUSIVE) ? "<" : "<=";
    if (type == TALUS_PARAM_BOOLEAN) return "true or false";
    if (has_lo && has_hi)
        return fmt::format("{:g} {} {} {} {:g}", min_value, lo_op, key, hi_op, max_value);
    if (has_lo)
        return fmt::format("{} {} {:g}", key,
                           (flags & TALUS_PARAM_MIN_EXCLUSIVE) ? ">" : ">=", min_value);
    if (has_hi) return fmt::format("{} {} {:g}", key, hi_op, max_value);
    return "any finite value";
}

std::string ParamInfo::count_text() const {
    auto values = [](std::uint32_t n) { return fmt::format("{} value{}", n, n == 1 ? "" : "s"); };
    if (max_count == 0)
        return min_count == 0 ? "any number of values" : "at least " + values(min_count);
    if (min_count == max_count) return "exactly " + values(min_count);
    return fmt::format("{} to {} values", min_count, max_count);
}

const char *ParamInfo::type_name() const {
    switch (type) {
    case TALUS_PARAM_INTEGER: return "integer";
    case TALUS_PARAM_BOOLEAN: return "boolean";
    case TALUS_PARAM_REAL_ARRAY: return "list of reals";
    case TALUS_PARAM_STRING: return "string";
    default: return "real";
    }
}

ParamValue ParamInfo::default_param() const {
    ParamValue v;
    v.scalar = default_value;
    v.text = default_string;
    return v; // an array's default is the empty list
}

ParamValue ParamInfo::typical_param() const {
    ParamValue v;
    v.scalar = typical_value;
    // A required list: max(min_count, 1) copies of typical_value; an
    // optional one: its default, the empty list (material_abi.h).
    if (type == TALUS_PARAM_REAL_ARRAY && required())
        v.reals.assign(std::max<std::uint32_t>(min_count, 1), typical_value);
    v.text = has_typical_string ? typical_string : default_string;
    return v;
}

std::string ParamInfo::value_text(const ParamValue &v) const {
    switch (type) {
    case TALUS_PARAM_BOOLEAN: return v.scalar != 0.0 ? "true" : "false";
    case TALUS_PARAM_REAL_ARRAY: return fmt::format("[{:g}]", fmt::join(v.reals, ", "));
    case TALUS_PARAM_STRING: return fmt::format("\"{}\"", v.text);
    default: return fmt::format("{:g}", v.scalar);
    }
}

std::string check_parameter(const ParamInfo &p, double v) {
    if (!std::isfinite(v)) return "expected a finite number";
    if (p.type == TALUS_PARAM_INTEGER && v != std::floor(v)) return "expected an integer";
    if (p.type == TALUS_PARAM_BOOLEAN && v != 0.0 && v != 1.0) return "expected true or false";
    if (!p.in_bounds(v)) return fmt::format("expected {} (unit {})", p.bounds_text(), p.unit);
    return {};
}

std::string check_parameter(const ParamInfo &p, const ParamValue &v) {
    if (p.scalar()) return check_parameter(p, v.scalar);
    if (p.type == TALUS_PARAM_STRING) {
        if (p.required() && v.text.empty()) return "expected a non-empty string";
        return {};
    }
    const auto n = v.reals.size();
    if (n < p.min_count || (p.max_count > 0 && n > p.max_count))
        return fmt::format("expected {}, got {}", p.count_text(), n);
    for (std::size_t i = 0; i < n; ++i) {
        const std::string why = check_parameter(p, v.reals[i]);
        if (!why.empty()) return fmt::format("value #{} ({:g}): {}", i + 1, v.reals[i], why);
    }
    return {};
}

std::vector<double> StateLayout::initial() const {
    std::vector<double> s(size);
    for (const StateInfo &v : vars)
        std::fill_n(s.begin() + v.offset, v.size, v.initial_value);
    return s;
}

} // namespace talus
