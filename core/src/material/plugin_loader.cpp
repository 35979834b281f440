#include <talus/material/plugin_loader.hpp>

#include <talus/material/crash_report.hpp>
#include <talus/text.hpp>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <dlfcn.h>
#include <openssl/evp.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>

#ifndef TALUS_VERSION_STRING
#define TALUS_VERSION_STRING "0.0.0"
#endif

namespace fs = std::filesystem;

namespace talus {

const char *host_name() { return "talus " TALUS_VERSION_STRING; }

// ------------------------------------------------------------ ParamInfo --

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

// ---------------------------------------------------------- StateLayout --

std::vector<double> StateLayout::initial() const {
    std::vector<double> s(size);
    for (const StateInfo &v : vars)
        std::fill_n(s.begin() + v.offset, v.size, v.initial_value);
    return s;
}

// ----------------------------------------------------- descriptor checks --
namespace {

bool is_snake_identifier(const char *s) { return s && talus::is_snake_identifier(s); }

// The most values a list parameter may require (material_abi.h).
constexpr std::uint32_t kMaxListMinCount = 65536;

// Keys the host owns in a material's YAML; a plugin cannot take them.
constexpr std::string_view kReservedKeys[] = {"model", "density", "initial_state"};

struct DescriptorChecker {
    const fs::path &file;

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
        if (!is_snake_identifier(d->key))
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
        if (!is_snake_identifier(d->name))
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

std::string read_message(const talus_error &e) {
    // The plugin may have filled the whole buffer without a NUL.
    return std::string(e.message, strnlen(e.message, sizeof(e.message)));
}

talus_error fresh_error() {
    talus_error e{};
    e.struct_size = sizeof(talus_error);
    e.point_index = -1;
    e.cut_factor = 1.0;
    return e;
}

} // namespace

// -------------------------------------------------------- PluginLibrary --

namespace {

// The SDK's build string in the library file (TALUS_SDK_BUILD_INFO).
PluginLibrary::Build read_build_info(const fs::path &file) {
    PluginLibrary::Build b;
    std::ifstream in(file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string key = "TALUS_BUILD_INFO optimised=";
    const auto at = bytes.find(key);
    if (at == std::string::npos || at + key.size() + 11 > bytes.size()) return b;
    const std::string rest = bytes.substr(at + key.size(), 11); // "1 asserts=0"
    if (rest.compare(1, 9, " asserts=") != 0) return b;
    b.known = true;
    b.optimised = rest[0] == '1';
    b.asserts = rest[10] == '1';
    return b;
}

} // namespace

std::string sha256_file(const fs::path &file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return {};
    std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), &EVP_MD_CTX_free);
    if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1) return {};
    std::vector<char> buf(1 << 16);
    while (in) {
        in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
        const auto got = static_cast<std::size_t>(in.gcount());
        if (got > 0 && EVP_DigestUpdate(ctx.get(), buf.data(), got) != 1) return {};
    }
    if (in.bad()) return {};
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int len = 0;
    if (EVP_DigestFinal_ex(ctx.get(), md, &len) != 1) return {};
    std::string hex;
    for (unsigned int i = 0; i < len; ++i)
        fmt::format_to(std::back_inserter(hex), "{:02x}", md[i]);
    return hex;
}

namespace {

std::mutex g_log_sink_mutex;
PluginLogSink g_log_sink;

} // namespace

PluginLogSink set_plugin_log_sink(PluginLogSink sink) {
    const std::lock_guard lock(g_log_sink_mutex);
    std::swap(g_log_sink, sink);
    return sink;
}

void PluginLibrary::host_log(void *context, std::int32_t level, const char *message) {
    // Called by plugin code, possibly from several threads inside update:
    // nothing may escape back across the C ABI.
    try {
        auto *lib = static_cast<PluginLibrary *>(context);
        if (!lib) return;
        std::size_t n = 0;
        {
            const std::lock_guard lock(lib->log_mutex_);
            n = ++lib->log_count_;
        }
        if (n > kPluginLogShown) return;
        const std::string text = message ? std::string(message, strnlen(message, 4096)) : "";
        std::string line =
            fmt::format("{}: plugin {}: {}", level == TALUS_LOG_WARNING ? "warning" : "note",
                        lib->name_.empty() ? lib->path_.string() : lib->name_, text);
        if (n == kPluginLogShown)
            line += fmt::format(" (further messages of this plugin are counted, not shown)");
        const std::lock_guard lock(g_log_sink_mutex);
        if (g_log_sink)
            g_log_sink(line);
        else
            std::fprintf(stderr, "%s\n", line.c_str());
    } catch (...) {
    }
}

std::size_t PluginLibrary::log_messages() const {
    const std::lock_guard lock(log_mutex_);
    return log_count_;
}

std::size_t PluginLibrary::log_suppressed() const {
    const std::size_t n = log_messages();
    return n > kPluginLogShown ? n - kPluginLogShown : 0;
}

const void *PluginLibrary::extension(const char *id) const {
    if (!get_extension_ || !id) return nullptr;
    try {
        return get_extension_(id);
    } catch (...) {
        return nullptr;
    }
}

std::string PluginLibrary::build_text() const {
    if (!build_.known) return "unknown (not built with the Talus SDK's TALUS_MATERIAL_LIBRARY)";
    return fmt::format("{}, assertions {}{}",
                       build_.optimised ? "optimised" : "NOT optimised (-O0)",
                       build_.asserts ? "on" : "off",
                       build_.optimised ? ""
                                        : ": expect it to run about ten times slower; rebuild it "
                                          "with CMAKE_BUILD_TYPE=Release");
}

std::shared_ptr<PluginLibrary> PluginLibrary::open(const fs::path &file) {
    std::error_code ec;
    if (!fs::exists(file, ec))
        throw Error(fmt::format("{}: plugin library not found", file.string()));
    // RTLD_NOW: an unresolved symbol is reported here rather than mid-run.
    // RTLD_LOCAL: two plugins never see each other's symbols.
    void *handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char *why = dlerror();
        throw Error(fmt::format("{}: not a loadable shared library: {}", file.string(),
                                why ? why : "unknown dlopen error"));
    }
    std::shared_ptr<PluginLibrary> lib(new PluginLibrary());
    lib->handle_ = handle;
    lib->path_ = file;
    lib->build_ = read_build_info(file);
    lib->hash_ = sha256_file(file);

    dlerror();
    void *sym = dlsym(handle, TALUS_MATERIAL_ENTRY_SYMBOL);
    if (!sym)
        throw Error(fmt::format(
            "{}: no exported symbol '{}': this is not a Talus material plugin (a plugin defines it "
            "with TALUS_MATERIAL_LIBRARY, or by hand with TALUS_PLUGIN_EXPORT)",
            file.string(), TALUS_MATERIAL_ENTRY_SYMBOL));
    auto entry = reinterpret_cast<talus_material_entry_fn>(sym);

    talus_host_info host{};
    host.struct_size = sizeof(host);
    host.abi_major = TALUS_ABI_VERSION_MAJOR;
    host.abi_minor = TALUS_ABI_VERSION_MINOR;
    host.host_name = host_name();
    host.log = &PluginLibrary::host_log;
    host.log_context = lib.get();
    host.get_extension = [](const char *) -> const void * { return nullptr; };
    const talus_library *desc = nullptr;
    talus_error err = fresh_error();
    std::int32_t status = TALUS_STATUS_FAILED;
    try {
        const crash::PluginCall call("(its entry point)", file.c_str());
        status = entry(&host, &desc, &err);
    } catch (...) {
        throw Error(
            fmt::format("{}: the entry point threw an exception across the C ABI", file.string()));
    }
    if (status != TALUS_STATUS_OK)
        throw Error(fmt::format("{}: the plugin refused to load (host speaks ABI {}.{}): {}",
                                file.string(), TALUS_ABI_VERSION_MAJOR, TALUS_ABI_VERSION_MINOR,
                                read_message(err)));
    lib->read_descriptor(desc);
    return lib;
}

std::shared_ptr<PluginLibrary> PluginLibrary::from_descriptor(const talus_library *desc,
                                                              const fs::path &label) {
    std::shared_ptr<PluginLibrary> lib(new PluginLibrary());
    lib->path_ = label;
    lib->read_descriptor(desc);
    return lib;
}

void PluginLibrary::read_descriptor(const talus_library *desc) {
    const DescriptorChecker chk{path_};
    if (!desc) chk.bad("library", "the entry point returned OK but no library descriptor");
    // Read the version first: a library of another major may lay out even
    // the library structure differently, so nothing else is trusted before.
    if (desc->struct_size < offsetof(talus_library, n_models))
        chk.bad("library", fmt::format("struct_size {} is too small", desc->struct_size));
    if (desc->abi_major != TALUS_ABI_VERSION_MAJOR)
        throw Error(fmt::format("{}: ABI major version mismatch: the plugin was built for Talus "
                                "material ABI {}.{}, this host speaks ABI {}.{}; rebuild the "
                                "plugin against this host's SDK",
                                path_.string(), desc->abi_major, desc->abi_minor,
                                TALUS_ABI_VERSION_MAJOR, TALUS_ABI_VERSION_MINOR));
    chk.need_size(desc->struct_size, offsetof(talus_library, get_extension), "library");
    chk.need_string(desc->name, "library", "name");
    chk.need_string(desc->version, "library", "version");
    // The name prefixes the qualified model ids (library/model).
    if (!*desc->name || std::strpbrk(desc->name, "/ \t\n"))
        chk.bad("library", fmt::format("field 'name' ('{}') must be non-empty, without '/' or "
                                       "spaces: it prefixes the qualified model ids",
                                       desc->name));
    if (TALUS_HAS_FIELD(talus_library, desc, get_extension)) get_extension_ = desc->get_extension;
    if (desc->n_models == 0)
        chk.bad("library", "field 'n_models' is 0: the library offers no model");
    if (!desc->models) chk.bad("library", "field 'models' is null");
    name_ = desc->name;
    version_ = desc->version;
    abi_major_ = desc->abi_major;
    abi_minor_ = desc->abi_minor;

    std::set<std::string> ids;
    for (std::uint32_t m = 0; m < desc->n_models; ++m) {
        const talus_model *md = desc->models[m];
        std::string where = fmt::format("model #{}", m);
        if (!md) chk.bad(where, "null pointer in the models array");
        chk.need_size(md->struct_size, offsetof(talus_model, create_ex), where);
        if (!is_snake_identifier(md->id))
            chk.bad(where, fmt::format("field 'id' must be lower_snake_case, got '{}'",
                                       md->id ? md->id : "(null)"));
        where = fmt::format("model '{}'", md->id);
        if (!ids.insert(md->id).second) chk.bad(where, "the id appears twice in this library");
        chk.need_string(md->name, where, "name");
        chk.need_string(md->version, where, "version");
        chk.need_string(md->doc, where, "doc");
        if (!md->create) chk.bad(where, "field 'create' is null");
        if (!md->destroy) chk.bad(where, "field 'destroy' is null");
        if (!md->update) chk.bad(where, "field 'update' is null");
        constexpr std::uint32_t known = TALUS_MODEL_FINITE_STRAIN | TALUS_MODEL_TANGENT |
                                        TALUS_MODEL_NOT_REENTRANT | TALUS_MODEL_INSTANCE_STATE |
                                        TALUS_MODEL_WANTS_ROTATION;
        if (md->flags & ~known)
            chk.bad(where, fmt::format("field 'flags': unknown bits 0x{:x}", md->flags & ~known));
        if (md->n_params > 0 && !md->params) chk.bad(where, "field 'params' is null");
        if (md->n_state > 0 && !md->state) chk.bad(where, "field 'state' is null");

        Model model;
        model.raw_ = md;
        model.library_ = this;
        if (TALUS_HAS_FIELD(talus_model, md, init_state)) {
            model.create_ex_ = md->create_ex;
            model.instance_state_ = md->instance_state;
            model.init_state_ = md->init_state;
        }
        constexpr std::uint32_t v11 =
            TALUS_MODEL_NOT_REENTRANT | TALUS_MODEL_INSTANCE_STATE | TALUS_MODEL_WANTS_ROTATION;
        if ((md->flags & v11) && !TALUS_HAS_FIELD(talus_model, md, init_state))
            chk.bad(where, fmt::format("flags 0x{:x} are ABI 1.1 but the descriptor is a 1.0 one "
                                       "(struct_size {})",
                                       md->flags & v11, md->struct_size));
        if ((md->flags & TALUS_MODEL_INSTANCE_STATE) && !model.instance_state_)
            chk.bad(where, "TALUS_MODEL_INSTANCE_STATE is set but 'instance_state' is null");
        model.id_ = md->id;
        model.name_ = md->name;
        model.version_ = md->version;
        model.doc_ = md->doc;
        std::set<std::string> keys;
        for (std::uint32_t i = 0; i < md->n_params; ++i) {
            const std::string pw = fmt::format("{} parameter #{}", where, i);
            ParamInfo p = chk.param(md->params[i], pw, model.create_ex_ != nullptr);
            if (!keys.insert(p.key).second)
                chk.bad(pw, fmt::format("key '{}' appears twice", p.key));
            model.params_.push_back(std::move(p));
        }
        // An instance-state model's own table is ignored (material_abi.h).
        if (!model.instance_state()) model.state_ = chk.layout(md->state, md->n_state, where);
        models_.push_back(std::move(model));
    }
}

PluginLibrary::~PluginLibrary() {
    if (handle_) dlclose(handle_);
}

const Model *PluginLibrary::find(const std::string &id) const {
    for (const Model &m : models_)
        if (m.id() == id) return &m;
    return nullptr;
}

// ---------------------------------------------------------------- Model --

std::string Model::qualified_id() const { return library_->name() + "/" + id_; }

std::vector<double> Model::initial_state() const { return state_.initial(); }

std::vector<ParamValue> Model::typical_values() const {
    std::vector<ParamValue> v;
    for (const ParamInfo &p : params_)
        v.push_back(p.typical_param());
    return v;
}

std::unique_ptr<MaterialInstance> Model::create(std::span<const double> values) const {
    std::vector<ParamValue> typed(values.size());
    for (std::size_t i = 0; i < values.size(); ++i)
        typed[i].scalar = values[i];
    return create(typed);
}

std::unique_ptr<MaterialInstance> Model::create(std::span<const ParamValue> values,
                                                const CreateContext &context) const {
    if (values.size() != params_.size())
        throw Error(fmt::format("model '{}': {} parameter values given, {} expected", id_,
                                values.size(), params_.size()));
    talus_error err = fresh_error();
    talus_instance *inst = nullptr;
    std::int32_t status = TALUS_STATUS_FAILED;
    try {
        const crash::PluginCall call(id_.c_str(), library_->path().c_str());
        if (create_ex_) {
            std::vector<talus_param_value> raw(values.size());
            std::vector<const talus_param_value *> ptrs(values.size());
            for (std::size_t i = 0; i < values.size(); ++i) {
                const ParamInfo &p = params_[i];
                talus_param_value &v = raw[i];
                v.struct_size = sizeof v;
                v.type = p.type;
                v.count = p.type == TALUS_PARAM_REAL_ARRAY ? values[i].reals.size()
                          : p.type == TALUS_PARAM_STRING   ? values[i].text.size()
                                                           : 1;
                v.scalar = values[i].scalar;
                v.reals = values[i].reals.empty() ? nullptr : values[i].reals.data();
                v.string = values[i].text.c_str();
                ptrs[i] = &v;
            }
            talus_create_args args{};
            args.struct_size = sizeof args;
            args.n_values = static_cast<std::uint32_t>(values.size());
            args.values = ptrs.data();
            args.material_name = context.material_name.c_str();
            args.base_dir = context.base_dir.c_str();
            status = create_ex_(&args, &inst, &err);
        } else {
            std::vector<double> scalars(values.size());
            for (std::size_t i = 0; i < values.size(); ++i)
                scalars[i] = values[i].scalar;
            status = raw_->create(scalars.data(), static_cast<std::uint32_t>(scalars.size()), &inst,
                                  &err);
        }
    } catch (...) {
        throw Error(fmt::format("model '{}' ({}): create threw an exception across the C ABI", id_,
                                library_->path().string()));
    }
    if (status != TALUS_STATUS_OK || !inst)
        throw Error(fmt::format("model '{}' rejected its parameters: {}", id_,
                                status == TALUS_STATUS_OK ? "create returned no instance"
                                                          : read_message(err)));
    std::unique_ptr<MaterialInstance> out(new MaterialInstance());
    out->model_ = this;
    out->library_ = library_->shared_from_this();
    out->instance_ = inst;
    out->parameters_.assign(values.begin(), values.end());
    if (instance_state()) {
        // Destroyed by `out` if the layout is refused.
        talus_state_layout layout{};
        layout.struct_size = sizeof layout;
        err = fresh_error();
        try {
            const crash::PluginCall call(id_.c_str(), library_->path().c_str());
            status = instance_state_(inst, &layout, &err);
        } catch (...) {
            throw Error(fmt::format("model '{}' ({}): instance_state threw an exception across "
                                    "the C ABI",
                                    id_, library_->path().string()));
        }
        if (status != TALUS_STATUS_OK)
            throw Error(
                fmt::format("model '{}' could not describe its state: {}", id_, read_message(err)));
        const DescriptorChecker chk{library_->path()};
        out->state_ =
            chk.layout(layout.state, layout.n_state, fmt::format("model '{}' instance state", id_));
    }
    return out;
}

// ------------------------------------------------------ MaterialInstance --

MaterialInstance::~MaterialInstance() {
    if (instance_) {
        const crash::PluginCall call(model_->id().c_str(), library_->path().c_str());
        model_->raw().destroy(instance_);
    }
}

MaterialInstance::Result MaterialInstance::update(talus_batch &b) const noexcept {
    return call(b, false);
}

MaterialInstance::Result MaterialInstance::start(talus_batch &b) const noexcept {
    return call(b, true);
}

namespace {

// The output screens below, in one version per instruction set, the
// widest the machine has picked when the program loads (GCC's and clang's
// target_clones): the core is built for the x86-64 baseline, where these
// loops take two values an instruction, and they ran at every batch: 3 %
// of a 2D step.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__APPLE__)
#define TALUS_SCREEN_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define TALUS_SCREEN_CLONES
#endif

// Whether any of the count values is NaN or infinite. The SDK's any_nonfinite
// is the same test for a plugin's inputs; the core does not use the SDK (the
// C header is all it shares with plugins), so each side keeps its own.
TALUS_SCREEN_CLONES bool nonfinite(const double *p, std::size_t count) {
    // The exponent lies in the upper 32 bits: a 32-bit test is one the
    // x86-64 baseline (SSE2) has in vector form; a 64-bit one is not.
    constexpr std::uint32_t exponent = 0x7ff00000u;
    std::uint32_t any = 0;
    for (std::size_t k = 0; k < count; ++k) {
        std::uint64_t bits;
        std::memcpy(&bits, p + k, sizeof bits);
        const auto high = static_cast<std::uint32_t>(bits >> 32);
        any |= static_cast<std::uint32_t>((high & exponent) == exponent);
    }
    return any != 0;
}

// Whether every wave speed is positive and finite (NaN fails both tests).
// The failures are or-ed without a branch so that the loop vectorises: as
// `ok &= c > 0 && c < inf` it was a scalar loop with a branch per value, 1 %
// of a 2D step.
TALUS_SCREEN_CLONES bool speeds_valid(const double *c, std::size_t n) {
    std::uint32_t bad = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const double x = c[i];
        bad |= static_cast<std::uint32_t>(!(x > 0.0)) | static_cast<std::uint32_t>(!(x < INFINITY));
    }
    return bad == 0;
}

} // namespace

MaterialInstance::Result MaterialInstance::call(talus_batch &b, bool setup) const noexcept {
    Result r;
    b.struct_size = sizeof(talus_batch);
    b.state_size = state_size();
    if (!model_->wants_rotation()) b.rotation = nullptr;
    talus_error err = fresh_error();
    const bool init = setup && model_->init_state_;
    const auto fn = init ? model_->init_state_ : model_->raw().update;
    const char *fn_name = init ? "init_state" : "update";
    try {
        const crash::PluginCall call(model_->id().c_str(), library_->path().c_str());
        // A lock per batch, only for models that ask for it (Fortran code
        // with SAVE or COMMON data): never in the reentrant models' path.
        std::unique_lock<std::mutex> serial;
        if (!model_->reentrant()) serial = std::unique_lock<std::mutex>(library_->call_mutex());
        r.status = fn(instance_, &b, &err);
    } catch (...) {
        r.status = TALUS_STATUS_FAILED;
        r.message = fmt::format("an exception escaped the plugin's {} across the C ABI", fn_name);
        return r;
    }
    if (r.status != TALUS_STATUS_OK) {
        if (r.status != TALUS_STATUS_FAILED && r.status != TALUS_STATUS_CUT_STEP) {
            r.message = fmt::format("{} returned the unknown status {}", fn_name, r.status);
            r.status = TALUS_STATUS_FAILED;
            return r;
        }
        r.point = err.point_index;
        r.cut_factor = err.cut_factor;
        r.message = read_message(err);
        if (r.message.empty()) r.message = fmt::format("{} failed without a message", fn_name);
        if (r.status == TALUS_STATUS_CUT_STEP && !(r.cut_factor > 0.0 && r.cut_factor < 1.0)) {
            r.message = fmt::format("cut-step request with an invalid factor {} (expected 0 < "
                                    "factor < 1): {}",
                                    r.cut_factor, r.message);
            r.status = TALUS_STATUS_FAILED;
        }
        return r;
    }
    // The host never trusts outputs blindly: a NaN that entered the solver
    // would spread silently through the grid. A value is NaN or infinite
    // exactly when its exponent bits are all ones; the test is an integer
    // one with an OR reduction, which the compiler vectorises (a sum of
    // x * 0, the other branch-free screen, is one long chain of dependent
    // floating-point adds). The point is looked for only when it trips.
    const std::size_t n = b.n_points, ns = b.state_size;
    const bool want_c = (b.flags & TALUS_BATCH_WANT_WAVE_SPEED) != 0;
    const bool want_t = (b.flags & TALUS_BATCH_WANT_TANGENT) != 0;
    const bool screen = nonfinite(b.stress_end, 6 * n) || (ns && nonfinite(b.state_end, ns * n)) ||
                        (want_t && nonfinite(b.tangent, 36 * n));
    const bool speeds_ok = !want_c || speeds_valid(b.wave_speed, n);
    if (!screen && speeds_ok) return r;
    for (std::size_t i = 0; i < n; ++i) {
        const bool bad_c = want_c && !speeds_valid(b.wave_speed + i, 1);
        const bool bad = nonfinite(b.stress_end + 6 * i, 6) ||
                         (ns && nonfinite(b.state_end + ns * i, ns)) ||
                         (want_t && nonfinite(b.tangent + 36 * i, 36)) || bad_c;
        if (!bad) continue;
        r.status = TALUS_STATUS_FAILED;
        r.host_detected = true;
        r.point = static_cast<std::int64_t>(i);
        r.message =
            fmt::format("returned status OK but a non-finite {} at point {}",
                        bad_c ? "or non-positive wave speed" : "stress, state or tangent", i);
        return r;
    }
    return r;
}

// ------------------------------------------------------- PluginRegistry --

PluginRegistry::PluginRegistry(std::vector<fs::path> plugin_path, bool use_environment)
    : extra_(std::move(plugin_path)), use_env_(use_environment) {}

namespace {
fs::path executable_dir() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? fs::path() : exe.parent_path();
}
} // namespace

std::vector<fs::path> PluginRegistry::search_dirs() const {
    std::vector<fs::path> dirs = extra_;
    if (use_env_) {
        if (const char *env = std::getenv("TALUS_PLUGIN_PATH")) {
            std::string_view s(env);
            while (!s.empty()) {
                const auto colon = s.find(':');
                const std::string_view part = s.substr(0, colon);
                if (!part.empty()) dirs.emplace_back(std::string(part));
                if (colon == std::string_view::npos) break;
                s.remove_prefix(colon + 1);
            }
        }
    }
    // The user's own plugins: $XDG_DATA_HOME/talus/plugins, by default
    // ~/.local/share/talus/plugins (the XDG base directory convention), so
    // that a plugin built once is found by every run without settings.
    if (use_env_) {
        const char *xdg = std::getenv("XDG_DATA_HOME");
        const char *home = std::getenv("HOME");
        if (xdg && *xdg)
            dirs.push_back(fs::path(xdg) / "talus" / "plugins");
        else if (home && *home)
            dirs.push_back(fs::path(home) / ".local" / "share" / "talus" / "plugins");
    }
    // The shipped plugins, found relative to the running executable so that
    // both a build tree (bin/ beside plugins/) and an installed, possibly
    // moved, tree (bin/ beside lib/talus/plugins/) work without settings.
    if (const fs::path exe = executable_dir(); !exe.empty()) {
        dirs.push_back(exe.parent_path() / "plugins");
#ifdef TALUS_INSTALL_PLUGIN_SUBDIR
        dirs.push_back(exe.parent_path() / TALUS_INSTALL_PLUGIN_SUBDIR);
#endif
    }
    return dirs;
}

const PluginLibrary &PluginRegistry::add(const fs::path &file) {
    std::error_code ec;
    const fs::path canon = fs::weakly_canonical(file, ec);
    for (const auto &lib : libraries_)
        if (lib->path() == canon) return *lib;
    std::shared_ptr<PluginLibrary> lib = PluginLibrary::open(canon);
    // Model ids may repeat across libraries (they are told apart by the
    // qualified id library/model), library names may not.
    for (const auto &other : libraries_)
        if (other->name() == lib->name())
            throw Error(fmt::format("two plugin libraries are named '{}': {} and {}; remove one "
                                    "of them from the plugin search path",
                                    lib->name(), other->path().string(), canon.string()));
    libraries_.push_back(std::move(lib));
    return *libraries_.back();
}

bool PluginRegistry::is_path(const std::string &name_or_path) {
    return name_or_path.find('/') != std::string::npos ||
           (name_or_path.size() > 3 &&
            name_or_path.compare(name_or_path.size() - 3, 3, ".so") == 0 &&
            fs::exists(name_or_path));
}

fs::path PluginRegistry::locate(const std::string &name_or_path) const {
    if (is_path(name_or_path)) {
        if (!fs::exists(name_or_path))
            throw Error(fmt::format("{}: plugin library not found", name_or_path));
        return name_or_path;
    }
    const std::string names[] = {name_or_path, "talus_" + name_or_path + ".so",
                                 name_or_path + ".so"};
    std::string tried;
    for (const fs::path &dir : search_dirs())
        for (const std::string &n : names) {
            const fs::path f = dir / n;
            std::error_code ec;
            if (fs::is_regular_file(f, ec)) return f;
            fmt::format_to(std::back_inserter(tried), "\n  {}", f.string());
        }
    throw Error(fmt::format("plugin library '{}' not found; looked for:{}\n(add a directory with "
                            "--plugin-path or the TALUS_PLUGIN_PATH environment variable)",
                            name_or_path, tried));
}

const PluginLibrary &PluginRegistry::load(const std::string &name_or_path) {
    return add(locate(name_or_path));
}

void PluginRegistry::load_all() {
    std::set<std::string> seen_names;
    for (const fs::path &dir : search_dirs()) {
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) continue;
        std::vector<fs::path> files;
        for (const auto &e : fs::directory_iterator(dir, ec)) {
            const std::string fn = e.path().filename().string();
            if (fn.rfind("talus_", 0) == 0 && e.path().extension() == ".so")
                files.push_back(e.path());
        }
        std::sort(files.begin(), files.end()); // deterministic order
        for (const fs::path &f : files)
            if (seen_names.insert(f.filename().string()).second) add(f);
    }
}

const Model &PluginRegistry::find_model(const std::string &id) {
    const auto slash = id.find('/');
    const std::string lib_name = slash == std::string::npos ? "" : id.substr(0, slash);
    const std::string model_id = slash == std::string::npos ? id : id.substr(slash + 1);
    // The models offering the id among the loaded libraries.
    auto offering = [&] {
        std::vector<const Model *> found;
        for (const auto &lib : libraries_)
            if (slash == std::string::npos || lib->name() == lib_name)
                if (const Model *m = lib->find(model_id)) found.push_back(m);
        return found;
    };
    std::vector<const Model *> found = offering();
    if (found.empty()) {
        load_all();
        found = offering();
    }
    if (found.size() == 1) return *found.front();
    if (found.size() > 1) {
        std::string which;
        for (const Model *m : found)
            fmt::format_to(std::back_inserter(which), "\n  {} ({})", m->qualified_id(),
                           m->library().path().string());
        throw Error(fmt::format("the material model id '{}' is offered by {} libraries; name one "
                                "by its qualified id:{}",
                                id, found.size(), which));
    }
    std::vector<std::string> known;
    for (const auto &lib : libraries_)
        for (const Model &m : lib->models())
            known.push_back(slash == std::string::npos ? m.id() : m.qualified_id());
    std::string dirs;
    for (const fs::path &d : search_dirs())
        dirs += "\n  " + d.string();
    const std::string guess = closest_match(id, std::span<const std::string>(known));
    std::string list;
    for (const auto &k : known)
        list += (list.empty() ? "" : ", ") + k;
    throw Error(fmt::format("no plugin offers the material model '{}'{}; models found: {}; plugin "
                            "directories searched:{}",
                            id, guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess),
                            list.empty() ? "none" : list, dirs));
}

} // namespace talus
