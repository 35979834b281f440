#include <talus/io/provenance.hpp>

#include <talus/material_abi.h>

#include <fmt/format.h>

#include <chrono>
#include <ctime>
#include <filesystem>

#ifndef TALUS_VERSION_STRING
#define TALUS_VERSION_STRING "0.0.0"
#endif

namespace talus {

namespace {

std::string json_string(const std::string &s) {
    std::string out = "\"";
    for (const char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\r': out += "\\r"; break;
        case '\t': out += "\\t"; break;
        default:
            if (c < 0x20)
                out += fmt::format("\\u{:04x}", c);
            else
                out += ch;
        }
    }
    return out + "\"";
}

std::string file_sha256(const std::string &file) {
    const std::string h = sha256_file(file);
    return h.empty() ? "unreadable" : h;
}

// The parameter's value as JSON.
std::string json_value(const ParamInfo &p, const ParamValue &v) {
    switch (p.type) {
    case TALUS_PARAM_BOOLEAN: return v.scalar != 0.0 ? "true" : "false";
    case TALUS_PARAM_STRING: return json_string(v.text);
    case TALUS_PARAM_REAL_ARRAY: {
        std::string s = "[";
        for (std::size_t i = 0; i < v.reals.size(); ++i)
            s += fmt::format("{}{}", i ? ", " : "", v.reals[i]);
        return s + "]";
    }
    default: return fmt::format("{}", v.scalar);
    }
}

} // namespace

std::string utc_now() {
    const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

namespace {
// The input as an absolute path: the record must stay meaningful when read
// from another working directory.
std::string absolute_input(const Provenance &p) {
    std::error_code ec;
    const std::filesystem::path abs = std::filesystem::absolute(p.input_file, ec);
    return ec ? p.input_file : abs.lexically_normal().string();
}
} // namespace

std::string provenance_json(const Provenance &p) {
    std::string j = "{\n";
    j += fmt::format("  \"talus_version\": {},\n", json_string(TALUS_VERSION_STRING));
    j += fmt::format("  \"material_abi\": \"{}.{}\",\n", TALUS_ABI_VERSION_MAJOR,
                     TALUS_ABI_VERSION_MINOR);
    j += fmt::format("  \"command\": {},\n", json_string(p.command));
    if (!p.run_id.empty()) j += fmt::format("  \"run_id\": {},\n", json_string(p.run_id));
    j += fmt::format("  \"created_utc\": {},\n", json_string(utc_now()));
    j += fmt::format(
        "  \"input\": {{\"file\": {}, \"sha256\": {}}},\n", json_string(absolute_input(p)),
        json_string(p.input_sha256.empty() ? file_sha256(p.input_file) : p.input_sha256));
    j += "  \"materials\": [";
    for (std::size_t i = 0; i < p.materials.size(); ++i) {
        const MaterialSpec &s = *p.materials[i].spec;
        const Model &m = *s.model;
        const PluginLibrary &lib = m.library();
        j += i ? ",\n" : "\n";
        j += fmt::format("    {{\"name\": {}, \"model\": {}, \"model_version\": {}, \"density\": "
                         "{},\n",
                         json_string(p.materials[i].name), json_string(m.qualified_id()),
                         json_string(m.version()), s.density);
        j += "     \"parameters\": {";
        for (std::size_t k = 0; k < m.params().size(); ++k)
            j += fmt::format("{}{}: {}", k ? ", " : "", json_string(m.params()[k].key),
                             json_value(m.params()[k], s.params[k]));
        j += "},\n";
        j += fmt::format("     \"library\": {{\"name\": {}, \"version\": {}, \"abi\": \"{}.{}\", "
                         "\"path\": {}, \"sha256\": {}, \"build\": {}}}}}",
                         json_string(lib.name()), json_string(lib.version()), lib.abi_major(),
                         lib.abi_minor(), json_string(lib.path().string()),
                         json_string(lib.content_hash()), json_string(lib.build_text()));
    }
    j += p.materials.empty() ? "]\n}\n" : "\n  ]\n}\n";
    return j;
}

std::string provenance_comments(const Provenance &p) {
    std::string c;
    c += fmt::format("# talus {} (material ABI {}.{}), talus {} {}, {}\n", TALUS_VERSION_STRING,
                     TALUS_ABI_VERSION_MAJOR, TALUS_ABI_VERSION_MINOR, p.command, absolute_input(p),
                     utc_now());
    c += fmt::format("# input sha256 {}\n", file_sha256(p.input_file));
    for (const ProvenanceMaterial &pm : p.materials) {
        const MaterialSpec &s = *pm.spec;
        const Model &m = *s.model;
        const PluginLibrary &lib = m.library();
        std::string params;
        for (std::size_t k = 0; k < m.params().size(); ++k)
            params += fmt::format("{}{}={}", k ? ", " : "", m.params()[k].key,
                                  m.params()[k].value_text(s.params[k]));
        c += fmt::format("# material {}: {} {}, density {:g}; {}\n", pm.name, m.qualified_id(),
                         m.version(), s.density, params);
        c += fmt::format("# plugin {} {} (ABI {}.{}, {}) {} sha256 {}\n", lib.name(), lib.version(),
                         lib.abi_major(), lib.abi_minor(), lib.build_text(), lib.path().string(),
                         lib.content_hash());
    }
    return c;
}

} // namespace talus
