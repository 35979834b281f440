// Everything a Simulation needs to go on from where it stands, as plain
// data: the particle arrays column by column (every plugin's state, of any
// size, included), the particle order the parallel P2G sums in, the
// counters, the time step's memory and the stage's. Restoring it into a
// Simulation of the same scenario continues the run bit for bit
// (io/checkpoint.hpp stores it in a file).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace talus {

struct Snapshot {
    enum class Type { f64, i64, i32, u32 };
    struct Column {
        std::string name; // ParticleSet::for_each_named_column
        Type type = Type::f64;
        std::size_t stride = 1;
        std::vector<std::byte> bytes; // n x stride values
    };
    struct Set {
        std::size_t material = 0;
        std::size_t n = 0;
        std::vector<Column> columns;
        std::vector<std::int32_t> slab_of; // the ordering's marks (empty: none)
    };
    long step = 0;
    double time = 0.0, last_dt = 0.0;
    double max_speed = -1.0; // the next step's dt comes from it
    long removed = 0, held_at_faces = 0, cut_steps = 0;
    double held_depth = 0.0;
    bool warned_dt = false;
    std::size_t stage = 0;
    double stage_start = 0.0;
    std::array<double, 3> gravity_before{0, 0, 0}; // where the stage's gravity ramp starts
    std::optional<double> hold, below_since;
    double ratio = 0.0;
    double out_of_order = 0.0;
    bool slabs_changed = true;
    // Solver options that change the trajectory.
    int batch_size = 0;
    double sort_disorder = 0.0;
    std::vector<Set> sets;
    // A run on several ranks (docs/mpi.md): the sets are this rank's
    // particles, and `boxes` the cells each rank owns, [lo, hi) per axis
    // as lo0 lo1 lo2 hi0 hi1 hi2. Empty on one rank, or when the sets hold
    // every particle (a checkpoint read on another number of ranks).
    int rank = 0;
    std::vector<std::array<int, 6>> boxes;
};

} // namespace talus
