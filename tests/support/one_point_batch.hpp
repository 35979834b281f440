// One material point's batch with the ABI 1.1 context filled as a host
// fills it, for tests that call a plugin directly. `batch(step)` points the
// batch at the members; step 0 is the set-up call (dt = 0).
#pragma once

#include <talus/material_abi.h>

#include <array>
#include <cstdint>
#include <vector>

namespace talus::test {

struct OnePoint {
    std::array<double, 6> de{}, s0{}, s1{};
    std::array<double, 9> F{1, 0, 0, 0, 1, 0, 0, 0, 1}, R{1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::vector<double> q0, q1;
    double rho = 2000.0, c = 0.0, length = 0.25, dt = 1e-3;
    std::int64_t id = 7;
    talus_batch batch(std::int64_t step) {
        q1.assign(q0.size(), 0.0);
        talus_batch b{};
        b.flags = TALUS_BATCH_WANT_WAVE_SPEED;
        b.n_points = 1;
        b.dt = step == 0 ? 0.0 : dt;
        b.strain_increment = de.data();
        b.F_start = F.data();
        b.F_end = F.data();
        b.density = &rho;
        b.stress_start = s0.data();
        b.stress_end = s1.data();
        b.state_start = q0.data();
        b.state_end = q1.data();
        b.wave_speed = &c;
        b.step = step;
        b.point_id = &id;
        b.characteristic_length = &length;
        b.rotation = R.data();
        return b;
    }
};

} // namespace talus::test
