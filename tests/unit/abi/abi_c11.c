/* The ABI header compiled as C11: layout as the C compiler sees it, with the
 * frozen sizes asserted at compile time (x86-64 / aarch64 LP64 layout). */
#include "abi_layout.h"

#include <assert.h>

_Static_assert(sizeof(void *) == 8, "the frozen layout below is the LP64 one");
_Static_assert(sizeof(talus_error) == 24 + TALUS_ERROR_MESSAGE_SIZE, "talus_error size frozen");
_Static_assert(sizeof(talus_host_info) == 24, "talus_host_info size frozen");
_Static_assert(sizeof(talus_param_desc) == 72, "talus_param_desc size frozen");
_Static_assert(sizeof(talus_state_desc) == 48, "talus_state_desc size frozen");
_Static_assert(sizeof(talus_batch) == 120, "talus_batch size frozen");
_Static_assert(sizeof(talus_model) == 88, "talus_model size frozen");
_Static_assert(sizeof(talus_library) == 40, "talus_library size frozen");

size_t talus_test_c_layout(size_t *out);
size_t talus_test_c_layout(size_t *out) {
    size_t n = 0;
    TALUS_LAYOUT_FILL(out, n);
    return n;
}
