#include <talus/material/material_spec.hpp>

namespace talus {

std::unique_ptr<MaterialInstance> instantiate(const MaterialSpec &spec) {
    return spec.model->create(spec.params, spec.context);
}

} // namespace talus
