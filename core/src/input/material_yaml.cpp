#include <talus/input/material_yaml.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>

namespace talus {

MaterialSpec read_material(const yaml::Node &node, PluginRegistry &registry) {
    node.expect_map();
    MaterialSpec spec;
    spec.name = node.path();

    const yaml::Node model_node = node.require("model");
    const std::string id = model_node.as_string();
    try {
        spec.model = &registry.find_model(id);
    } catch (const Error &e) {
        model_node.fail(e.what());
    }
    const Model &model = *spec.model;

    std::vector<std::string_view> allowed = {"model", "density"};
    for (const ParamInfo &p : model.params())
        allowed.push_back(p.key);
    const bool any_user_state =
        std::any_of(model.state().begin(), model.state().end(),
                    [](const StateInfo &s) { return s.user_initialisable(); });
    if (any_user_state) allowed.push_back("initial_state");
    node.allow_keys(allowed);

    const yaml::Node rho = node.require("density");
    spec.density = rho.as_double();
    if (!(spec.density > 0.0))
        rho.fail(fmt::format("expected density > 0 (kg/m^3), got {}", spec.density));

    for (const ParamInfo &p : model.params()) {
        const yaml::Node v = node.get(p.key);
        if (!v.raw().IsDefined()) {
            if (p.required())
                node.fail(fmt::format("missing required parameter '{}' of model '{}': {} (unit {}, "
                                      "expected {}, e.g. {:g})",
                                      p.key, id, p.doc, p.unit, p.bounds_text(), p.typical_value));
            spec.param_values.push_back(p.default_value);
            continue;
        }
        double value = 0.0;
        switch (p.type) {
        case TALUS_PARAM_INTEGER: value = static_cast<double>(v.as_integer()); break;
        case TALUS_PARAM_BOOLEAN: value = v.as_bool() ? 1.0 : 0.0; break;
        default: value = v.as_double(); break;
        }
        const std::string why = check_parameter(p, value);
        if (!why.empty()) v.fail(fmt::format("value {:g} is out of range: {}", value, why));
        spec.param_values.push_back(value);
    }

    spec.initial_state = model.initial_state();
    if (const yaml::Node init = node.get("initial_state"); init.defined()) {
        std::vector<std::string_view> settable;
        for (const StateInfo &s : model.state())
            if (s.user_initialisable()) settable.push_back(s.name);
        init.allow_keys(settable);
        for (const StateInfo &s : model.state()) {
            const yaml::Node v = init.get(s.name);
            if (!v.raw().IsDefined()) continue;
            std::vector<double> values;
            if (v.is_sequence())
                values = v.as_doubles();
            else
                values.assign(s.size, v.as_double());
            if (values.size() != s.size)
                v.fail(fmt::format("expected {} values for state variable '{}', got {}", s.size,
                                   s.name, values.size()));
            std::copy(values.begin(), values.end(), spec.initial_state.begin() + s.offset);
        }
    }
    return spec;
}

void load_plugin_list(const yaml::Node &list, PluginRegistry &registry) {
    list.expect_sequence();
    for (std::size_t i = 0; i < list.size(); ++i) {
        const yaml::Node p = list.at(i);
        std::string name = p.as_string();
        // A relative path is relative to the file, not the working directory.
        if (name.find('/') != std::string::npos && !std::filesystem::path(name).is_absolute())
            name = (std::filesystem::path(list.file()).parent_path() / name).string();
        try {
            registry.load(name);
        } catch (const Error &e) {
            p.fail(e.what());
        }
    }
}

std::unique_ptr<MaterialInstance> instantiate(const MaterialSpec &spec, const yaml::Node &node) {
    try {
        return spec.model->create(spec.param_values);
    } catch (const Error &e) {
        node.fail(e.what());
    }
}

} // namespace talus
