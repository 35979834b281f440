// The instruction sets the transfer kernels are compiled for, and the one
// a run uses: the widest this CPU has, chosen once at set-up. The release
// build stays portable (any x86-64); its P2G and G2P kernels exist in three
// versions (function-level target attributes, see p2g_kernels.hpp and
// g2p_kernels.hpp).
// TALUS_KERNEL_ISA=generic|avx2|avx512 forces one (tests, comparisons);
// asking for one the CPU lacks is refused.
#pragma once

namespace talus {

enum class Isa { generic, avx2, avx512 };

// The widest available, or TALUS_KERNEL_ISA; throws talus::Error for an
// unknown or unavailable name.
Isa kernel_isa();
const char *isa_name(Isa isa);

} // namespace talus

// The function attributes of the kernel versions; empty where the compiler
// or the target has no such versions, or the build leaves them out
// (TALUS_KERNEL_ISA_VERSIONS=OFF): then every Isa runs the generic one, and
// kernel_isa() offers no other.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) &&                            \
    !defined(TALUS_NO_ISA_VERSIONS)
#define TALUS_HAS_ISA_VERSIONS 1
#define TALUS_TARGET_AVX2 __attribute__((target("avx2,fma")))
#define TALUS_TARGET_AVX512 __attribute__((target("avx512f,avx2,fma")))
#else
#define TALUS_HAS_ISA_VERSIONS 0
#define TALUS_TARGET_AVX2
#define TALUS_TARGET_AVX512
#endif
