// The checks of a plugin's descriptors as the loader reads them (the
// library's, each model's, its parameters' and state variables'): a field
// that breaks the ABI's rules (material_abi.h) is refused with the file and
// the field. Internal to the material layer.
#pragma once

#include <talus/error.hpp>
#include <talus/material/plugin_loader.hpp>
#include <talus/text.hpp>

#include <fmt/format.h>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <set>
#include <string>
#include <string_view>

namespace talus {

struct DescriptorChecker {
    // The most values a list parameter may require (material_abi.h).
    static constexpr std::uint32_t kMaxListMinCount = 65536;
    // Keys the host owns in a material's YAML; a plugin cannot take them.
    static constexpr std::string_view kReservedKeys[] = {"model", "density", "initial_state"};

    const std::filesystem::path &file;

    static bool snake_case(const char *s) { return s && is_snake_identifier(s); }

    [[noreturn]] void bad(const std::string &where, const std::string &what) const {
        throw Error(
            fmt::format("{}: invalid plugin descriptor: {}: {}", file.string(), where, what));
    }
    void need_string(const char *s, const std::string &where, const char *field) const {
        if (!s) bad(where, fmt::format("field '{}' is null", field));
    }
    // `need`: the structure's size in ABI 1.0 (the offset of its first 1.1
    // field); the 1.1 fields are read only when struct_size holds them.
    void need_size(std::uint32_t have, std::size_t need, const std::string &where) const {
        if (have < need)
            bad(where, fmt::format("struct_size {} is smaller than the {} bytes of ABI {}.0", have,
                                   need, TALUS_ABI_VERSION_MAJOR));
    }

    ParamInfo param(const talus_param_desc *d, const std::string &where, bool typed_create) const {
        if (!d) bad(where, "null pointer in the params array");
        need_size(d->struct_size, offsetof(talus_param_desc, min_count), where);
        if (!snake_case(d->key))
            bad(where, fmt::format("field 'key' must be lower_snake_case, got '{}'",
                                   d->key ? d->key : "(null)"));
        for (auto r : kReservedKeys)
            if (r == d->key)
                bad(where, fmt::format("field 'key': '{}' is reserved for the host", d->key));
        need_string(d->unit, where, "unit");
        need_string(d->doc, where, "doc");
        if (d->type > TALUS_PARAM_STRING)
            bad(where, fmt::format("field 'type': unknown type {}", d->type));
        const bool typed = d->type > TALUS_PARAM_BOOLEAN;
        if (typed && !TALUS_HAS_FIELD(talus_param_desc, d, typical_string))
            bad(where, fmt::format("type {} is ABI 1.1 but the descriptor is a 1.0 one "
                                   "(struct_size {})",
                                   d->type, d->struct_size));
        if (typed && !typed_create)
            bad(where, "a list or string parameter needs the model's create_ex (ABI 1.1)");
        constexpr std::uint32_t known =
            TALUS_PARAM_REQUIRED | TALUS_PARAM_MIN_EXCLUSIVE | TALUS_PARAM_MAX_EXCLUSIVE;
        if (d->flags & ~known)
            bad(where, fmt::format("field 'flags': unknown bits 0x{:x}", d->flags & ~known));
        if (std::isnan(d->min_value) || std::isnan(d->max_value) || d->min_value > d->max_value)
            bad(where,
                fmt::format("fields 'min_value' ({}) and 'max_value' ({}) are not an interval",
                            d->min_value, d->max_value));
        ParamInfo p;
        p.key = d->key;
        p.unit = d->unit;
        p.doc = d->doc;
        p.type = d->type;
        p.flags = d->flags;
        p.default_value = d->default_value;
        p.min_value = d->min_value;
        p.max_value = d->max_value;
        p.typical_value = d->typical_value;
        if (typed) {
            p.min_count = d->min_count;
            p.max_count = d->max_count;
            if (d->default_string) p.default_string = d->default_string;
            p.has_typical_string = d->typical_string != nullptr;
            if (d->typical_string) p.typical_string = d->typical_string;
        }
        if (p.type == TALUS_PARAM_REAL_ARRAY) {
            // The host builds the typical list (min_count copies) for the
            // conformance checks and the documentation: a count in the
            // billions would take the machine's memory (found by the
            // descriptor fuzzer).
            if (p.min_count > kMaxListMinCount)
                bad(where, fmt::format("field 'min_count' ({}) is above the {} values a list "
                                       "parameter may require",
                                       p.min_count, kMaxListMinCount));
            if (p.max_count > 0 && p.min_count > p.max_count)
                bad(where, fmt::format("fields 'min_count' ({}) and 'max_count' ({}) are not an "
                                       "interval",
                                       p.min_count, p.max_count));
            if (!p.required() && p.min_count > 0)
                bad(where, fmt::format("an optional list defaults to the empty list, so "
                                       "'min_count' must be 0, got {}",
                                       p.min_count));
        }
        if (p.type == TALUS_PARAM_STRING) return p;
        if (!p.required() && p.scalar()) {
            const std::string why = check_parameter(p, d->default_value);
            if (!why.empty())
                bad(where, fmt::format("field 'default_value' ({}) is invalid: {}",
                                       d->default_value, why));
        }
        const std::string why = check_parameter(p, d->typical_value);
        if (!why.empty())
            bad(where,
                fmt::format("field 'typical_value' ({}) is invalid: {}", d->typical_value, why));
        return p;
    }

    // The variables of a layout, with their offsets; duplicates refused.
    StateLayout layout(const talus_state_desc *const *vars, std::uint32_t n,
                       const std::string &where) const {
        if (n > 0 && !vars) bad(where, "the state array is null");
        StateLayout out;
        std::set<std::string> names;
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::string sw = fmt::format("{} state variable #{}", where, i);
            StateInfo s = state(vars[i], sw);
            if (!names.insert(s.name).second)
                bad(sw, fmt::format("name '{}' appears twice", s.name));
            s.offset = out.size;
            out.size += s.size;
            out.vars.push_back(std::move(s));
        }
        return out;
    }

    StateInfo state(const talus_state_desc *d, const std::string &where) const {
        if (!d) bad(where, "null pointer in the state array");
        need_size(d->struct_size, sizeof(talus_state_desc), where);
        if (!snake_case(d->name))
            bad(where, fmt::format("field 'name' must be lower_snake_case, got '{}'",
                                   d->name ? d->name : "(null)"));
        need_string(d->unit, where, "unit");
        need_string(d->doc, where, "doc");
        if (d->size == 0 || d->size > 81)
            bad(where, fmt::format("field 'size' is {}, expected 1..81", d->size));
        constexpr std::uint32_t known = TALUS_STATE_OUTPUT | TALUS_STATE_USER_INIT;
        if (d->flags & ~known)
            bad(where, fmt::format("field 'flags': unknown bits 0x{:x}", d->flags & ~known));
        if (!std::isfinite(d->initial_value))
            bad(where, fmt::format("field 'initial_value' is not finite ({})", d->initial_value));
        return StateInfo{d->name, d->unit, d->doc, d->size, d->flags, d->initial_value, 0};
    }
};

} // namespace talus
