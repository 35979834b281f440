// A plugin library: opened once per file, its entry called, its
// descriptors checked and kept (PluginLibrary), its file's digest, and the
// host's log callback.
#include <talus/material/plugin_loader.hpp>

#include "descriptor_checker.hpp"
#include "fp_environment.hpp"
#include "plugin_errors.hpp"

#include <talus/material/crash_report.hpp>
#include <talus/regular_file.hpp>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <atomic>
#include <dlfcn.h>
#include <openssl/evp.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>

#ifndef TALUS_VERSION_STRING
#define TALUS_VERSION_STRING "0.0.0"
#endif

namespace fs = std::filesystem;

namespace talus {

const char *host_name() { return "talus " TALUS_VERSION_STRING; }

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

namespace {

// Feeds `more` chunks into SHA-256; the digest in hex, empty on a failure.
template <class More>
std::string sha256_of(More &&more) {
    std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), &EVP_MD_CTX_free);
    if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1) return {};
    if (!more([&](const void *p, std::size_t n) {
            return n == 0 || EVP_DigestUpdate(ctx.get(), p, n) == 1;
        }))
        return {};
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int len = 0;
    if (EVP_DigestFinal_ex(ctx.get(), md, &len) != 1) return {};
    std::string hex;
    for (unsigned int i = 0; i < len; ++i)
        fmt::format_to(std::back_inserter(hex), "{:02x}", md[i]);
    return hex;
}

} // namespace

std::string sha256_file(const fs::path &file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return {};
    return sha256_of([&](auto &&update) {
        std::vector<char> buf(1 << 16);
        while (in) {
            in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
            if (!update(buf.data(), static_cast<std::size_t>(in.gcount()))) return false;
        }
        return !in.bad();
    });
}

std::string sha256_bytes(std::string_view bytes) {
    return sha256_of([&](auto &&update) { return update(bytes.data(), bytes.size()); });
}

namespace {

std::mutex g_log_sink_mutex;
std::atomic<std::size_t> g_log_shown{kPluginLogShown};
std::atomic<bool> g_log_notes{true};
PluginLogSink g_log_sink;

} // namespace

void set_plugin_log_policy(std::size_t shown, bool notes) {
    g_log_shown.store(shown);
    g_log_notes.store(notes);
}

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
        if (level != TALUS_LOG_WARNING && !g_log_notes.load(std::memory_order_relaxed)) return;
        const std::size_t shown = g_log_shown.load(std::memory_order_relaxed);
        std::size_t n = 0;
        {
            const std::lock_guard lock(lib->log_mutex_);
            n = ++lib->log_count_;
        }
        if (n > shown) return;
        const std::string text = message ? std::string(message, strnlen(message, 4096)) : "";
        // Where the solver is: a message of a batch's point says "point 3",
        // which means nothing to a user without the group and particles.
        const std::string task = crash::current_task();
        std::string line =
            fmt::format("{}: plugin {}{}: {}", level == TALUS_LOG_WARNING ? "warning" : "note",
                        lib->name_.empty() ? lib->path_.string() : lib->name_,
                        task.empty() ? std::string() : " (" + task + ")", text);
        if (n == shown)
            line += fmt::format(" (further messages of this plugin are counted; the count comes "
                                "at the end)");
        const std::lock_guard lock(g_log_sink_mutex);
        if (g_log_sink)
            g_log_sink(line);
        else
            std::fprintf(stderr, "%s\n", line.c_str());
    } catch (...) {
    }
}

void PluginLibrary::note_fp_change(const char *model, const char *call,
                                   const std::string &what) const {
    std::string line;
    {
        const std::lock_guard lock(log_mutex_);
        if (fp_changes_++ > 0) return;
        const std::string who =
            model ? fmt::format("{} of model '{}'", call, model) : std::string(call);
        fp_change_ = fmt::format("{}: {}", who, what);
        line = fmt::format("warning: plugin {}: {} changed the floating-point environment ({}) "
                           "and did not set it back; Talus put it back after that call and does "
                           "after every call, but a plugin must leave the environment as it "
                           "found it (`talus plugin check` fails it)",
                           name_.empty() ? path_.string() : name_, who, what);
    }
    const std::lock_guard lock(g_log_sink_mutex);
    if (g_log_sink)
        g_log_sink(line);
    else
        std::fprintf(stderr, "%s\n", line.c_str());
}

std::string PluginLibrary::fp_change() const {
    const std::lock_guard lock(log_mutex_);
    return fp_change_;
}

std::size_t PluginLibrary::fp_changes() const {
    const std::lock_guard lock(log_mutex_);
    return fp_changes_;
}

std::size_t PluginLibrary::log_messages() const {
    const std::lock_guard lock(log_mutex_);
    return log_count_;
}

std::string PluginLibrary::log_note() const {
    const std::size_t more = log_suppressed();
    if (more == 0) return {};
    return fmt::format("talus: note: plugin {} sent {} message(s) more than the {} shown",
                       name_.empty() ? path_.string() : name_, more, g_log_shown.load());
}

std::size_t PluginLibrary::log_suppressed() const {
    const std::size_t n = log_messages();
    const std::size_t shown = g_log_shown.load();
    return n > shown ? n - shown : 0;
}

const void *PluginLibrary::extension(const char *id) const {
    if (!get_extension_ || !id) return nullptr;
    try {
        const crash::PluginCall call("(get_extension)", path_.c_str());
        const FpGuard fp(*this, nullptr, "get_extension");
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
    if (const std::string why = not_a_regular_file(file); !why.empty())
        throw Error(fmt::format("{}: {}", file.string(), why));
    // RTLD_NOW: an unresolved symbol is reported here rather than mid-run.
    // RTLD_LOCAL: two plugins never see each other's symbols.
    // Its constructors run here (and set flush-to-zero if it was built
    // with -ffast-math): what they change of the floating-point
    // environment is put back like a call's (fp_environment.hpp).
    const FpControl fp_before = fp_control();
    void *handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    const FpControl fp_after = fp_control();
    if (!(fp_after == fp_before)) set_fp_control(fp_before);
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
        // The library's own path, which outlives the call (a crash report
        // may name it later).
        const crash::PluginCall call("(its entry point)", lib->path_.c_str());
        const FpGuard fp(*lib, nullptr, "its entry point");
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
    if (!(fp_after == fp_before))
        lib->note_fp_change(nullptr,
                            "loading the library (its constructors; -ffast-math sets "
                            "flush-to-zero as a library loads)",
                            fp_difference(fp_before, fp_after));
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
        if (!DescriptorChecker::snake_case(md->id))
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

} // namespace talus
