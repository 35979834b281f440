// The material-point driver: one point, one material, a loading programme of
// stages. Plugin authors use it to test a model alone, through the same
// plugin binary the MPM solver loads.
//
// Each stage imposes six linear conditions on the strain and the stress
// (docs/point-driver.md):
//
//   sum_k a_rk eps_k + sum_k b_rk sig_k = v_r(tau),   r = 1..6,
//
// eps the logarithmic (Hencky) strain tensor, sig the Cauchy stress (tension
// positive), tau the time since the stage began. A strain-controlled
// component is a row with a single a; a stress-controlled one a row with a
// single b; undrained (constant volume), constant-p' and K0 paths are rows
// with several. Each increment solves the six conditions at its end by
// Newton iteration on the strain increment with the plugin's tangent (or
// finite differences), the stress coming from the plugin. Kinematics: each
// increment stretches the current configuration, F_n+1 = exp(d_eps) F_n
// (the ABI's convention); a rotation stage rotates it rigidly instead.
//
// The presets an engineer knows (isotropic compression, oedometer, drained
// and undrained triaxial, constant-p', simple shear, cyclic variants) expand
// into this form (core/src/input/point_presets.cpp); `talus point
// --print-stages` shows the expansion. The case and its reader are in
// talus/input/point_case.hpp.
#pragma once

#include <talus/input/point_case.hpp>
#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/simulation.hpp>

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace talus {

// Runs the programme. Throws talus::Error naming the stage, the time and
// the cause (plugin failure, Newton residual, exit condition never met);
// `rows` then holds every row computed until then, so that the caller can
// write them out.
void run_point_case(const PointCase &pc, std::vector<PointRow> &rows);
std::vector<PointRow> run_point_case(const PointCase &pc);

// CSV: time, stage, eps_*, sig_* (tension positive), then the geotechnical
// quantities (compression positive): p, q, eps_v, eps_q, eps_a, sig_a,
// sig_r, then one column per state component.
void write_point_csv(std::ostream &out, const MaterialInstance &material, int axis,
                     const std::vector<PointRow> &rows);

// A driver case that replays the failed plugin call of a run (written by
// `talus run` next to its output when a plugin fails at a particle).
std::string replay_case_yaml(const FailedCall &call, const Scenario &scenario);

// Human-readable list of the stages' conditions (--print-stages).
void print_stages(std::ostream &out, const PointCase &pc);

// Compares the rows with the case's `compare` block; returns an empty
// string on agreement, else a report of every mismatch.
std::string compare_point_rows(const PointCase &pc, const std::vector<PointRow> &rows);

} // namespace talus
