// Reading a scenario from YAML with errors at file:line:column.
#pragma once

#include <talus/input/yaml_input.hpp>
#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/scenario.hpp>

#include <string>
#include <vector>

namespace talus {

// Reads and validates a scenario; loads the plugins it needs into
// `registry` and checks that each plugin accepts its material's parameters
// (by making an instance and dropping it). Throws talus::Error with
// file:line:column on the first problem.
Scenario read_scenario(const yaml::Node &root, PluginRegistry &registry);

// Every key the reader accepts, as dotted paths with '*' for user-chosen
// names ("groups.*.shape.box.min"), for the documentation test.
std::vector<std::string> scenario_schema();

} // namespace talus
