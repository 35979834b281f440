// The error record of one call into a plugin: fresh before the call, its
// message read after (the plugin may fill the buffer without a NUL).
// Internal to the material layer.
#pragma once

#include <talus/material_abi.h>

#include <cstring>
#include <string>

namespace talus {

inline std::string read_message(const talus_error &e) {
    // The plugin may have filled the whole buffer without a NUL.
    return std::string(e.message, strnlen(e.message, sizeof(e.message)));
}

inline talus_error fresh_error() {
    talus_error e{};
    e.struct_size = sizeof(talus_error);
    e.point_index = -1;
    e.cut_factor = 1.0;
    return e;
}

} // namespace talus
