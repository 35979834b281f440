// talus plugin check: the conformance suite on a plugin library
// (tools/plugin_check), each check in a child process unless --no-isolate.
#include "commands.hpp"

#include <talus/error.hpp>
#include <talus/plugin_check/conformance.hpp>

#include <fmt/format.h>

#include <iostream>

namespace talus::cli {

namespace {

class PluginCheck final : public Command {
  public:
    explicit PluginCheck(CLI::App &plugin)
        : Command(plugin.add_subcommand("check", "Run the conformance suite on a plugin library")) {
        app_->add_option("library", target_, "Library path or name")->required()->type_name("LIB");
        app_->add_option("--param", params_,
                         "Override a parameter's typical value for the checks (repeatable)")
            ->type_name("KEY=VALUE");
        app_->add_option("--strain-scale", opt_.strain_scale,
                         "Strain increment of the loading paths (default 1e-4)")
            ->check(kPositive);
        app_->add_option("--density", opt_.density,
                         "Density of the test point in kg/m^3 (default 2000)")
            ->check(kPositive);
        app_->add_flag("--no-isolate", no_isolate_,
                       "Run the checks in this process (for debugging a plugin under gdb)");
    }
    int run(Context &ctx) override {
        for (const std::string &kv : params_) {
            const auto eq = kv.find('=');
            if (eq == std::string::npos || eq == 0)
                throw Error(fmt::format("--param {}: expected KEY=VALUE", kv));
            // Parsed by the parameter's type once the model is known.
            opt_.params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
        }
        opt_.isolate = !no_isolate_;
        if (is_yaml_name(target_))
            throw Error(fmt::format(
                "{}: `talus plugin check` checks a plugin library (a .so file, or its name on the "
                "plugin path), not a YAML file; {}",
                target_,
                yaml_kind(target_) == YamlKind::scenario
                    ? fmt::format("this is a scenario: `talus validate {}` checks it", target_)
                    : fmt::format("a driver case runs with `talus point {}`", target_)));
        // Resolve a name through the search path, but do not load it here:
        // the checks load it themselves (in a child process).
        const std::filesystem::path file = ctx.registry.locate(target_);
        const ConformanceReport rep = check_plugin(file, opt_);
        print_report(std::cout, rep);
        return rep.passed() ? 0 : 1;
    }

  private:
    std::string target_;
    std::vector<std::string> params_;
    CheckOptions opt_;
    bool no_isolate_ = false;
};

} // namespace

std::unique_ptr<Command> plugin_check_command(CLI::App &plugin) {
    return std::make_unique<PluginCheck>(plugin);
}

} // namespace talus::cli
