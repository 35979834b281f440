// The forcing of one step in a stage: gravity (with its ramp), the applied
// loads on particles, and the particle velocity fixities, each function of
// the stage's time evaluated once per step (not once per particle) into
// plain arrays that the kernels read through a particle's bit masks.
#pragma once

#include <talus/mpm/scenario.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace talus {

class Loads {
  public:
    // The stage's conditions `c`, from time t0 on; its gravity ramp starts
    // from `gravity_before` (the previous stage's).
    Loads(const Scenario &sc, const Conditions &c, const Vec3 &gravity_before, double t0);
    // Values at time t (gravity, loads) and over [t, t + dt] (fixities);
    // t is the run's time.
    void evaluate(double t, double dt);

    // Gravity at (the run's) time t, m/s^2.
    Vec3 gravity_at(double t) const;
    // Gravity at the evaluated time, m/s^2.
    const double *gravity() const { return gravity_now_.data(); }
    // Sum of the applied forces on a particle of `group` with load mask
    // `mask` (point loads, and tractions on the particle's face area).
    template <int D>
    void particle_force(std::uint32_t mask, std::int32_t group, double *f) const {
        for (int d = 0; d < D; ++d)
            f[d] = 0.0;
        while (mask) {
            const std::size_t k = static_cast<std::size_t>(__builtin_ctz(mask));
            mask &= mask - 1;
            const double scale = traction_[k] ? group_area_[static_cast<std::size_t>(group)] : 1.0;
            for (int d = 0; d < D; ++d)
                f[d] += scale * load_now_[k][static_cast<std::size_t>(d)];
        }
    }

    // Fixity k prescribes component d.
    bool fixes(std::size_t k, int d) const { return fixed_[k][static_cast<std::size_t>(d)]; }
    // Prescribed velocity of fixity k at the end of the step.
    double fix_end(std::size_t k, int d) const { return fix_end_[k][static_cast<std::size_t>(d)]; }
    // A fixity prescribes the displacement of its components over the step
    // (trapezoidal in the prescribed velocity), whatever the grid says.
    template <int D>
    void fixity_step(std::uint32_t mask, double dt, double *step) const {
        while (mask) {
            const std::size_t k = static_cast<std::size_t>(__builtin_ctz(mask));
            mask &= mask - 1;
            for (int d = 0; d < D; ++d)
                if (fixed_[k][static_cast<std::size_t>(d)])
                    step[d] = 0.5 * dt *
                              (fix_start_[k][static_cast<std::size_t>(d)] +
                               fix_end_[k][static_cast<std::size_t>(d)]);
        }
    }
    // Fixed components override the velocity from the grid.
    template <int D>
    void fix_velocity(std::uint32_t mask, double *v) const {
        while (mask) {
            const std::size_t k = static_cast<std::size_t>(__builtin_ctz(mask));
            mask &= mask - 1;
            for (int d = 0; d < D; ++d)
                if (fixed_[k][static_cast<std::size_t>(d)])
                    v[d] = fix_end_[k][static_cast<std::size_t>(d)];
        }
    }

  private:
    int dim_;
    std::array<double, 3> gravity_, gravity_before_, gravity_now_{0, 0, 0};
    double gravity_ramp_, t0_;
    std::vector<std::array<PiecewiseLinear, 3>> load_fn_;
    std::vector<std::uint8_t> traction_;
    std::vector<double> group_area_; // traction area (h / ppc)^(dim - 1) per group
    std::vector<std::array<std::optional<PiecewiseLinear>, 3>> fix_fn_;
    std::vector<std::array<bool, 3>> fixed_;
    std::vector<std::array<double, 3>> load_now_, fix_start_, fix_end_;
};

} // namespace talus
