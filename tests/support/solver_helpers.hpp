// Shared helpers for the solver tests: build a simulation from YAML text or a
// config file, advance it to a time, read CSV references.
#pragma once

#include "test_paths.hpp"

#include <talus/input/scenario_yaml.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/mpm/scenario.hpp>
#include <talus/mpm/simulation.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace talus::test {

struct Sim {
    PluginRegistry registry;
    Scenario scenario;
    std::unique_ptr<Simulation> sim;
};

// `edit` changes the scenario as read before the simulation is made.
inline std::unique_ptr<Sim> make_sim(const yaml::Node &root,
                                     std::vector<std::filesystem::path> dirs = {},
                                     const std::function<void(Scenario &)> &edit = {}) {
    unsetenv("TALUS_PLUGIN_PATH");
    auto s = std::make_unique<Sim>();
    s->registry = PluginRegistry(std::move(dirs));
    s->scenario = read_scenario(root, s->registry);
    if (edit) edit(s->scenario);
    s->sim = std::make_unique<Simulation>(s->scenario);
    return s;
}

inline std::unique_ptr<Sim> sim_from_text(const std::string &yaml,
                                          std::vector<std::filesystem::path> dirs = {}) {
    return make_sim(yaml::load_string(yaml, "test.yaml"), std::move(dirs));
}

inline std::unique_ptr<Sim> sim_from_config(const std::string &relative,
                                            const std::function<void(Scenario &)> &edit = {}) {
    return make_sim(yaml::load_file((source_dir() / relative).string()), {}, edit);
}

// Steps until time t, landing on it exactly; calls `each` after every step.
inline void advance(Simulation &sim, double t, const std::function<void()> &each = {}) {
    while (sim.time() < t * (1.0 - 1e-12)) {
        sim.step(t - sim.time());
        if (each) each();
    }
}

// Numeric CSV rows, skipping '#' comment lines and the header.
inline std::vector<std::vector<double>> read_numeric_csv(const std::filesystem::path &file) {
    std::ifstream in(file);
    std::string line;
    std::vector<std::vector<double>> rows;
    bool header = true;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        if (header) {
            header = false;
            continue;
        }
        std::vector<double> row;
        std::stringstream ss(line);
        std::string cell;
        while (std::getline(ss, cell, ','))
            row.push_back(std::stod(cell));
        rows.push_back(row);
    }
    return rows;
}

// Total momentum, mass and kinetic energy straight from the particles.
struct Totals {
    double mass = 0.0, ke = 0.0;
    double p[3] = {0, 0, 0};
};
inline Totals totals(const Simulation &sim) {
    Totals t;
    for (const ParticleSet &s : sim.sets())
        for (std::size_t k = 0; k < s.n; ++k) {
            t.mass += s.mass[k];
            for (int d = 0; d < s.dim; ++d) {
                t.p[d] += s.mass[k] * s.v[static_cast<std::size_t>(d)][k];
                t.ke += 0.5 * s.mass[k] * s.v[static_cast<std::size_t>(d)][k] *
                        s.v[static_cast<std::size_t>(d)][k];
            }
        }
    return t;
}

} // namespace talus::test
