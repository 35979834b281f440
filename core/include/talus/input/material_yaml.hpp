// Reading a material and a plugins list from YAML (material_spec.hpp has
// the example).
#pragma once

#include <talus/input/yaml_input.hpp>
#include <talus/material/material_spec.hpp>

#include <memory>

namespace talus {

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
