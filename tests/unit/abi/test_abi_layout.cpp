// Freezes the ABI: sizes and offsets of every structure (a change here is a
// new ABI major), the C and C++ views agreeing, and the conventions the
// header states (Voigt order, status codes, flags).
#include "abi_layout.h"

#include <talus/sdk/voigt.hpp>

#include <gtest/gtest.h>

#include <cstddef>

extern "C" size_t talus_test_c_layout(size_t *out);
extern "C" int talus_test_c99_major(void);

static_assert(sizeof(void *) == 8, "the frozen layout below is the LP64 one");
static_assert(sizeof(talus_error) == 24 + TALUS_ERROR_MESSAGE_SIZE);
static_assert(offsetof(talus_error, point_index) == 8);
static_assert(offsetof(talus_error, cut_factor) == 16);
static_assert(offsetof(talus_error, message) == 24);
// 1.0 sizes stay where the 1.1 fields begin (append-only).
static_assert(offsetof(talus_host_info, log) == 24);
static_assert(offsetof(talus_host_info, log_context) == 32);
static_assert(offsetof(talus_host_info, get_extension) == 40);
static_assert(sizeof(talus_host_info) == 48);
static_assert(offsetof(talus_host_info, host_name) == 16);
static_assert(offsetof(talus_param_desc, min_count) == 72);
static_assert(offsetof(talus_param_desc, max_count) == 76);
static_assert(offsetof(talus_param_desc, default_string) == 80);
static_assert(offsetof(talus_param_desc, typical_string) == 88);
static_assert(sizeof(talus_param_desc) == 96);
static_assert(offsetof(talus_param_desc, key) == 16);
static_assert(offsetof(talus_param_desc, default_value) == 40);
static_assert(offsetof(talus_param_desc, typical_value) == 64);
static_assert(sizeof(talus_state_desc) == 48);
static_assert(offsetof(talus_state_desc, name) == 16);
static_assert(offsetof(talus_state_desc, initial_value) == 40);
static_assert(offsetof(talus_batch, step) == 120);
static_assert(offsetof(talus_batch, point_id) == 128);
static_assert(offsetof(talus_batch, characteristic_length) == 136);
static_assert(offsetof(talus_batch, rotation) == 144);
static_assert(sizeof(talus_batch) == 152);
static_assert(offsetof(talus_batch, n_points) == 16);
static_assert(offsetof(talus_batch, time) == 24);
static_assert(offsetof(talus_batch, dt) == 32);
static_assert(offsetof(talus_batch, strain_increment) == 40);
static_assert(offsetof(talus_batch, F_start) == 48);
static_assert(offsetof(talus_batch, F_end) == 56);
static_assert(offsetof(talus_batch, density) == 64);
static_assert(offsetof(talus_batch, stress_start) == 72);
static_assert(offsetof(talus_batch, state_start) == 80);
static_assert(offsetof(talus_batch, stress_end) == 88);
static_assert(offsetof(talus_batch, state_end) == 96);
static_assert(offsetof(talus_batch, wave_speed) == 104);
static_assert(offsetof(talus_batch, tangent) == 112);
static_assert(offsetof(talus_model, create_ex) == 88);
static_assert(offsetof(talus_model, instance_state) == 96);
static_assert(offsetof(talus_model, init_state) == 104);
static_assert(sizeof(talus_model) == 112);
static_assert(offsetof(talus_model, id) == 16);
static_assert(offsetof(talus_model, params) == 48);
static_assert(offsetof(talus_model, create) == 64);
static_assert(offsetof(talus_model, update) == 80);
static_assert(offsetof(talus_library, get_extension) == 40);
static_assert(sizeof(talus_library) == 48);
static_assert(sizeof(talus_state_layout) == 16);
static_assert(offsetof(talus_state_layout, state) == 8);
static_assert(sizeof(talus_param_value) == 40);
static_assert(offsetof(talus_param_value, count) == 8);
static_assert(offsetof(talus_param_value, scalar) == 16);
static_assert(offsetof(talus_param_value, reals) == 24);
static_assert(offsetof(talus_param_value, string) == 32);
static_assert(sizeof(talus_create_args) == 32);
static_assert(offsetof(talus_create_args, values) == 8);
static_assert(offsetof(talus_create_args, material_name) == 16);
static_assert(offsetof(talus_create_args, base_dir) == 24);
static_assert(offsetof(talus_library, name) == 16);
static_assert(offsetof(talus_library, models) == 32);

TEST(Abi, CAndCxxSeeTheSameLayout) {
    size_t c[TALUS_LAYOUT_ENTRIES] = {};
    size_t cxx[TALUS_LAYOUT_ENTRIES] = {};
    const size_t nc = talus_test_c_layout(c);
    size_t ncxx = 0;
    TALUS_LAYOUT_FILL(cxx, ncxx);
    ASSERT_EQ(nc, ncxx);
    ASSERT_LE(nc, static_cast<size_t>(TALUS_LAYOUT_ENTRIES));
    for (size_t i = 0; i < nc; ++i)
        EXPECT_EQ(c[i], cxx[i]) << "layout entry " << i;
}

TEST(Abi, VersionAndCodesAreFrozen) {
    EXPECT_EQ(talus_test_c99_major(), TALUS_ABI_VERSION_MAJOR);
    EXPECT_EQ(TALUS_ABI_VERSION_MAJOR, 1);
    EXPECT_EQ(TALUS_STATUS_OK, 0);
    EXPECT_EQ(TALUS_STATUS_FAILED, 1);
    EXPECT_EQ(TALUS_STATUS_CUT_STEP, 2);
    EXPECT_EQ(TALUS_PARAM_REQUIRED, 1u);
    EXPECT_EQ(TALUS_PARAM_MIN_EXCLUSIVE, 2u);
    EXPECT_EQ(TALUS_PARAM_MAX_EXCLUSIVE, 4u);
    EXPECT_EQ(TALUS_STATE_OUTPUT, 1u);
    EXPECT_EQ(TALUS_STATE_USER_INIT, 2u);
    EXPECT_EQ(TALUS_BATCH_WANT_WAVE_SPEED, 1u);
    EXPECT_EQ(TALUS_BATCH_WANT_TANGENT, 2u);
    EXPECT_EQ(TALUS_MODEL_FINITE_STRAIN, 1u);
    EXPECT_EQ(TALUS_MODEL_TANGENT, 2u);
    // ABI 1.1
    EXPECT_GE(TALUS_ABI_VERSION_MINOR, 1);
    EXPECT_EQ(TALUS_MODEL_NOT_REENTRANT, 4u);
    EXPECT_EQ(TALUS_MODEL_INSTANCE_STATE, 8u);
    EXPECT_EQ(TALUS_MODEL_WANTS_ROTATION, 16u);
    EXPECT_EQ(TALUS_PARAM_REAL_ARRAY, 3u);
    EXPECT_EQ(TALUS_PARAM_STRING, 4u);
    EXPECT_EQ(TALUS_LOG_INFO, 0);
    EXPECT_EQ(TALUS_LOG_WARNING, 1);
    EXPECT_STREQ(TALUS_MATERIAL_ENTRY_SYMBOL, "talus_material_entry");
    // ABI 1.2
    EXPECT_EQ(TALUS_ABI_VERSION_MINOR, 2);
    EXPECT_EQ(TALUS_BATCH_INPUTS_FINITE, 4u);
}

// The header states Voigt order xx, yy, zz, xy, yz, xz with engineering shear
// strain; the SDK's conversions must say the same.
TEST(Abi, VoigtConventionOfTheSdk) {
    EXPECT_EQ(talus::sdk::voigt_index(0, 0), 0);
    EXPECT_EQ(talus::sdk::voigt_index(1, 1), 1);
    EXPECT_EQ(talus::sdk::voigt_index(2, 2), 2);
    EXPECT_EQ(talus::sdk::voigt_index(0, 1), 3);
    EXPECT_EQ(talus::sdk::voigt_index(1, 2), 4);
    EXPECT_EQ(talus::sdk::voigt_index(0, 2), 5);
    EXPECT_EQ(talus::sdk::voigt_index(2, 0), 5);
    talus::sdk::Vec6 gamma;
    gamma << 1, 2, 3, 4, 5, 6;
    const talus::sdk::Mat3 eps = talus::sdk::strain_to_matrix(gamma);
    EXPECT_EQ(eps(0, 1), 2.0); // engineering shear 4 -> tensor 2
    EXPECT_EQ(eps(1, 2), 2.5);
    EXPECT_EQ(eps(0, 2), 3.0);
    const talus::sdk::Mat3 sig = talus::sdk::stress_to_matrix(gamma);
    EXPECT_EQ(sig(0, 1), 4.0); // stress keeps tensor components
    EXPECT_EQ(sig(2, 1), 5.0);
    EXPECT_EQ(talus::sdk::matrix_to_strain(eps), gamma);
    EXPECT_EQ(talus::sdk::matrix_to_stress(sig), gamma);
}
