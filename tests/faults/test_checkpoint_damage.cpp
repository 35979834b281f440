// Faults, checkpoint integrity (docs/restart.md, "What a checkpoint
// holds"): a damaged checkpoint is refused, naming what is damaged, and is
// never read as values other than those written.
#include "solver_helpers.hpp"

#include <talus/error.hpp>
#include <talus/io/checkpoint.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;

// A Mohr-Coulomb block settling under gravity: particles with plugin
// state, a stage, an ordering.
const std::string kScenario =
    "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 0.6], cell: 0.05}\n"
    "materials:\n"
    "  soil: {model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, poisson_ratio: 0.3, "
    "friction_angle: 35, dilation_angle: 0, cohesion: 5.0e3}\n"
    "groups:\n  block: {material: soil, shape: {box: {min: [0.1, 0], max: [0.5, 0.4]}}, "
    "initial_stress: {geostatic: {k0: 0.5}}}\n"
    "boundaries: {y-: {friction: 0.5}}\ngravity: [0, -9.81]\n"
    "stages:\n  - {name: settle, duration: 0.05, damping: {type: local, coefficient: 0.7}}\n";

// A checkpoint of the block after `steps` steps, written to `file`.
talus::Checkpoint written(const fs::path &file, int steps) {
    auto run = talus::test::sim_from_text(kScenario);
    for (int k = 0; k < steps; ++k)
        run->sim->step(1.0);
    talus::Checkpoint c;
    c.scenario_text = kScenario;
    c.run_id = "0123456789abcdef0123456789abcdef";
    c.state = run->sim->snapshot();
    c.plugins = talus::plugin_identities(run->scenario);
    talus::write_checkpoint(file, c);
    return c;
}

std::string file_bytes(const fs::path &file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

void put_bytes(const fs::path &file, const std::string &bytes) {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(out.good()) << file;
}

// Every value of a checkpoint, as bytes where they are numbers (a NaN
// equals itself), so that two equal checkpoints give equal texts.
std::string everything(const talus::Checkpoint &c) {
    std::ostringstream o;
    auto put = [&](const auto &v) { o.write(reinterpret_cast<const char *>(&v), sizeof v); };
    auto text = [&](const std::string &t) { o << t.size() << ':' << t; };
    text(c.talus_version), put(c.abi_major), put(c.abi_minor);
    text(c.scenario_path), text(c.scenario_text), text(c.scenario_sha256), text(c.run_id);
    for (const talus::PluginIdentity &p : c.plugins) {
        text(p.material), text(p.qualified_id), text(p.path), text(p.library_version);
        text(p.model_version), text(p.sha256), put(p.abi_major), put(p.abi_minor);
    }
    const talus::OutputProgress &u = c.output;
    put(u.next_output), put(u.next_due), put(u.last_written_step), put(u.stage_first_step);
    for (double t : u.frames)
        put(t);
    for (std::int64_t p : u.probe_particles)
        put(p);
    put(u.diagnostics_bytes), put(u.probes_bytes), put(u.stages_bytes), put(u.particle_steps);
    const talus::Snapshot &s = c.state;
    put(s.step), put(s.time), put(s.last_dt), put(s.max_speed), put(s.removed);
    put(s.held_at_faces), put(s.cut_steps), put(s.held_depth), put(s.warned_dt), put(s.stage);
    put(s.stage_start), put(s.gravity_before), put(s.hold.has_value()), put(s.hold.value_or(0));
    put(s.below_since.has_value()), put(s.below_since.value_or(0)), put(s.ratio);
    put(s.out_of_order), put(s.slabs_changed), put(s.batch_size), put(s.sort_disorder);
    put(s.rank);
    for (const auto &b : s.boxes)
        put(b);
    for (const talus::Snapshot::Set &set : s.sets) {
        put(set.material), put(set.n);
        for (const talus::Snapshot::Column &col : set.columns) {
            text(col.name), put(col.type), put(col.stride);
            o.write(reinterpret_cast<const char *>(col.bytes.data()),
                    static_cast<std::streamsize>(col.bytes.size()));
        }
        for (std::int32_t m : set.slab_of)
            put(m);
    }
    return o.str();
}

} // namespace

// Damage to a checkpoint file (one flipped bit at a time, at 1000 places
// spread over the whole file, the values' bytes and HDF5's own structures
// alike) is either refused when the file is read or changes nothing of what
// is read (a bit of unused space): never a restart from values other than
// those written. The file's digests see any damage within one 8-byte word:
// not one flip may be read as other values.
TEST(CheckpointDamage, AFlippedBitIsRefusedNeverReadAsOtherValues) {
    const fs::path dir = fs::temp_directory_path() / "talus_checkpoint_flips";
    fs::create_directories(dir);
    const fs::path file = dir / "c.h5", bad = dir / "bad.h5";
    written(file, 40);
    const std::string reference = everything(talus::read_checkpoint(file));
    const std::string bytes = file_bytes(file);
    ASSERT_GT(bytes.size(), 10000u);
    int refused = 0, unchanged = 0;
    const std::size_t flips = 1000;
    for (std::size_t k = 0; k < flips; ++k) {
        const std::size_t at = std::min(bytes.size() - 1, (k * bytes.size()) / flips + k % 97);
        std::string damaged = bytes;
        damaged[at] = static_cast<char>(damaged[at] ^ (1 << (k % 8)));
        put_bytes(bad, damaged);
        try {
            const std::string read = everything(talus::read_checkpoint(bad));
            EXPECT_TRUE(read == reference) << "bit " << k % 8 << " of byte " << at << " of "
                                           << bytes.size() << " flipped: read as other values";
            ++unchanged;
        } catch (const talus::Error &) {
            ++refused;
        }
    }
    // Most of the file is values, each of them covered: most flips are
    // refused (the rest fall on unused space).
    EXPECT_GT(refused, static_cast<int>(flips) / 2) << unchanged << " read unchanged";
    fs::remove_all(dir);
}

// A flip inside a particle column is refused naming the column.
TEST(CheckpointDamage, ADamagedColumnIsNamed) {
    const fs::path dir = fs::temp_directory_path() / "talus_checkpoint_column";
    fs::create_directories(dir);
    const fs::path file = dir / "c.h5";
    const talus::Checkpoint c = written(file, 1);
    const auto &cols = c.state.sets.at(0).columns;
    const auto stress = std::find_if(cols.begin(), cols.end(),
                                     [](const auto &col) { return col.name == "stress"; });
    ASSERT_NE(stress, cols.end());
    // The column's bytes, found by their values in the file.
    std::string bytes = file_bytes(file);
    const std::string column(reinterpret_cast<const char *>(stress->bytes.data()),
                             stress->bytes.size());
    const std::size_t at = bytes.find(column);
    ASSERT_NE(at, std::string::npos);
    bytes[at + column.size() / 2] = static_cast<char>(bytes[at + column.size() / 2] ^ 0x10);
    put_bytes(file, bytes);
    try {
        talus::read_checkpoint(file);
        ADD_FAILURE() << "a damaged stress column was read";
    } catch (const talus::Error &e) {
        EXPECT_NE(std::string(e.what()).find("damaged: the array '/sets/0/stress' does not match "
                                             "its digest"),
                  std::string::npos)
            << e.what();
    }
    fs::remove_all(dir);
}
