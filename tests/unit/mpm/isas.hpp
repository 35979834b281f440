// The instruction sets a test compares: every kernel version this machine
// runs, up to the one a run would pick (talus::kernel_isa).
#pragma once

#include "kernels/isa.hpp"

#include <vector>

inline std::vector<talus::Isa> runnable_isas() {
    using talus::Isa;
    std::vector<Isa> v{Isa::generic};
    const Isa widest = talus::kernel_isa();
    if (widest == Isa::avx2 || widest == Isa::avx512) v.push_back(Isa::avx2);
    if (widest == Isa::avx512) v.push_back(Isa::avx512);
    return v;
}
