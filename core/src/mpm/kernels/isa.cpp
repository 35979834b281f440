#include "kernels/isa.hpp"

#include <talus/error.hpp>

#include <fmt/format.h>

#include <cstdlib>
#include <string_view>

namespace talus {

namespace {

bool available(Isa isa) {
#if TALUS_HAS_ISA_VERSIONS
    switch (isa) {
    case Isa::generic: return true;
    case Isa::avx2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case Isa::avx512:
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx2") &&
               __builtin_cpu_supports("fma");
    }
    return false;
#else
    return isa == Isa::generic;
#endif
}

} // namespace

const char *isa_name(Isa isa) {
    switch (isa) {
    case Isa::generic: return "generic";
    case Isa::avx2: return "avx2";
    case Isa::avx512: return "avx512";
    }
    return "?";
}

Isa kernel_isa() {
    if (const char *want = std::getenv("TALUS_KERNEL_ISA"); want && *want) {
        for (Isa isa : {Isa::generic, Isa::avx2, Isa::avx512})
            if (std::string_view(want) == isa_name(isa)) {
                if (!available(isa))
                    throw Error(fmt::format("TALUS_KERNEL_ISA={}: this CPU (or this build) has no "
                                            "{} kernels",
                                            want, want));
                return isa;
            }
        throw Error(fmt::format("TALUS_KERNEL_ISA={}: expected generic, avx2 or avx512", want));
    }
    if (available(Isa::avx512)) return Isa::avx512;
    if (available(Isa::avx2)) return Isa::avx2;
    return Isa::generic;
}

} // namespace talus
