// A seam for measuring the plugin path: a block of points updated by the
// host itself instead of by the plugin (SolverOptions::material_hook).
#pragma once

#include <cstddef>

namespace talus {

class MaterialInstance;

// A replacement for the plugin call on one block of a material's points:
// the start stress, engineering strain increment and density of `count`
// points in, the end stress and wave speed out (the ABI's layouts). It
// returns false, having written nothing, to leave the block to the plugin.
// For talus_bench's plugin-overhead A/B (bench/README.md): it sees no
// state, no F, no cut step, so it serves only a stateless model.
using MaterialBlockHook = bool (*)(const MaterialInstance &material, std::size_t count,
                                   const double *stress_start, const double *strain_increment,
                                   const double *density, double *stress_end, double *wave_speed);

} // namespace talus
