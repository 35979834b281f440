// Particle storage: the particles of one material as a structure of arrays,
// every array a column carved from one aligned arena (one allocation per
// set, each column on its own cache line). Tensors use the ABI's layouts
// (Voigt stress, row-major F) so that a plugin reads them in place.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace talus {

class MaterialInstance;

// One column of per-particle values (stride values per particle): indexed
// like a vector; its storage belongs to the ParticleSet.
template <class T>
class Column {
  public:
    using value_type = T;
    T &operator[](std::size_t i) { return data_[i]; }
    const T &operator[](std::size_t i) const { return data_[i]; }
    T *data() { return data_; }
    const T *data() const { return data_; }
    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    T *begin() { return data_; }
    T *end() { return data_ + size_; }
    const T *begin() const { return data_; }
    const T *end() const { return data_ + size_; }
    // Same values (not the same storage).
    friend bool operator==(const Column &a, const Column &b) {
        return a.size_ == b.size_ && std::equal(a.begin(), a.end(), b.begin());
    }

  private:
    friend struct ParticleSet;
    T *data_ = nullptr;
    std::size_t size_ = 0;
};

struct ParticleSet {
    std::size_t material = 0; // index into Scenario::materials
    const MaterialInstance *instance = nullptr;
    bool finite_strain = false;
    bool wants_rotation = false; // the model is given each increment's rotation
    std::uint32_t state_size = 0;
    double rho0 = 0.0;
    std::size_t n = 0;

    Column<std::int64_t> id;    // stable particle id (output, probes)
    Column<std::int32_t> group; // index into Scenario::groups
    std::array<Column<double>, 3> x, x0, v, dx;
    Column<double> mass, vol0;
    Column<double> lp; // GIMP's half-width (cells)
    // The deformation gradient: 9 per point, row-major, in 3D; in plane
    // strain the in-plane block alone, 4 per point (F_xx, F_xy, F_yx,
    // F_yy), because there F_zz stays 1 and the other four stay 0: the
    // kinematics change only the in-plane block. The step reads and writes
    // F each step; in 2D the 5 values that never change were 80 of the
    // bytes a particle moved. F_of and set_F speak the full 3x3.
    Column<double> F;
    Column<double> J;
    Column<double> stress; // 6 per point, Voigt, Cauchy, tension +
    Column<double> state;  // state_size per point
    Column<double> c;      // wave speed from the plugin
    Column<double> L;      // velocity gradient, 9 per point
    Column<double> C;      // affine velocity matrix for APIC / TPIC, 9 per point
    Column<double> work;   // accumulated stress work, J
    Column<double> divv;   // velocity divergence (cell-averaged dilation)
    Column<std::uint32_t> load_mask, fix_mask; // bit k: loads[k] / particle_velocities[k]

    // Which optional columns this run needs (the others stay empty): the
    // third components only in 3D, L and dx unless USL does its kinematics
    // inside G2P, C for the affine transfers, divv for cell-averaged
    // dilation, lp for GIMP. Set before the first resize().
    int dim = 3;
    bool has_L = true, has_dx = true, has_C = true, has_divv = true, has_lp = true;

    // F's values per particle (above).
    std::size_t F_size() const { return dim == 2 ? 4 : 9; }
    // Particle p's F as the full row-major 3x3 (9 values), and back (in
    // plane strain only the in-plane block of `in` is kept).
    void F_of(std::size_t p, double *out) const {
        const double *f = &F[F_size() * p];
        if (dim == 2) {
            out[0] = f[0], out[1] = f[1], out[3] = f[2], out[4] = f[3];
            out[2] = out[5] = out[6] = out[7] = 0.0;
            out[8] = 1.0;
        } else {
            std::copy_n(f, 9, out);
        }
    }
    void set_F(std::size_t p, const double *in) {
        double *f = &F[F_size() * p];
        if (dim == 2)
            f[0] = in[0], f[1] = in[1], f[2] = in[3], f[3] = in[4];
        else
            std::copy_n(in, 9, f);
    }

    ParticleSet() = default;
    ParticleSet(ParticleSet &&) noexcept = default;
    ParticleSet &operator=(ParticleSet &&) noexcept = default;

    // New particles are zero; existing ones keep their values.
    void resize(std::size_t count);
    // Moves particle `from` to slot `to` (compaction).
    void move(std::size_t from, std::size_t to);
    // Reorders the particles in place: particle p takes the values particle
    // from[p] had (from.size() == n).
    void permute(const std::vector<std::uint32_t> &from);
    // Copies particle p of `other` (a set of another material with the same
    // columns in use) into slot q, all but its state.
    void copy_point(ParticleSet &other, std::size_t p, std::size_t q);
    // Calls f(column, values per particle) for every column in use.
    template <class Fn>
    void for_each_column(Fn &&f);
    // The same, as f(name, column, values per particle): the names a
    // checkpoint stores the columns under.
    template <class Fn>
    void for_each_named_column(Fn &&f);
    // Bytes per particle of the columns in use.
    std::size_t bytes_per_particle();

  private:
    struct Free {
        void operator()(std::byte *p) const;
    };
    std::unique_ptr<std::byte[], Free> arena_;
    std::size_t capacity_ = 0;
};

template <class Fn>
void ParticleSet::for_each_named_column(Fn &&f) {
    static constexpr const char *axis[3] = {"x", "y", "z"};
    static constexpr const char *start[3] = {"x0_x", "x0_y", "x0_z"};
    static constexpr const char *vel[3] = {"v_x", "v_y", "v_z"};
    static constexpr const char *step[3] = {"dx_x", "dx_y", "dx_z"};
    f("id", id, 1);
    f("group", group, 1);
    for (int d = 0; d < dim; ++d) {
        const std::size_t dd = static_cast<std::size_t>(d);
        f(axis[dd], x[dd], 1);
        f(start[dd], x0[dd], 1);
        f(vel[dd], v[dd], 1);
        if (has_dx) f(step[dd], dx[dd], 1);
    }
    f("mass", mass, 1);
    f("vol0", vol0, 1);
    if (has_lp) f("lp", lp, 1);
    f("F", F, F_size());
    f("J", J, 1);
    f("stress", stress, 6);
    if (state_size > 0) f("state", state, state_size);
    f("c", c, 1);
    if (has_L) f("L", L, 9);
    if (has_C) f("C", C, 9);
    f("work", work, 1);
    if (has_divv) f("divv", divv, 1);
    f("load_mask", load_mask, 1);
    f("fix_mask", fix_mask, 1);
}

template <class Fn>
void ParticleSet::for_each_column(Fn &&f) {
    for_each_named_column([&](const char *, auto &col, std::size_t stride) { f(col, stride); });
}

} // namespace talus
