// Where the host finds plugins (PluginRegistry): explicit paths, the
// plugin path, the user's folder and the shipped plugins, and a model's id
// resolved across the libraries loaded.
#include <talus/material/plugin_loader.hpp>

#include <talus/text.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <set>

namespace fs = std::filesystem;

namespace talus {

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
            // Regular files only: a FIFO or a folder of that name is not a
            // plugin, and opening a FIFO would block.
            if (fn.rfind("talus_", 0) == 0 && e.path().extension() == ".so" &&
                fs::is_regular_file(e.path(), ec))
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
