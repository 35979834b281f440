// A material as a user writes it in YAML: a model id, the host-owned density,
// the model's parameters (checked against the plugin's own metadata) and,
// optionally, initial values of user-initialisable state variables.
//
//   sand:
//     model: mohr_coulomb
//     density: 1800          # kg/m^3, owned by the host: it makes the mass
//     youngs_modulus: 2e7
//     ...
//     initial_state: {void_ratio: 0.7}
#pragma once

#include <talus/plugin_loader.hpp>
#include <talus/yaml_input.hpp>

#include <memory>
#include <string>
#include <vector>

namespace talus {

struct MaterialSpec {
    std::string name; // the YAML key path, for messages
    const Model *model = nullptr;
    double density = 0.0;              // reference (initial) density
    std::vector<double> param_values;  // in the order of model->params()
    std::vector<double> initial_state; // one point's state at t = 0
};

// Reads and validates a material mapping. Every error names file:line:column,
// the key, and what was expected; unknown keys get a "did you mean".
MaterialSpec read_material(const yaml::Node &node, PluginRegistry &registry);

// Loads the libraries of a `plugins:` list (names, or paths relative to the
// file the list is in), each error at its entry's location.
void load_plugin_list(const yaml::Node &list, PluginRegistry &registry);

// Creates the plugin instance; a parameter combination the plugin rejects is
// reported at the material's location in the file.
std::unique_ptr<MaterialInstance> instantiate(const MaterialSpec &spec, const yaml::Node &node);

} // namespace talus
