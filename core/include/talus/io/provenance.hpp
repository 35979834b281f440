// The provenance record every run and every driver output carries: which
// Talus, which ABI, and for each material the model, its parameter values
// and the exact plugin file (path, library and model versions, build, and
// the SHA-256 of its content, which `sha256sum FILE` reproduces). With it a
// result can be traced to the binaries that made it, and a rerun with a
// different plugin build is told apart from a rerun with the same one.
#pragma once

#include <talus/material/material_spec.hpp>

#include <span>
#include <string>

namespace talus {

struct ProvenanceMaterial {
    std::string name; // the user's name for the material
    const MaterialSpec *spec = nullptr;
};

struct Provenance {
    std::string command;    // "run", "point"
    std::string input_file; // the scenario or driver case
    std::vector<ProvenanceMaterial> materials;
    // The digest of the input as read (default: of the file now).
    std::string input_sha256;
    // A run's name (Checkpoint::run_id); none for the point driver.
    std::string run_id;
};

// The time now, UTC, as the records give it ("2026-12-03T07:52:10Z").
std::string utc_now();

// As a JSON document (provenance.json beside a run's output).
std::string provenance_json(const Provenance &p);
// As '#' comment lines, for the head of a CSV file (the driver's output).
std::string provenance_comments(const Provenance &p);

} // namespace talus
