// Loading material plugins (shared libraries speaking talus/material_abi.h).
//
// Search order for a library given by name (see docs/plugins.md):
//   1. an explicit path (anything containing '/' or ending in ".so");
//   2. the directories given with --plugin-path, in order;
//   3. the directories in the TALUS_PLUGIN_PATH environment variable;
//   4. the user's plugin folder, $XDG_DATA_HOME/talus/plugins (by default
//      ~/.local/share/talus/plugins);
//   5. the shipped plugins beside the running executable: <bin>/../plugins
//      (a build tree), then <bin>/../lib/talus/plugins (an installation).
// A name N matches the files N, talus_N.so and N.so. A model is named by
// its qualified id "library/model" (never ambiguous) or by its model id
// alone: that is taken from the loaded libraries (a scenario's `plugins:`
// list) when exactly one of them offers it, else found by scanning every
// talus_*.so on the search path, where exactly one library must offer it. A
// file name seen in an earlier directory shadows the same name later; two
// libraries of the same name are an error.
#pragma once

#include <talus/error.hpp>
#include <talus/material_abi.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace talus {

// One parameter's value: `scalar` for REAL, INTEGER and BOOLEAN, `reals`
// for REAL_ARRAY, `text` for STRING (ABI 1.1).
struct ParamValue {
    double scalar = 0.0;
    std::vector<double> reals;
    std::string text;
    bool operator==(const ParamValue &) const = default;
};

struct ParamInfo {
    std::string key, unit, doc;
    std::uint32_t type = TALUS_PARAM_REAL;
    std::uint32_t flags = 0;
    double default_value = 0.0, min_value = 0.0, max_value = 0.0, typical_value = 0.0;
    // REAL_ARRAY: allowed counts (max_count 0: no limit). STRING: default
    // and example (has_typical_string false: the plugin gave none).
    std::uint32_t min_count = 0, max_count = 0;
    std::string default_string{}, typical_string{};
    bool has_typical_string = false;

    bool required() const { return (flags & TALUS_PARAM_REQUIRED) != 0; }
    bool scalar() const { return type <= TALUS_PARAM_BOOLEAN; }
    bool in_bounds(double v) const;
    // "-1 < poisson_ratio < 0.5", "youngs_modulus > 0", "any value"; for an
    // array, the bound of each value.
    std::string bounds_text() const;
    // "3 to 10 values", "at least 1 value": REAL_ARRAY only.
    std::string count_text() const;
    const char *type_name() const;
    // The value used when the user omits it (not required), and the one the
    // conformance checks and docs use.
    ParamValue default_param() const;
    ParamValue typical_param() const;
    // The value as text, for messages and provenance ("2e+07", "[1, 2]").
    std::string value_text(const ParamValue &v) const;
};

struct StateInfo {
    std::string name, unit, doc;
    std::uint32_t size = 1;
    std::uint32_t flags = 0;
    double initial_value = 0.0;
    std::uint32_t offset = 0; // first index in the point's state vector
    bool output() const { return (flags & TALUS_STATE_OUTPUT) != 0; }
    bool user_initialisable() const { return (flags & TALUS_STATE_USER_INIT) != 0; }
};

// A state layout: the variables in order and the doubles per point.
struct StateLayout {
    std::vector<StateInfo> vars;
    std::uint32_t size = 0;
    // One point's state with every variable at its initial value.
    std::vector<double> initial() const;
};

// Where a material's parameters come from, for create_ex and messages.
struct CreateContext {
    std::string material_name; // the user's name, e.g. "materials.sand"
    std::string base_dir;      // folder of the file it was read from ("" if none)
};

class PluginLibrary;
class MaterialInstance;

// A validated view of one model descriptor.
class Model {
  public:
    const std::string &id() const { return id_; }
    const std::string &name() const { return name_; }
    const std::string &version() const { return version_; }
    // "library/model": unique among the loaded libraries.
    std::string qualified_id() const;
    const std::string &doc() const { return doc_; }
    std::uint32_t flags() const { return raw_->flags; }
    bool finite_strain() const { return (raw_->flags & TALUS_MODEL_FINITE_STRAIN) != 0; }
    bool has_tangent() const { return (raw_->flags & TALUS_MODEL_TANGENT) != 0; }
    bool reentrant() const { return (raw_->flags & TALUS_MODEL_NOT_REENTRANT) == 0; }
    bool wants_rotation() const { return (raw_->flags & TALUS_MODEL_WANTS_ROTATION) != 0; }
    // The state layout is the instance's (MaterialInstance::state()); the
    // model's own state() is then empty.
    bool instance_state() const { return (raw_->flags & TALUS_MODEL_INSTANCE_STATE) != 0; }
    bool has_init_state() const { return init_state_ != nullptr; }
    const std::vector<ParamInfo> &params() const { return params_; }
    const std::vector<StateInfo> &state() const { return state_.vars; }
    std::uint32_t state_size() const { return state_.size; }
    const StateLayout &state_layout() const { return state_; }
    // Initial state vector of one point (each variable at its initial value).
    std::vector<double> initial_state() const;
    const PluginLibrary &library() const { return *library_; }
    const talus_model &raw() const { return *raw_; }

    // Parameter values in the order of params(), already checked by the
    // caller against type and bounds (see check_parameter()). Throws
    // talus::Error with the plugin's message if it rejects them, or if an
    // instance-state model reports an invalid layout.
    std::unique_ptr<MaterialInstance> create(std::span<const ParamValue> values,
                                             const CreateContext &context = {}) const;
    // The same for a model whose parameters are all scalars.
    std::unique_ptr<MaterialInstance> create(std::span<const double> values) const;
    // Every parameter at its typical value.
    std::vector<ParamValue> typical_values() const;

  private:
    friend class PluginLibrary;
    friend class MaterialInstance;
    const talus_model *raw_ = nullptr;
    const PluginLibrary *library_ = nullptr;
    // 1.1 functions, null when the plugin's descriptor predates them.
    decltype(talus_model::create_ex) create_ex_ = nullptr;
    decltype(talus_model::instance_state) instance_state_ = nullptr;
    decltype(talus_model::init_state) init_state_ = nullptr;
    std::string id_, name_, version_, doc_;
    std::vector<ParamInfo> params_;
    StateLayout state_;
};

// An open plugin library. Closes it (dlclose) when the last user is gone.
class PluginLibrary : public std::enable_shared_from_this<PluginLibrary> {
  public:
    // Opens, calls the entry point and validates every descriptor; throws
    // talus::Error naming the file and the problem.
    static std::shared_ptr<PluginLibrary> open(const std::filesystem::path &file);
    // The checks open() makes of the descriptor its entry point returned, on
    // a descriptor already in memory (no file is loaded; `label` names it in
    // messages). The library and its models point into `desc`, which must
    // outlive them. For the descriptor fuzzer (fuzz/plugin_descriptor.cpp).
    static std::shared_ptr<PluginLibrary> from_descriptor(const talus_library *desc,
                                                          const std::filesystem::path &label);
    ~PluginLibrary();
    PluginLibrary(const PluginLibrary &) = delete;
    PluginLibrary &operator=(const PluginLibrary &) = delete;

    const std::filesystem::path &path() const { return path_; }
    const std::string &name() const { return name_; }
    const std::string &version() const { return version_; }
    std::uint32_t abi_major() const { return abi_major_; }
    std::uint32_t abi_minor() const { return abi_minor_; }
    const std::vector<Model> &models() const { return models_; }
    const Model *find(const std::string &id) const;
    // SHA-256 of the library file as loaded, in hex (what sha256sum prints).
    const std::string &content_hash() const { return hash_; }
    // The library's extension by id, or null (ABI 1.1 get_extension).
    const void *extension(const char *id) const;

    // Serialises calls into a library whose models are not reentrant.
    std::mutex &call_mutex() const { return call_mutex_; }
    // Messages the plugin sent through the host's log callback, and how
    // many of them were not shown (past the first kPluginLogShown).
    std::size_t log_messages() const;
    std::size_t log_suppressed() const;
    // "talus: note: plugin x sent 380 message(s) more than the 20 shown",
    // or empty: for the end of a command.
    std::string log_note() const;

    // The first change a call into the library made to the calling
    // thread's floating-point environment ("create of model 'x': rounding
    // upward instead of to nearest"), empty if none; the host puts every
    // such change back after the call (material/fp_environment.hpp) and
    // logs the first. fp_changes() counts the calls that made one.
    std::string fp_change() const;
    std::size_t fp_changes() const;
    void note_fp_change(const char *model, const char *call, const std::string &what) const;

    // How the library was compiled, from the string the SDK embeds
    // (TALUS_SDK_BUILD_INFO); unknown for plugins written without the SDK.
    struct Build {
        bool known = false, optimised = false, asserts = false;
    };
    const Build &build() const { return build_; }
    // "optimised, assertions off", "NOT optimised (-O0), ...", or "unknown".
    std::string build_text() const;

  private:
    PluginLibrary() = default;
    friend class Model;
    void read_descriptor(const talus_library *desc);
    static void host_log(void *context, std::int32_t level, const char *message);
    void *handle_ = nullptr;
    std::filesystem::path path_;
    std::string name_, version_, hash_;
    std::uint32_t abi_major_ = 0, abi_minor_ = 0;
    std::vector<Model> models_;
    Build build_;
    decltype(talus_library::get_extension) get_extension_ = nullptr;
    mutable std::mutex call_mutex_, log_mutex_;
    std::size_t log_count_ = 0;
    mutable std::string fp_change_; // under log_mutex_
    mutable std::size_t fp_changes_ = 0;
};

// Where plugins' log messages go (default: stderr), one finished line each
// ("warning: plugin talus_x: ..."). Each library shows its first
// kPluginLogShown messages; later ones are only counted. Returns the
// previous sink.
inline constexpr std::size_t kPluginLogShown = 20;
using PluginLogSink = std::function<void(const std::string &)>;
PluginLogSink set_plugin_log_sink(PluginLogSink sink);
// How many messages of each library are shown (kPluginLogShown unless set;
// SIZE_MAX: all), and whether its notes are (a warning always is, up to
// the count): `talus --verbose` shows all, `--quiet` no notes.
void set_plugin_log_policy(std::size_t shown, bool notes);

// One material: a model with one set of parameter values. Owns the plugin's
// instance and keeps its library loaded.
class MaterialInstance {
  public:
    ~MaterialInstance();
    MaterialInstance(const MaterialInstance &) = delete;
    MaterialInstance &operator=(const MaterialInstance &) = delete;

    const Model &model() const { return *model_; }
    // The parameter values it was created with, in the order of
    // model().params().
    const std::vector<ParamValue> &parameters() const { return parameters_; }
    // The state layout of its points: the model's, or with
    // TALUS_MODEL_INSTANCE_STATE the instance's own.
    const StateLayout &state() const {
        return model_->instance_state() ? state_ : model_->state_layout();
    }
    std::uint32_t state_size() const { return state().size; }

    struct Result {
        std::int32_t status = TALUS_STATUS_OK;
        std::int64_t point = -1; // failing point in the batch, -1 if none
        double cut_factor = 1.0; // with TALUS_STATUS_CUT_STEP
        std::string message;     // empty when ok
        // True when the plugin said OK but the host found a non-finite
        // output: the plugin broke the contract rather than failing cleanly.
        bool host_detected = false;
        bool ok() const { return status == TALUS_STATUS_OK; }
    };
    // Calls the plugin's update on a batch the caller filled (struct_size and
    // state_size are set here). Never throws: a plugin failure, a cut-step
    // request, an exception escaping the plugin, or a non-finite value in any
    // requested output all come back in Result, with the point named.
    // Callable from several threads: calls into a model that is not
    // reentrant are serialised here.
    Result update(talus_batch &batch) const noexcept;
    // The set-up call before the first step (batch.dt = 0, step 0): the
    // model's init_state when it has one, else update (material_abi.h).
    Result start(talus_batch &batch) const noexcept;

    // A batch given to update or start, for the crash report's search of
    // the particle a crash is the doing of (crash::Task::run_alone).
    struct AloneCall {
        const MaterialInstance *instance;
        const talus_batch *batch;
        bool setup;
    };
    // Point k of that batch alone: the plugin's function on a one-point
    // batch of the same inputs, with no lock, guard or screen. Only for a
    // child process the crash report forked, which has one thread and ends
    // after the call.
    static void run_alone(const void *alone_call, std::size_t k) noexcept;

  private:
    friend class Model;
    MaterialInstance() = default;
    Result call(talus_batch &batch, bool setup) const noexcept;
    const Model *model_ = nullptr;
    std::shared_ptr<const PluginLibrary> library_;
    talus_instance *instance_ = nullptr;
    std::vector<ParamValue> parameters_;
    StateLayout state_;
};

class PluginRegistry {
  public:
    // `plugin_path`: directories from --plugin-path, searched first.
    explicit PluginRegistry(std::vector<std::filesystem::path> plugin_path = {},
                            bool use_environment = true);

    // The directories searched, in order (existing or not).
    std::vector<std::filesystem::path> search_dirs() const;

    // The library file a name or path designates (see the header comment),
    // without loading it. Throws, listing the places looked at, if there is
    // none.
    std::filesystem::path locate(const std::string &name_or_path) const;
    // True when `name_or_path` is a path (contains '/', or is an existing
    // file ending in ".so"), false for a name to look up.
    static bool is_path(const std::string &name_or_path);
    // Load a library by explicit path or by name (locate()).
    // Loading the same file twice returns the same library. Throws if a model
    // id it offers is already offered by another loaded library.
    const PluginLibrary &load(const std::string &name_or_path);
    // The model with this id: among loaded libraries, else by scanning the
    // search path. Throws, listing the places searched and the models seen
    // (with a "did you mean"), if it is nowhere.
    const Model &find_model(const std::string &id);
    // Load every talus_*.so on the search path.
    void load_all();

    const std::vector<std::shared_ptr<PluginLibrary>> &libraries() const { return libraries_; }

  private:
    const PluginLibrary &add(const std::filesystem::path &file);
    std::vector<std::filesystem::path> extra_;
    bool use_env_;
    std::vector<std::shared_ptr<PluginLibrary>> libraries_;
};

// Checks one user value against a parameter's type and bounds; returns an
// empty string when fine, else what was expected ("expected -1 < nu < 0.5").
std::string check_parameter(const ParamInfo &p, double value);
// The same for a value of any type (an array: its count and each value).
std::string check_parameter(const ParamInfo &p, const ParamValue &value);

// SHA-256 of a file's content in hex (what sha256sum prints); empty when
// the file cannot be read.
std::string sha256_file(const std::filesystem::path &file);
// The same of bytes in memory (a scenario's text as it was read).
std::string sha256_bytes(std::string_view bytes);

// The host's own identification passed to plugins ("talus 0.1.0").
const char *host_name();

} // namespace talus
