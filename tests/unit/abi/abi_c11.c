/* The ABI header compiled as C11: layout as the C compiler sees it, with the
 * frozen sizes asserted at compile time (x86-64 / aarch64 LP64 layout). */
#include "abi_layout.h"

#include <assert.h>

_Static_assert(sizeof(void *) == 8, "the frozen layout below is the LP64 one");
_Static_assert(sizeof(talus_error) == 24 + TALUS_ERROR_MESSAGE_SIZE, "talus_error size frozen");
/* ABI 1.0 sizes are where the first 1.1 field begins (append-only), then
 * the 1.1 sizes. */
_Static_assert(offsetof(talus_host_info, log) == 24, "talus_host_info 1.0 size frozen");
_Static_assert(sizeof(talus_host_info) == 48, "talus_host_info size frozen");
_Static_assert(offsetof(talus_param_desc, min_count) == 72, "talus_param_desc 1.0 size frozen");
_Static_assert(sizeof(talus_param_desc) == 96, "talus_param_desc size frozen");
_Static_assert(sizeof(talus_state_desc) == 48, "talus_state_desc size frozen");
_Static_assert(offsetof(talus_batch, step) == 120, "talus_batch 1.0 size frozen");
_Static_assert(sizeof(talus_batch) == 152, "talus_batch size frozen");
_Static_assert(offsetof(talus_model, create_ex) == 88, "talus_model 1.0 size frozen");
_Static_assert(sizeof(talus_model) == 112, "talus_model size frozen");
_Static_assert(offsetof(talus_library, get_extension) == 40, "talus_library 1.0 size frozen");
_Static_assert(sizeof(talus_library) == 48, "talus_library size frozen");
_Static_assert(sizeof(talus_state_layout) == 16, "talus_state_layout size frozen");
_Static_assert(sizeof(talus_param_value) == 40, "talus_param_value size frozen");
_Static_assert(sizeof(talus_create_args) == 32, "talus_create_args size frozen");

size_t talus_test_c_layout(size_t *out);
size_t talus_test_c_layout(size_t *out) {
    size_t n = 0;
    TALUS_LAYOUT_FILL(out, n);
    return n;
}
