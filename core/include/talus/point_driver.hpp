// The material-point driver: one point, one material, a prescribed strain
// path. Plugin authors use it to test a model alone, through the same plugin
// binary the MPM solver loads.
//
// Kinematics (docs/point-driver.md): the user prescribes the logarithmic
// (Hencky) strain tensor eps(t), component by component, as piecewise-linear
// functions of time. The deformation gradient is the pure stretch
// F = exp(eps) (no rotation), the strain increment handed to the plugin is
// eps(t_{n+1}) - eps(t_n), and the density is rho0 / det F. For coaxial
// paths (all the usual laboratory tests) the Hencky increment is the exact
// time integral of the rate of deformation; at small strain every measure
// coincides.
#pragma once

#include <talus/material_spec.hpp>
#include <talus/plugin_loader.hpp>
#include <talus/time_function.hpp>
#include <talus/yaml_input.hpp>

#include <Eigen/Core>

#include <array>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace talus {

struct PointCase {
    MaterialSpec material;
    std::unique_ptr<MaterialInstance> instance;
    Eigen::Matrix<double, 6, 1> initial_stress = Eigen::Matrix<double, 6, 1>::Zero();
    double end_time = 1.0;
    long increments = 1;
    long output_every = 1;
    // Hencky strain, tensor components in Voigt order xx yy zz xy yz xz.
    std::array<PiecewiseLinear, 6> strain;
};

// One output row.
struct PointRow {
    double time = 0.0;
    Eigen::Matrix<double, 6, 1> strain; // tensor components
    Eigen::Matrix<double, 6, 1> stress; // Cauchy, tension positive
    std::vector<double> state;
};

// Reads and validates a driver case; plugins listed under `plugins:` are
// loaded into `registry` first. Creates the material instance.
PointCase read_point_case(const yaml::Node &root, PluginRegistry &registry);

// Runs the path. A cut-step request is honoured by sub-stepping the
// increment; a plugin failure throws talus::Error naming the model, the
// increment, the time and the plugin's message.
std::vector<PointRow> run_point_case(const PointCase &pc);

// CSV: time, eps_*, sig_*, p, q, then one column per state component.
void write_point_csv(std::ostream &out, const Model &model, const std::vector<PointRow> &rows);

} // namespace talus
