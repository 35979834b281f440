/* The layout of every ABI structure as one list of numbers, so that the C
 * and the C++ compilers' views can be compared number by number. */
#ifndef TALUS_TEST_ABI_LAYOUT_H
#define TALUS_TEST_ABI_LAYOUT_H

#include <talus/material_abi.h>

#include <stddef.h>

#define TALUS_LAYOUT_ENTRIES 96

#define TALUS_LAYOUT_FILL(out, n)                                                                  \
    do {                                                                                           \
        size_t k_ = 0;                                                                             \
        out[k_++] = sizeof(talus_error);                                                           \
        out[k_++] = offsetof(talus_error, point_index);                                            \
        out[k_++] = offsetof(talus_error, cut_factor);                                             \
        out[k_++] = offsetof(talus_error, message);                                                \
        out[k_++] = sizeof(talus_host_info);                                                       \
        out[k_++] = offsetof(talus_host_info, abi_major);                                          \
        out[k_++] = offsetof(talus_host_info, abi_minor);                                          \
        out[k_++] = offsetof(talus_host_info, host_name);                                          \
        out[k_++] = offsetof(talus_host_info, log);                                                \
        out[k_++] = offsetof(talus_host_info, log_context);                                        \
        out[k_++] = offsetof(talus_host_info, get_extension);                                      \
        out[k_++] = sizeof(talus_param_desc);                                                      \
        out[k_++] = offsetof(talus_param_desc, type);                                              \
        out[k_++] = offsetof(talus_param_desc, flags);                                             \
        out[k_++] = offsetof(talus_param_desc, key);                                               \
        out[k_++] = offsetof(talus_param_desc, unit);                                              \
        out[k_++] = offsetof(talus_param_desc, doc);                                               \
        out[k_++] = offsetof(talus_param_desc, default_value);                                     \
        out[k_++] = offsetof(talus_param_desc, min_value);                                         \
        out[k_++] = offsetof(talus_param_desc, max_value);                                         \
        out[k_++] = offsetof(talus_param_desc, typical_value);                                     \
        out[k_++] = offsetof(talus_param_desc, min_count);                                         \
        out[k_++] = offsetof(talus_param_desc, max_count);                                         \
        out[k_++] = offsetof(talus_param_desc, default_string);                                    \
        out[k_++] = offsetof(talus_param_desc, typical_string);                                    \
        out[k_++] = sizeof(talus_state_desc);                                                      \
        out[k_++] = offsetof(talus_state_desc, flags);                                             \
        out[k_++] = offsetof(talus_state_desc, size);                                              \
        out[k_++] = offsetof(talus_state_desc, name);                                              \
        out[k_++] = offsetof(talus_state_desc, unit);                                              \
        out[k_++] = offsetof(talus_state_desc, doc);                                               \
        out[k_++] = offsetof(talus_state_desc, initial_value);                                     \
        out[k_++] = sizeof(talus_batch);                                                           \
        out[k_++] = offsetof(talus_batch, flags);                                                  \
        out[k_++] = offsetof(talus_batch, state_size);                                             \
        out[k_++] = offsetof(talus_batch, n_points);                                               \
        out[k_++] = offsetof(talus_batch, time);                                                   \
        out[k_++] = offsetof(talus_batch, dt);                                                     \
        out[k_++] = offsetof(talus_batch, strain_increment);                                       \
        out[k_++] = offsetof(talus_batch, F_start);                                                \
        out[k_++] = offsetof(talus_batch, F_end);                                                  \
        out[k_++] = offsetof(talus_batch, density);                                                \
        out[k_++] = offsetof(talus_batch, stress_start);                                           \
        out[k_++] = offsetof(talus_batch, state_start);                                            \
        out[k_++] = offsetof(talus_batch, stress_end);                                             \
        out[k_++] = offsetof(talus_batch, state_end);                                              \
        out[k_++] = offsetof(talus_batch, wave_speed);                                             \
        out[k_++] = offsetof(talus_batch, tangent);                                                \
        out[k_++] = offsetof(talus_batch, step);                                                   \
        out[k_++] = offsetof(talus_batch, point_id);                                               \
        out[k_++] = offsetof(talus_batch, characteristic_length);                                  \
        out[k_++] = offsetof(talus_batch, rotation);                                               \
        out[k_++] = sizeof(talus_model);                                                           \
        out[k_++] = offsetof(talus_model, flags);                                                  \
        out[k_++] = offsetof(talus_model, n_params);                                               \
        out[k_++] = offsetof(talus_model, n_state);                                                \
        out[k_++] = offsetof(talus_model, id);                                                     \
        out[k_++] = offsetof(talus_model, name);                                                   \
        out[k_++] = offsetof(talus_model, version);                                                \
        out[k_++] = offsetof(talus_model, doc);                                                    \
        out[k_++] = offsetof(talus_model, params);                                                 \
        out[k_++] = offsetof(talus_model, state);                                                  \
        out[k_++] = offsetof(talus_model, create);                                                 \
        out[k_++] = offsetof(talus_model, destroy);                                                \
        out[k_++] = offsetof(talus_model, update);                                                 \
        out[k_++] = offsetof(talus_model, create_ex);                                              \
        out[k_++] = offsetof(talus_model, instance_state);                                         \
        out[k_++] = offsetof(talus_model, init_state);                                             \
        out[k_++] = sizeof(talus_library);                                                         \
        out[k_++] = offsetof(talus_library, abi_major);                                            \
        out[k_++] = offsetof(talus_library, abi_minor);                                            \
        out[k_++] = offsetof(talus_library, n_models);                                             \
        out[k_++] = offsetof(talus_library, name);                                                 \
        out[k_++] = offsetof(talus_library, version);                                              \
        out[k_++] = offsetof(talus_library, models);                                               \
        out[k_++] = offsetof(talus_library, get_extension);                                        \
        out[k_++] = sizeof(talus_state_layout);                                                    \
        out[k_++] = offsetof(talus_state_layout, n_state);                                         \
        out[k_++] = offsetof(talus_state_layout, state);                                           \
        out[k_++] = sizeof(talus_param_value);                                                     \
        out[k_++] = offsetof(talus_param_value, type);                                             \
        out[k_++] = offsetof(talus_param_value, count);                                            \
        out[k_++] = offsetof(talus_param_value, scalar);                                           \
        out[k_++] = offsetof(talus_param_value, reals);                                            \
        out[k_++] = offsetof(talus_param_value, string);                                           \
        out[k_++] = sizeof(talus_create_args);                                                     \
        out[k_++] = offsetof(talus_create_args, n_values);                                         \
        out[k_++] = offsetof(talus_create_args, values);                                           \
        out[k_++] = offsetof(talus_create_args, material_name);                                    \
        out[k_++] = offsetof(talus_create_args, base_dir);                                         \
        (n) = k_;                                                                                  \
    } while (0)

#endif
