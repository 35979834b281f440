#include "method/loads.hpp"

#include <algorithm>
#include <cmath>

namespace talus {

Loads::Loads(const Scenario &sc, const Conditions &c, const Vec3 &gravity_before, double t0)
    : dim_(sc.dim), gravity_(c.gravity), gravity_before_(gravity_before),
      gravity_ramp_(c.gravity_ramp), t0_(t0) {
    for (const Load &l : c.loads) {
        load_fn_.push_back(l.value);
        traction_.push_back(l.kind == Load::Kind::traction ? 1 : 0);
    }
    for (const GroupSpec &g : sc.groups)
        group_area_.push_back(std::pow(sc.cell / g.particles_per_cell, sc.dim - 1));
    for (const ParticleVelocity &pv : c.particle_velocities) {
        fix_fn_.push_back(pv.velocity.c);
        fixed_.push_back({pv.velocity.c[0].has_value(), pv.velocity.c[1].has_value(),
                          pv.velocity.c[2].has_value()});
    }
    load_now_.resize(load_fn_.size());
    fix_start_.assign(fix_fn_.size(), {0, 0, 0});
    fix_end_.assign(fix_fn_.size(), {0, 0, 0});
}

Vec3 Loads::gravity_at(double t_run) const {
    const double t = t_run - t0_;
    const double ramp = gravity_ramp_ > 0.0 ? std::min(1.0, t / gravity_ramp_) : 1.0;
    Vec3 g;
    for (std::size_t d = 0; d < 3; ++d)
        g[d] = gravity_before_[d] + (gravity_[d] - gravity_before_[d]) * ramp;
    return g;
}

void Loads::evaluate(double t_run, double dt) {
    const double t = t_run - t0_;
    gravity_now_ = gravity_at(t_run);
    for (std::size_t k = 0; k < load_fn_.size(); ++k)
        for (std::size_t d = 0; d < static_cast<std::size_t>(dim_); ++d)
            load_now_[k][d] = load_fn_[k][d](t);
    for (std::size_t k = 0; k < fix_fn_.size(); ++k)
        for (std::size_t d = 0; d < static_cast<std::size_t>(dim_); ++d)
            if (const auto &fn = fix_fn_[k][d]) {
                fix_start_[k][d] = (*fn)(t);
                fix_end_[k][d] = (*fn)(t + dt);
            }
}

} // namespace talus
