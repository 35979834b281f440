// A material as a user writes it in YAML (input/material_yaml.hpp reads
// it): a model, the host-owned density, the model's parameters (checked
// against the plugin's own metadata) and, optionally, initial values of
// user-initialisable state variables. Plain data: the plugin's instance is
// made from it by whoever runs the material (instantiate()).
//
//   sand:
//     model: mohr_coulomb
//     density: 1800          # kg/m^3, owned by the host: it makes the mass
//     youngs_modulus: 2e7
//     ...
//     initial_state: {void_ratio: 0.7}
#pragma once

#include <talus/material/plugin_loader.hpp>

#include <memory>
#include <string>
#include <vector>

namespace talus {

struct MaterialSpec {
    std::string name; // the YAML key path, for messages
    const Model *model = nullptr;
    double density = 0.0;              // reference (initial) density
    std::vector<ParamValue> params;    // in the order of model->params()
    CreateContext context;             // the user's name and the file's folder
    StateLayout state;                 // the points' state layout (the model's or,
                                       // for an instance-state model, its instance's)
    std::vector<double> initial_state; // one point's state at t = 0
};

// The plugin's instance for these parameters; throws talus::Error with the
// plugin's message if it rejects them.
std::unique_ptr<MaterialInstance> instantiate(const MaterialSpec &spec);

} // namespace talus
