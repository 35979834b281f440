// talus validate: everything `talus run` decides before its first step, by
// the same code, without running.
#include "commands.hpp"

#include <talus/driver/run.hpp>
#include <talus/input/scenario_yaml.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/io/checkpoint.hpp>

#include <fmt/format.h>

#include <iostream>

namespace talus::cli {

namespace {

class Validate final : public Command {
  public:
    explicit Validate(CLI::App &parent)
        : Command(parent.add_subcommand("validate", "Check a scenario file without running it")) {
        app_->add_option("scenario", file_, "Scenario file (YAML)")
            ->required()
            ->type_name("SCENARIO.yaml");
    }
    bool calls_plugins() const override { return true; }
    int run(Context &ctx) override {
        refuse_wrong_file(file_, YamlKind::scenario, "validate");
        const yaml::Node root = yaml::load_file(file_);
        Scenario sc = read_scenario(root, ctx.registry);
        const Prepared prep = prepare_run(sc, {});
        const RunPlan &plan = prep.plan;
        const bool quiet = ctx.verbosity == Verbosity::quiet;
        // Quiet: the warnings, and the exit status.
        for (const std::string &n : plan.notes)
            if (!quiet || n.substr(0, n.find('\n')).find("warning:") != std::string::npos)
                std::cerr << n << '\n';
        for (const std::string &w : plan.over_limits)
            std::cerr << w << " (`talus run` refuses this unless --allow-large)\n";
        if (ctx.verbosity == Verbosity::verbose)
            for (const PluginIdentity &p : plugin_identities(sc))
                std::cerr << describe(p) << '\n';
        if (quiet) return 0;
        std::cout << fmt::format(
            "{}: valid ({}D, {} material(s), {} group(s)): {} particles, {:.3g} grid nodes, about "
            "{:.3g} MB; about {:.3g} steps of {:.3g} s{}\n",
            file_, sc.dim, sc.materials.size(), sc.groups.size(), plan.particles,
            plan.estimate.nodes, plan.estimate.bytes / 1e6, plan.steps, plan.first_dt,
            plan.output_files > 0 ? fmt::format(", {:.3g} VTK files", plan.output_files)
                                  : std::string());
        return 0;
    }

  private:
    std::string file_;
};

} // namespace

std::unique_ptr<Command> validate_command(CLI::App &parent) {
    return std::make_unique<Validate>(parent);
}

} // namespace talus::cli
