// Loading material plugins (shared libraries speaking talus/material_abi.h).
//
// Search order for a library given by name (see docs/plugins.md):
//   1. an explicit path (anything containing '/' or ending in ".so");
//   2. the directories given with --plugin-path, in order;
//   3. the directories in the TALUS_PLUGIN_PATH environment variable;
//   4. the shipped plugins beside the running executable: <bin>/../plugins
//      (a build tree), then <bin>/../lib/talus/plugins (an installation).
// A name N matches the files N, talus_N.so and N.so. A model id is found by
// scanning every talus_*.so on the search path; a file name seen in an
// earlier directory shadows the same name later, and two different libraries
// offering the same model id is an error.
#pragma once

#include <talus/error.hpp>
#include <talus/material_abi.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace talus {

struct ParamInfo {
    std::string key, unit, doc;
    std::uint32_t type = TALUS_PARAM_REAL;
    std::uint32_t flags = 0;
    double default_value = 0.0, min_value = 0.0, max_value = 0.0, typical_value = 0.0;

    bool required() const { return (flags & TALUS_PARAM_REQUIRED) != 0; }
    bool in_bounds(double v) const;
    // "-1 < poisson_ratio < 0.5", "youngs_modulus > 0", "any value".
    std::string bounds_text() const;
    const char *type_name() const;
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

class PluginLibrary;
class MaterialInstance;

// A validated view of one model descriptor.
class Model {
  public:
    const std::string &id() const { return id_; }
    const std::string &name() const { return name_; }
    const std::string &version() const { return version_; }
    const std::string &doc() const { return doc_; }
    bool finite_strain() const { return (raw_->flags & TALUS_MODEL_FINITE_STRAIN) != 0; }
    bool has_tangent() const { return (raw_->flags & TALUS_MODEL_TANGENT) != 0; }
    const std::vector<ParamInfo> &params() const { return params_; }
    const std::vector<StateInfo> &state() const { return state_; }
    std::uint32_t state_size() const { return state_size_; }
    // Initial state vector of one point (each variable at its initial value).
    std::vector<double> initial_state() const;
    const PluginLibrary &library() const { return *library_; }
    const talus_model &raw() const { return *raw_; }

    // Parameter values in the order of params(), already checked by the
    // caller against type and bounds (see check_parameter()). Throws
    // talus::Error with the plugin's message if it rejects them.
    std::unique_ptr<MaterialInstance> create(std::span<const double> values) const;

  private:
    friend class PluginLibrary;
    const talus_model *raw_ = nullptr;
    const PluginLibrary *library_ = nullptr;
    std::string id_, name_, version_, doc_;
    std::vector<ParamInfo> params_;
    std::vector<StateInfo> state_;
    std::uint32_t state_size_ = 0;
};

// An open plugin library. Closes it (dlclose) when the last user is gone.
class PluginLibrary : public std::enable_shared_from_this<PluginLibrary> {
  public:
    // Opens, calls the entry point and validates every descriptor; throws
    // talus::Error naming the file and the problem.
    static std::shared_ptr<PluginLibrary> open(const std::filesystem::path &file);
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
    void *handle_ = nullptr;
    std::filesystem::path path_;
    std::string name_, version_;
    std::uint32_t abi_major_ = 0, abi_minor_ = 0;
    std::vector<Model> models_;
    Build build_;
};

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
    const std::vector<double> &parameters() const { return parameters_; }

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
    // Reentrant, as the plugin's update must be.
    Result update(talus_batch &batch) const noexcept;

  private:
    friend class Model;
    MaterialInstance() = default;
    const Model *model_ = nullptr;
    std::shared_ptr<const PluginLibrary> library_;
    talus_instance *instance_ = nullptr;
    std::vector<double> parameters_;
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

// The host's own identification passed to plugins ("talus 0.1.0").
const char *host_name();

} // namespace talus
