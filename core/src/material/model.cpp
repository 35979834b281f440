// A model of a plugin library (Model): its descriptors as the host keeps
// them, and the creation of instances with checked parameter values.
#include <talus/material/plugin_loader.hpp>

#include "descriptor_checker.hpp"
#include "fp_environment.hpp"
#include "plugin_errors.hpp"

#include <talus/material/crash_report.hpp>

#include <fmt/format.h>

namespace talus {

std::string Model::qualified_id() const { return library_->name() + "/" + id_; }

std::vector<double> Model::initial_state() const { return state_.initial(); }

std::vector<ParamValue> Model::typical_values() const {
    std::vector<ParamValue> v;
    for (const ParamInfo &p : params_)
        v.push_back(p.typical_param());
    return v;
}

std::unique_ptr<MaterialInstance> Model::create(std::span<const double> values) const {
    std::vector<ParamValue> typed(values.size());
    for (std::size_t i = 0; i < values.size(); ++i)
        typed[i].scalar = values[i];
    return create(typed);
}

std::unique_ptr<MaterialInstance> Model::create(std::span<const ParamValue> values,
                                                const CreateContext &context) const {
    if (values.size() != params_.size())
        throw Error(fmt::format("model '{}': {} parameter values given, {} expected", id_,
                                values.size(), params_.size()));
    talus_error err = fresh_error();
    talus_instance *inst = nullptr;
    std::int32_t status = TALUS_STATUS_FAILED;
    try {
        const crash::PluginCall call(id_.c_str(), library_->path().c_str());
        const FpGuard fp(*library_, id_.c_str(), "create");
        if (create_ex_) {
            std::vector<talus_param_value> raw(values.size());
            std::vector<const talus_param_value *> ptrs(values.size());
            for (std::size_t i = 0; i < values.size(); ++i) {
                const ParamInfo &p = params_[i];
                talus_param_value &v = raw[i];
                v.struct_size = sizeof v;
                v.type = p.type;
                v.count = p.type == TALUS_PARAM_REAL_ARRAY ? values[i].reals.size()
                          : p.type == TALUS_PARAM_STRING   ? values[i].text.size()
                                                           : 1;
                v.scalar = values[i].scalar;
                v.reals = values[i].reals.empty() ? nullptr : values[i].reals.data();
                v.string = values[i].text.c_str();
                ptrs[i] = &v;
            }
            talus_create_args args{};
            args.struct_size = sizeof args;
            args.n_values = static_cast<std::uint32_t>(values.size());
            args.values = ptrs.data();
            args.material_name = context.material_name.c_str();
            args.base_dir = context.base_dir.c_str();
            status = create_ex_(&args, &inst, &err);
        } else {
            std::vector<double> scalars(values.size());
            for (std::size_t i = 0; i < values.size(); ++i)
                scalars[i] = values[i].scalar;
            status = raw_->create(scalars.data(), static_cast<std::uint32_t>(scalars.size()), &inst,
                                  &err);
        }
    } catch (...) {
        throw Error(fmt::format("model '{}' ({}): create threw an exception across the C ABI", id_,
                                library_->path().string()));
    }
    if (status != TALUS_STATUS_OK || !inst)
        throw Error(fmt::format("model '{}' rejected its parameters: {}", id_,
                                status == TALUS_STATUS_OK ? "create returned no instance"
                                                          : read_message(err)));
    std::unique_ptr<MaterialInstance> out(new MaterialInstance());
    out->model_ = this;
    out->library_ = library_->shared_from_this();
    out->instance_ = inst;
    out->parameters_.assign(values.begin(), values.end());
    if (instance_state()) {
        // Destroyed by `out` if the layout is refused.
        talus_state_layout layout{};
        layout.struct_size = sizeof layout;
        err = fresh_error();
        try {
            const crash::PluginCall call(id_.c_str(), library_->path().c_str());
            const FpGuard fp(*library_, id_.c_str(), "instance_state");
            status = instance_state_(inst, &layout, &err);
        } catch (...) {
            throw Error(fmt::format("model '{}' ({}): instance_state threw an exception across "
                                    "the C ABI",
                                    id_, library_->path().string()));
        }
        if (status != TALUS_STATUS_OK)
            throw Error(
                fmt::format("model '{}' could not describe its state: {}", id_, read_message(err)));
        const DescriptorChecker chk{library_->path()};
        out->state_ =
            chk.layout(layout.state, layout.n_state, fmt::format("model '{}' instance state", id_));
    }
    return out;
}

} // namespace talus
