// talus plugin info: a library's models, or one model by its id, as text
// or as its reference page in Markdown (docs/materials/).
#include "commands.hpp"

#include "../model_markdown.hpp"

#include <talus/error.hpp>
#include <talus/io/output_file.hpp>

#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <sstream>

namespace talus::cli {

namespace {

std::string wrap(const std::string &text, std::size_t indent, std::size_t width = 78) {
    std::istringstream words(text);
    std::string word, line, out;
    const std::string pad(indent, ' ');
    while (words >> word) {
        if (!line.empty() && line.size() + 1 + word.size() > width - indent) {
            out += pad + line + '\n';
            line.clear();
        }
        line += (line.empty() ? "" : " ") + word;
    }
    if (!line.empty()) out += pad + line + '\n';
    return out;
}

void print_model(std::ostream &out, const Model &m) {
    out << fmt::format("model {} {}: {}\n", m.id(), m.version(), m.name());
    out << wrap(m.doc(), 2);
    out << fmt::format("  kinematics: {}; tangent: {}\n",
                       m.finite_strain() ? "finite strain (uses F, owns its objectivity)"
                                         : "strain increment (host rotates stress objectively)",
                       m.has_tangent() ? "consistent tangent provided" : "not provided");
    out << fmt::format("  qualified id: {}; set-up call: {}; threads: {}{}\n", m.qualified_id(),
                       m.has_init_state() ? "init_state" : "update with dt = 0",
                       m.reentrant() ? "reentrant"
                                     : "NOT reentrant (called from one thread at a time)",
                       m.wants_rotation() ? "; is given each increment's rotation" : "");
    out << "  parameters (YAML keys of the material, beside model and density):\n";
    if (m.params().empty()) out << "    none\n";
    for (const ParamInfo &p : m.params()) {
        out << fmt::format("    {:<20} [{}] {}, {}\n", p.key, p.unit, p.type_name(),
                           p.required() ? "required"
                                        : "default " + p.value_text(p.default_param()));
        if (p.type == TALUS_PARAM_STRING)
            out << fmt::format("      example: {}\n", p.value_text(p.typical_param()));
        else if (p.type == TALUS_PARAM_REAL_ARRAY)
            out << fmt::format("      {}, each {}; example: {}\n", p.count_text(), p.bounds_text(),
                               p.value_text(p.typical_param()));
        else
            out << fmt::format("      bounds: {}; example: {}\n", p.bounds_text(),
                               p.value_text(p.typical_param()));
        out << wrap(p.doc, 6);
    }
    out << "  state variables:\n";
    if (m.instance_state())
        out << "    set per material from its parameters (the instance's layout)\n";
    else if (m.state().empty())
        out << "    none\n";
    for (const StateInfo &s : m.state()) {
        std::string flags;
        if (s.output()) flags += ", written to output";
        if (s.user_initialisable()) flags += ", user-initialisable";
        out << fmt::format("    {:<20} [{}] {} component{}, initially {:g}{}\n", s.name, s.unit,
                           s.size, s.size == 1 ? "" : "s", s.initial_value, flags);
        out << wrap(s.doc, 6);
    }
}

void print_library(std::ostream &out, const PluginLibrary &lib) {
    out << fmt::format("library {} {} (material ABI {}.{})\n  {}\n  build: {}\n", lib.name(),
                       lib.version(), lib.abi_major(), lib.abi_minor(), lib.path().string(),
                       lib.build_text());
    for (const Model &m : lib.models()) {
        out << '\n';
        print_model(out, m);
    }
}

class PluginInfo final : public Command {
  public:
    explicit PluginInfo(CLI::App &plugin)
        : Command(plugin.add_subcommand("info",
                                        "Describe a plugin library, or the model with this id")) {
        app_->add_option("target", target_, "Library path or name, or a model id")
            ->required()
            ->type_name("LIB_OR_MODEL");
        app_->add_flag("--markdown", markdown_,
                       "Print each model's reference page in Markdown (docs/materials/)");
        app_->add_option("--output-dir", markdown_dir_,
                         "With --markdown: write one MODEL_ID.md per model into this folder")
            ->type_name("DIR");
    }
    int run(Context &ctx) override;

  private:
    int write_markdown(PluginRegistry &registry, const std::filesystem::path &library) const;

    std::string target_, markdown_dir_;
    bool markdown_ = false;
};

int PluginInfo::write_markdown(PluginRegistry &registry,
                               const std::filesystem::path &library) const {
    std::vector<const Model *> models;
    if (!library.empty())
        for (const Model &m : registry.load(library.string()).models())
            models.push_back(&m);
    else
        models.push_back(&registry.find_model(target_));
    for (const Model *m : models) {
        const std::string page = model_markdown(*m);
        if (markdown_dir_.empty()) {
            std::cout << page;
        } else {
            const auto file = std::filesystem::path(markdown_dir_) / (m->id() + ".md");
            write_file_atomically(file, page);
            std::cerr << fmt::format("talus: wrote {}\n", file.string());
        }
    }
    return 0;
}

int PluginInfo::run(Context &ctx) {
    PluginRegistry &registry = ctx.registry;
    // A path, or a bare word that names a library file on the search path,
    // is a library (whose load errors are reported); any other word is a
    // model id.
    std::filesystem::path library;
    if (PluginRegistry::is_path(target_)) {
        library = registry.locate(target_);
    } else {
        try {
            library = registry.locate(target_);
        } catch (const Error &) {
        }
    }
    if (markdown_) return write_markdown(registry, library);
    if (!markdown_dir_.empty()) throw Error("--output-dir goes with --markdown");
    if (!library.empty()) {
        print_library(std::cout, registry.load(library.string()));
        return 0;
    }
    const Model &m = registry.find_model(target_);
    std::cout << fmt::format("(from {} {}, {}; build: {})\n\n", m.library().name(),
                             m.library().version(), m.library().path().string(),
                             m.library().build_text());
    print_model(std::cout, m);
    return 0;
}

} // namespace

std::unique_ptr<Command> plugin_info_command(CLI::App &plugin) {
    return std::make_unique<PluginInfo>(plugin);
}

} // namespace talus::cli
