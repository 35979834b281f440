// A material-point driver case as plain data (docs/point-driver.md): the
// material, the initial stress, and the stages, each six linear conditions
// on the strain and the stress (talus/driver/point_driver.hpp says how the
// driver runs them), and its reader from YAML, with errors at
// file:line:column.
#pragma once

#include <talus/input/yaml_input.hpp>
#include <talus/material/material_spec.hpp>
#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/time_function.hpp>

#include <Eigen/Core>

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace talus {

using PointVec6 = Eigen::Matrix<double, 6, 1>;

// Names of the symmetric tensor components in Voigt order.
inline constexpr std::array<std::string_view, 6> kVoigtNames = {"xx", "yy", "zz", "xy", "yz", "xz"};

// How a condition's right-hand side evolves over its stage.
struct ControlValue {
    enum class Kind {
        change, // v0 + amount * tau / duration (amount 0: held)
        target, // v0 + (amount - v0) * tau / duration
        rate,   // v0 + amount * tau
        table,  // table(tau), absolute
    };
    Kind kind = Kind::change;
    double amount = 0.0;
    PiecewiseLinear table;
};

// One linear condition: a . eps + b . sig = v(tau). Tensor components in
// Voigt order xx yy zz xy yz xz (the shear strains are tensor components,
// not engineering ones).
struct Condition {
    PointVec6 a = PointVec6::Zero();
    PointVec6 b = PointVec6::Zero();
    ControlValue value;
    std::string label; // for messages and --print-stages, e.g. "sig_xx"
};

// A stopping criterion "variable op threshold", e.g. q >= 2e5.
struct ExitCondition {
    std::string variable;
    std::string op; // ">=", "<=", ">", "<"
    double threshold = 0.0;
    std::string text; // as written
};

// A rigid rotation of the current configuration over a stage.
struct RigidRotation {
    std::array<double, 3> axis{0.0, 0.0, 1.0};
    double angle = 0.0; // radians over the stage
};

// One plugin call with exactly these inputs (ABI conventions), no
// conditions: how a failed particle of `talus run` is replayed.
struct ReplayCall {
    double time = 0.0, dt = 0.0, density = 0.0;
    PointVec6 strain_increment = PointVec6::Zero(); // engineering shear
    std::array<double, 9> F_start{}, F_end{};       // row-major
    PointVec6 stress = PointVec6::Zero();
    std::vector<double> state;
};

struct Stage {
    std::string name;
    double duration = 1.0;
    long increments = 1;
    std::array<Condition, 6> conditions;
    std::optional<ExitCondition> until;
    std::optional<RigidRotation> rotation; // replaces the conditions
    std::optional<ReplayCall> replay;      // replaces the conditions
    // A prescribed deformation gradient F(tau), row-major xx xy xz yx ... zz,
    // relative to the reference configuration; replaces the conditions.
    std::optional<std::array<PiecewiseLinear, 9>> deformation;
    bool zero_strain = false; // strains measured from this stage's start (as a lab does)
    std::string where;        // file:line:col of the stage, for messages
};

// A reference to compare the output with (exit code non-zero on mismatch).
struct CompareSpec {
    std::string file;  // CSV, resolved against the case file's folder
    std::string x;     // column of both files to interpolate on
    std::string stage; // only the rows of this stage (by name), or all
    std::string ref_x; // the reference's name for x
    struct Column {
        std::string ours, theirs;
        double rel = 0.0, abs = 0.0;
    };
    std::vector<Column> columns;
    std::string where;
};

struct PointCase {
    MaterialSpec material;
    std::unique_ptr<MaterialInstance> instance;
    PointVec6 initial_stress = PointVec6::Zero();
    int axis = 2; // the axial direction of the geotechnical output (z)
    // The length the plugin is told (talus_batch.characteristic_length:
    // regularised softening, UMAT's CELENT): the element the point stands
    // for.
    double characteristic_length = 1.0;
    std::vector<Stage> stages;
    long output_every = 1;
    std::optional<CompareSpec> compare;
    std::string file; // the case file, for relative paths
};

// One output row.
struct PointRow {
    double time = 0.0;
    int stage = 0;
    PointVec6 strain; // Hencky, tensor components
    PointVec6 stress; // Cauchy, tension positive
    std::vector<double> state;
};

// The named quantity of a row (a column of the driver's CSV, which a
// case's `compare:` and `until:` name), or nullopt.
std::optional<double> point_quantity(const PointRow &row, const MaterialInstance &material,
                                     int axis, const std::string &name);

// Reads and validates a driver case; plugins listed under `plugins:` are
// loaded into `registry` first. Creates the material instance.
PointCase read_point_case(const yaml::Node &root, PluginRegistry &registry);

// Reads an exit condition 'VARIABLE OP NUMBER' (OP one of >=, <=, >, <).
ExitCondition read_until(const yaml::Node &node);

// Expands `preset:` stages into conditions (point_presets.cpp).
std::vector<Stage> expand_preset(const yaml::Node &stage, int axis);

} // namespace talus
