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
    // An instance-state model's variables are known only once its instance
    // exists: `initial_state` is then checked against them below.
    const bool any_user_state =
        model.instance_state() ||
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
                node.fail(fmt::format(
                    "missing required parameter '{}' of model '{}': {} (unit {}, "
                    "{}, e.g. {})",
                    p.key, id, p.doc, p.unit,
                    p.type == TALUS_PARAM_STRING ? "a string"
                    : p.type == TALUS_PARAM_REAL_ARRAY
                        ? fmt::format("a list of {}, each {}", p.count_text(), p.bounds_text())
                        : "expected " + p.bounds_text(),
                    p.value_text(p.typical_param())));
            spec.params.push_back(p.default_param());
            continue;
        }
        ParamValue value;
        switch (p.type) {
        case TALUS_PARAM_INTEGER: value.scalar = static_cast<double>(v.as_integer()); break;
        case TALUS_PARAM_BOOLEAN: value.scalar = v.as_bool() ? 1.0 : 0.0; break;
        case TALUS_PARAM_REAL_ARRAY:
            if (!v.is_sequence())
                v.fail(fmt::format("expected a list of {} (e.g. [{:g}, {:g}])", p.count_text(),
                                   p.typical_value, p.typical_value));
            value.reals = v.as_doubles();
            break;
        case TALUS_PARAM_STRING: value.text = v.as_string(); break;
        default: value.scalar = v.as_double(); break;
        }
        const std::string why = check_parameter(p, value);
        if (!why.empty())
            v.fail(fmt::format("value {} is out of range: {}", p.value_text(value), why));
        spec.params.push_back(std::move(value));
    }
    spec.context.material_name = spec.name;
    // Absolute: a file named relative to it never resolves through a
    // search path, nor against another working folder.
    spec.context.base_dir =
        std::filesystem::absolute(std::filesystem::path(node.file())).parent_path().string();

    // An instance-state model's layout depends on its parameters: ask an
    // instance (the plugin's verdict on the parameters, at their place).
    if (model.instance_state())
        spec.state = instantiate(spec, node)->state();
    else
        spec.state = model.state_layout();
    spec.initial_state = spec.state.initial();
    if (const yaml::Node init = node.get("initial_state"); init.defined()) {
        std::vector<std::string_view> settable;
        for (const StateInfo &s : spec.state.vars)
            if (s.user_initialisable()) settable.push_back(s.name);
        if (settable.empty())
            init.fail(fmt::format("model '{}' has no state variable a user may initialise", id));
        init.allow_keys(settable);
        for (const StateInfo &s : spec.state.vars) {
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
        return spec.model->create(spec.params, spec.context);
    } catch (const Error &e) {
        node.fail(e.what());
    }
}

} // namespace talus
