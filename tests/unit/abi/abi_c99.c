/* The ABI promises C99: this translation unit only has to compile, with
 * -std=c99 -pedantic and warnings as errors. */
#include <talus/material_abi.h>

int talus_test_c99_major(void);
int talus_test_c99_major(void) { return TALUS_ABI_VERSION_MAJOR; }
