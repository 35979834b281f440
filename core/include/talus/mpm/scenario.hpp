// A scenario as plain data: what `talus run` reads from YAML
// (input/scenario_yaml.hpp), validated completely (schema and each plugin's
// own parameter metadata) before any work starts. No YAML and no live
// plugin instance in here: the Simulation makes its materials' instances.
// docs/scenario-reference.md documents every key; a test keeps the two in
// step through scenario_schema().
#pragma once

#include <talus/material/material_spec.hpp>
#include <talus/mpm/shape_functions.hpp>
#include <talus/mpm/spatial_field.hpp>
#include <talus/mpm/time_function.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace talus {

using Vec3 = std::array<double, 3>;

// Where an entry of the scenario file came from, so that a problem found
// after reading (a group outside the grid, a box that selects nothing) is
// still reported at file:line:column with its key. Empty for scenarios
// built in code.
struct Origin {
    std::string where; // "file:line:column"
    std::string key;   // "groups.block"
    // "<where>: error: '<key>' <what>", or "error: <what>" without a place.
    std::string error(std::string_view what) const;
    std::string warning(std::string_view what) const;
    std::string note(std::string_view what) const;
};

struct Box {
    Vec3 min{0, 0, 0}, max{0, 0, 0};
    bool contains(const double *x, int dim) const {
        for (int d = 0; d < dim; ++d)
            if (x[d] < min[d] || x[d] > max[d]) return false;
        return true;
    }
};

// Geometry of a particle group.
struct GroupShape {
    enum class Kind { box, sphere, cylinder, polygon } kind = Kind::box;
    Box box;                                    // box
    Vec3 center{0, 0, 0};                       // sphere (disk in 2D), cylinder
    double radius = 0.0;                        // sphere, cylinder
    int axis = 2;                               // cylinder axis (0, 1, 2)
    double zmin = 0.0, zmax = 0.0;              // cylinder extent along its axis
    std::vector<std::array<double, 2>> polygon; // 2D polygon vertices
    bool contains(const double *x, int dim) const;
    Box bounds(int dim) const;
    // Area (2D) or volume (3D) of the shape, m^2 or m^3.
    double measure(int dim) const;
};

struct InitialStress {
    // given: `components`, numbers (uniform:) or functions of position (field:)
    enum class Kind { none, given, geostatic } kind = Kind::none;
    std::array<SpatialField, 6> components{}; // Voigt, Pa, tension +
    double k0 = 0.5;                          // geostatic: sigma_h / sigma_v
    std::optional<double> surface;            // geostatic: free-surface level
};

struct GroupSpec {
    std::string name;
    std::size_t material = 0; // index into Scenario::materials
    GroupShape shape;
    int particles_per_cell = 2; // per direction
    std::array<SpatialField, 3> velocity{};
    // Rigid rotation added to the initial velocity, about the centre of the
    // shape's bounding box: rad/s about z in 2D, a vector in 3D.
    Vec3 angular_velocity{0, 0, 0};
    InitialStress stress;
    // Values of the material's user-initialisable state variables that
    // replace its initial_state in this group: component `index` of the
    // point's state vector.
    struct StateValue {
        std::uint32_t index = 0;
        SpatialField value;
    };
    std::vector<StateValue> initial_state;
    Origin origin, shape_origin, stress_origin, velocity_origin, state_origin;
};

struct NamedMaterial {
    std::string name;
    MaterialSpec spec;
    Origin origin; // where the material is defined, for a plugin's refusal
};

// One optional function of time per component x, y, z.
struct ComponentFunctions {
    std::array<std::optional<PiecewiseLinear>, 3> c;
};

// What a face does to the material at it (docs/scenario-reference.md):
//   fixed:    no motion at all (bilateral, sticking)
//   roller:   no normal motion, either way (bilateral), tangential free
//   slip:     frictionless contact: the material cannot enter the wall but
//             may leave it (unilateral), tangential free
//   friction: slip plus Coulomb friction while in contact
enum class FaceType { free, fixed, roller, slip, friction };
struct FaceCondition {
    FaceType type = FaceType::free;
    double friction = 0.0; // Coulomb coefficient, with FaceType::friction (0 for slip)
};

struct NodalVelocity { // prescribed grid velocity in a box
    Box box;
    ComponentFunctions velocity;
    Origin origin;
};

struct ParticleVelocity { // particle velocity fixity on a group or in a box
    std::optional<std::size_t> group;
    std::optional<Box> box;
    ComponentFunctions velocity;
    Origin origin;
};

struct Load {
    enum class Kind { point, traction } kind = Kind::point;
    std::optional<std::size_t> group;
    std::optional<Box> box;
    std::array<PiecewiseLinear, 3> value; // force (N) per particle, or traction (Pa)
    Origin origin;
};

struct Probe {
    enum class Kind { particle, centre_of_mass } kind = Kind::particle;
    std::string name;
    Vec3 point{0, 0, 0};   // particle: the one nearest this point at t = 0
    std::size_t group = 0; // centre_of_mass
    Origin origin;
};

enum class Scheme { usl, usf, musl, usavg };
enum class Transfer { flip, apic, tpic };
enum class LeavePolicy { stop, remove };

struct SolverSpec {
    Scheme scheme = Scheme::usl;
    Transfer transfer = Transfer::flip;
    double alpha = 1.0; // FLIP fraction of the FLIP/PIC blend (seed 000 eq. 36)
    ShapeKind shape = ShapeKind::bspline2;
    double cfl = 0.3;
    std::optional<double> dt; // fixed time step
    Origin dt_origin;
    bool second_order_position = false;
    bool cell_averaged_dilation = false;
    LeavePolicy leave = LeavePolicy::stop;
    // On several ranks (docs/mpi.md): every `rebalance_every` steps, the
    // cells are shared anew when the most particles on a rank exceed the
    // mean by this factor. Ignored on one rank.
    double rebalance_imbalance = 1.2;
    int rebalance_every = 10;
};

// Damping of the nodal motion for quasi-static work (docs/theory.md,
// "Damping"): local non-viscous damping (Cundall 1987) removes from each
// nodal force component the fraction `coefficient` of its magnitude,
// against the node's velocity; mass-proportional viscous damping the force
// coefficient m v (coefficient in 1/s).
enum class DampingKind { none, local, viscous };
struct DampingSpec {
    DampingKind kind = DampingKind::none;
    double coefficient = 0.0;
};

struct OutputSpec {
    double every = 0.0; // s; 0: only the start and the end
    bool vtk = true;
    std::vector<std::string> state_fields; // plugin state variables to write; empty: those flagged
    bool all_flagged_state = true;
    std::vector<Probe> probes;
    Origin every_origin;
};

// What acts on the body, and may change from one stage to the next. Its
// functions of time are of the time since the stage began.
struct Conditions {
    std::array<FaceCondition, 6> faces; // x-, x+, y-, y+, z-, z+
    Vec3 gravity{0, 0, 0};
    // s; gravity changes linearly over it from the previous stage's (zero
    // before the first) to `gravity`.
    double gravity_ramp = 0.0;
    DampingSpec damping;
    std::vector<NodalVelocity> nodal_velocities;
    std::vector<ParticleVelocity> particle_velocities;
    std::vector<Load> loads;
};

// A stage ends early once the motion has died out (docs/theory.md,
// "Stages"): the kinetic energy stays below `kinetic_energy_ratio` times the
// strain energy estimate sum V sigma:sigma / (2 rho c^2) for `hold` seconds.
struct Quiescence {
    double kinetic_energy_ratio = 0.0;
    std::optional<double> hold;  // s; default: 8 P-wave transits of the material (stage start)
    bool stop_if_not_met = true; // false: go on to the next stage with a warning
    Origin origin;
};

struct MaterialSwitch {
    std::size_t group = 0, material = 0;
};

// One stage of an analysis: its conditions, complete (what the file does
// not give for a stage is carried from the one before), how long it may
// last, and what changes when it begins.
struct StageSpec {
    std::string name;
    double duration = 0.0; // s
    std::optional<Quiescence> until;
    Conditions conditions;
    std::vector<std::size_t> activate; // groups that appear at the stage start
    std::vector<std::size_t> remove;   // groups taken out at the stage start
    std::vector<MaterialSwitch> set_material;
    bool reset_displacement = false; // x0 := x: displacements count from here
    bool reset_velocity = false;     // v := 0 (and the affine matrices)
    Origin origin;
};

// When a run writes a checkpoint (docs/restart.md); on SIGTERM and SIGINT
// it always does.
struct CheckpointSpec {
    std::optional<double> every; // s of simulated time
    Origin every_origin;
    std::optional<long> steps;  // every this many steps
    std::optional<double> wall; // s of wall-clock time
    int keep = 2;               // the newest this many are kept
};

struct Scenario {
    std::string file;
    int dim = 2;
    Vec3 origin{0, 0, 0}, size{0, 0, 0};
    double cell = 0.0;
    // The named numbers expressions may use (`constants:`).
    std::vector<NamedConstant> constants;
    std::vector<NamedMaterial> materials;
    std::vector<GroupSpec> groups;
    // The conditions of a scenario without stages (and what its first stage
    // starts from).
    Conditions conditions;
    SolverSpec solver;
    // Without stages, the end time; with stages, the sum of their durations
    // (the latest the run can end).
    double end_time = 0.0;
    // Empty: one stage, `conditions` until `end_time` (stages_of()).
    std::vector<StageSpec> stages;
    OutputSpec output;
    CheckpointSpec checkpoint;
    Origin grid_origin, end_origin;
};

// The stages a run goes through: the scenario's, or the one stage a
// scenario without `stages:` is.
std::vector<StageSpec> stages_of(const Scenario &scenario);
// The materials a run uses, in order of first use: those of the groups,
// then those stages switch groups to.
std::vector<std::size_t> materials_in_use(const Scenario &scenario);
// The stage in which each group first appears (0 for those present from
// the start).
std::vector<std::size_t> first_stage_of_groups(const Scenario &scenario);

// A speed at or above this is a typo or a unit error, not the velocity of
// a continuum (and its square overflows the energy diagnostics long before
// it matters): the reader refuses it in numbers, particle generation in the
// values of expressions.
inline constexpr double kSpeedOfLight = 299792458.0; // m/s

// At most this many loads and particle_velocities entries (each particle
// records its own in a 32-bit mask).
inline constexpr std::size_t kMaxLoads = 32;

} // namespace talus
