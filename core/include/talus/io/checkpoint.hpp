// Checkpoints: a run's complete state in one HDF5 file (docs/restart.md),
// from which `talus run --restart FILE` continues bit for bit. HDF5 because
// a user can look inside with the common tools (h5dump, h5ls, h5py,
// ParaView) and every array keeps its name, type and shape; the library is
// Debian's libhdf5-dev.
//
// A checkpoint holds the scenario as it was read (its text, path and
// SHA-256), the identity of Talus and of every plugin in use (path,
// library and model versions, content SHA-256), the solver's state
// (Snapshot: particle arrays with every plugin's state, the ordering, the
// counters, the stage), and where the output stood (the next file number,
// the length of each CSV file, the probes' particles), so that the
// restarted run writes exactly what the uninterrupted one would have.
#pragma once

#include <talus/mpm/scenario.hpp>
#include <talus/mpm/snapshot.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace talus {

struct PluginIdentity {
    std::string material;     // the scenario's name for the material
    std::string qualified_id; // library/model
    std::string path;         // the plugin file
    std::string library_version, model_version, sha256;
    int abi_major = 0, abi_minor = 0;
};

// Where the run's output stood at the checkpoint.
struct OutputProgress {
    long next_output = 0;        // the number of the next VTK file
    long next_due = 1;           // the next output time is next_due * output.every
    long last_written_step = -1; // the step of the last output
    long stage_first_step = 1;   // the first step of the current stage
    std::vector<double> frames;  // the times of the VTK files written (the .pvd)
    std::vector<std::int64_t> probe_particles;
    std::uint64_t diagnostics_bytes = 0, probes_bytes = 0, stages_bytes = 0;
    long particle_steps = 0;
};

struct Checkpoint {
    // Of the Talus that wrote it (write_checkpoint stamps its own).
    std::string talus_version;
    int abi_major = 0, abi_minor = 0;
    std::string scenario_path, scenario_text, scenario_sha256;
    // The run's own name (32 hex digits, made at its start and kept by its
    // restarts; also in its folder's provenance.json), so that a restart
    // can tell its own folder from another run's. Empty where the file has
    // none (formats 1 to 3, and format 4 as first written).
    std::string run_id;
    std::vector<PluginIdentity> plugins;
    OutputProgress output;
    Snapshot state;
};

// The identity of every material's plugin as loaded now.
std::vector<PluginIdentity> plugin_identities(const Scenario &scenario);
// One line for a verbose log: "talus: material 'soil': model 'lib/mc' 1.0
// from PATH (library 1.2, SHA-256 ...)".
std::string describe(const PluginIdentity &plugin);

// What differs between the checkpoint's Talus and plugins and those of this
// run, one line each (empty: the same binaries).
std::vector<std::string> identity_differences(const Checkpoint &checkpoint,
                                              const std::vector<PluginIdentity> &now);

// Writes the checkpoint to `file` atomically (a temporary, synced, renamed
// over it, the folder synced): a kill at any moment leaves either the old
// file or the complete new one. Throws talus::Error naming the file.
void write_checkpoint(const std::filesystem::path &file, const Checkpoint &checkpoint);

// Reads a checkpoint; throws talus::Error naming the file and what is
// missing or wrong (not a checkpoint, a newer format, a damaged array).
Checkpoint read_checkpoint(const std::filesystem::path &file);

// A run on several ranks checkpoints into one file per rank: rank 0's is
// `file` (checkpoint_<step>.h5, the one `--restart` names, written last,
// so that it exists only when every rank's does), rank r's beside it as
// checkpoint_<step>.rank<r>.h5.
std::filesystem::path rank_checkpoint_file(const std::filesystem::path &file, int rank);

// The checkpoint `file` (rank 0's) as rank `rank` of a run on `ranks`
// continues it: written by as many ranks, that rank's own part; by another
// number, the particles of this rank's share of the files (a contiguous
// run of them, rank 0 of 1 reading all; Snapshot::boxes empty: the solver
// sends them to their cells' ranks). Throws talus::Error when a rank's
// file is missing or from another step or run.
Checkpoint read_checkpoint_for(const std::filesystem::path &file, int rank, int ranks);

} // namespace talus
