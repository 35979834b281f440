// The UMAT adapter: runs a user's compiled Abaqus UMAT, unchanged, as a
// Talus material (docs/umat.md). Written against the C header alone, not the
// C++ SDK: its state layout is per instance (NSTATV is a parameter) and it
// needs the ABI 1.1 create_ex, init-free context and rotation.
//
// Per point and increment it calls
//   UMAT(STRESS, STATEV, DDSDDE, SSE, SPD, SCD, RPL, DDSDDT, DRPLDE, DRPLDT,
//        STRAN, DSTRAN, TIME, DTIME, TEMP, DTEMP, PREDEF, DPRED, CMNAME,
//        NDI, NSHR, NTENS, NSTATV, PROPS, NPROPS, COORDS, DROT, PNEWDT,
//        CELENT, DFGRD0, DFGRD1, NOEL, NPT, LAYER, KSPT, KSTEP, KINC)
// with NDI = NSHR = 3, NTENS = 6, every argument by reference, arrays
// column-major, and (Fortran convention) the hidden length of CMNAME
// appended. Conventions translated:
//   - component order: Talus xx, yy, zz, xy, yz, xz; Abaqus 11, 22, 33, 12,
//     13, 23 (the last two swapped); both use engineering shear strains and
//     tensor shear stresses;
//   - STRAN is the total (log) strain the adapter keeps per point, rotated by
//     DROT before each call as Abaqus does; DSTRAN the host's increment;
//   - STRESS is the host's start stress, already rotated objectively;
//   - DDSDDE becomes the tangent (same shear conventions, order permuted);
//   - PNEWDT < 1 becomes a cut-step request with that factor;
//   - DROT is the increment's rotation, DFGRD0/DFGRD1 F at start and end,
//     CELENT the characteristic length, NOEL the particle id + 1, KINC the
//     step; TIME(1) = TIME(2) = the time at the start of the increment.
// Not passed (zero): SSE, SPD, SCD (not accumulated), temperatures and
// predefined fields, COORDS.
#include <talus/material_abi.h>

#include <dlfcn.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <vector>

namespace {

// The UMAT's signature, all arguments by reference; `cmname_length` is the
// hidden length gfortran (and most Fortran compilers) append for a
// CHARACTER argument. The C convention omits it.
using FortranUmat = void (*)(double *, double *, double *, double *, double *, double *, double *,
                             double *, double *, double *, double *, double *, double *, double *,
                             double *, double *, double *, double *, char *, std::int32_t *,
                             std::int32_t *, std::int32_t *, std::int32_t *, double *,
                             std::int32_t *, double *, double *, double *, double *, double *,
                             double *, std::int32_t *, std::int32_t *, std::int32_t *,
                             std::int32_t *, std::int32_t *, std::int32_t *, std::size_t);
using CUmat = void (*)(double *, double *, double *, double *, double *, double *, double *,
                       double *, double *, double *, double *, double *, double *, double *,
                       double *, double *, double *, double *, char *, std::int32_t *,
                       std::int32_t *, std::int32_t *, std::int32_t *, double *, std::int32_t *,
                       double *, double *, double *, double *, double *, double *, std::int32_t *,
                       std::int32_t *, std::int32_t *, std::int32_t *, std::int32_t *,
                       std::int32_t *);

// Talus Voigt index of each Abaqus component (11, 22, 33, 12, 13, 23).
constexpr std::array<int, 6> kFromAbaqus = {0, 1, 2, 3, 5, 4};

void message(talus_error *e, const std::string &text) {
    if (!e) return;
    std::snprintf(e->message, sizeof e->message, "%s", text.c_str());
}

std::int32_t fail(talus_error *e, std::int64_t point, const std::string &text) {
    if (e) e->point_index = point;
    message(e, text);
    return TALUS_STATUS_FAILED;
}

bool finite(const double *p, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i)
        if (!std::isfinite(p[i])) return false;
    return true;
}

// Rotates a Voigt strain (engineering shear, Talus order) by Q: eps' =
// Q eps Q^T.
void rotate_strain(const double *Q, double *e) {
    const double E[3][3] = {{e[0], 0.5 * e[3], 0.5 * e[5]},
                            {0.5 * e[3], e[1], 0.5 * e[4]},
                            {0.5 * e[5], 0.5 * e[4], e[2]}};
    double QE[3][3], R[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            QE[i][j] = Q[3 * i] * E[0][j] + Q[3 * i + 1] * E[1][j] + Q[3 * i + 2] * E[2][j];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            R[i][j] = QE[i][0] * Q[3 * j] + QE[i][1] * Q[3 * j + 1] + QE[i][2] * Q[3 * j + 2];
    e[0] = R[0][0];
    e[1] = R[1][1];
    e[2] = R[2][2];
    e[3] = 2.0 * R[0][1];
    e[4] = 2.0 * R[1][2];
    e[5] = 2.0 * R[0][2];
}

// The largest eigenvalue of a symmetric 3x3 (the acoustic tensor), by the
// trigonometric closed form (Smith 1961).
double largest_eigenvalue(const double A[3][3]) {
    const double p1 = A[0][1] * A[0][1] + A[0][2] * A[0][2] + A[1][2] * A[1][2];
    const double q = (A[0][0] + A[1][1] + A[2][2]) / 3.0;
    if (p1 == 0.0) return std::max({A[0][0], A[1][1], A[2][2]});
    const double p2 = (A[0][0] - q) * (A[0][0] - q) + (A[1][1] - q) * (A[1][1] - q) +
                      (A[2][2] - q) * (A[2][2] - q) + 2.0 * p1;
    const double p = std::sqrt(p2 / 6.0);
    double B[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            B[i][j] = (A[i][j] - (i == j ? q : 0.0)) / p;
    const double det = B[0][0] * (B[1][1] * B[2][2] - B[1][2] * B[2][1]) -
                       B[0][1] * (B[1][0] * B[2][2] - B[1][2] * B[2][0]) +
                       B[0][2] * (B[1][0] * B[2][1] - B[1][1] * B[2][0]);
    const double r = std::clamp(det / 2.0, -1.0, 1.0);
    return q + 2.0 * p * std::cos(std::acos(r) / 3.0);
}

// rho c^2 from a tangent (Talus order, row-major, engineering shear): the
// largest eigenvalue of the acoustic tensor Q_ik = C_ijkl n_j n_l over 13
// directions (the axes, the face and the body diagonals). Exact for an
// isotropic tangent (any direction gives lambda + 2 G), and for the
// symmetry axes of orthotropic ones.
double p_wave_modulus(const double *D) {
    auto voigt = [](int i, int j) {
        if (i == j) return i;
        if (i > j) std::swap(i, j);
        return i == 0 ? (j == 1 ? 3 : 5) : 4;
    };
    static const double s = 1.0 / std::sqrt(2.0), t = 1.0 / std::sqrt(3.0);
    static const double dirs[13][3] = {{1, 0, 0},  {0, 1, 0},  {0, 0, 1}, {s, s, 0},  {s, -s, 0},
                                       {s, 0, s},  {s, 0, -s}, {0, s, s}, {0, s, -s}, {t, t, t},
                                       {t, t, -t}, {t, -t, t}, {-t, t, t}};
    double best = 0.0;
    for (const auto &n : dirs) {
        double A[3][3] = {};
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j)
                    for (int l = 0; l < 3; ++l)
                        // C_ijkl from the Voigt tangent: dsigma_ij / deps_kl
                        // = D[ij][kl], the engineering shear column already
                        // holding the factor for eps_kl + eps_lk.
                        A[i][k] += D[6 * voigt(i, j) + voigt(k, l)] * n[j] * n[l];
        // Symmetrise (a UMAT's tangent need not be symmetric).
        for (int i = 0; i < 3; ++i)
            for (int k = i + 1; k < 3; ++k)
                A[i][k] = A[k][i] = 0.5 * (A[i][k] + A[k][i]);
        best = std::max(best, largest_eigenvalue(A));
    }
    return best;
}

struct Instance {
    void *handle = nullptr;
    FortranUmat fortran = nullptr;
    CUmat c = nullptr;
    std::vector<double> props;
    std::int32_t nstatv = 0;
    std::array<char, 80> cmname{};
    double p_wave_modulus = 0.0; // 0: from DDSDDE
    std::string library;
    // The state layout: NSTATV named variables, then the total strain.
    std::vector<std::string> names;
    std::vector<double> initial;
    std::vector<talus_state_desc> descs;
    std::vector<const talus_state_desc *> desc_ptrs;
    ~Instance() {
        if (handle) dlclose(handle);
    }
};

std::vector<std::string> split_names(const char *text) {
    std::vector<std::string> out;
    std::string cur;
    for (const char *c = text;; ++c) {
        if (*c == ',' || *c == ' ' || *c == '\0') {
            if (!cur.empty()) out.push_back(cur);
            cur.clear();
            if (*c == '\0') break;
        } else {
            cur += *c;
        }
    }
    return out;
}

bool snake(const std::string &s) {
    if (s.empty() || !(s[0] >= 'a' && s[0] <= 'z')) return false;
    return std::all_of(s.begin(), s.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    });
}

// Parameter order (see the table below).
enum : std::size_t {
    kLibrary,
    kEntry,
    kConvention,
    kProps,
    kNstatv,
    kStateNames,
    kDepvar,
    kCmname,
    kPWave,
    kParams
};

std::int32_t create_ex(const talus_create_args *args, talus_instance **out, talus_error *e) {
    if (!args || !out || args->n_values != kParams)
        return fail(e, -1, "create_ex: unexpected arguments");
    *out = nullptr;
    const talus_param_value *const *v = args->values;
    auto inst = std::unique_ptr<Instance>(new (std::nothrow) Instance());
    if (!inst) return fail(e, -1, "out of memory");
    // The library: relative to the file the material was read from (to the
    // working folder where there is none), never looked up through
    // LD_LIBRARY_PATH and the system's folders, where a name without a '/'
    // would send dlopen (a library of the same name elsewhere is not the
    // one the user named).
    std::string lib = v[kLibrary]->string;
    if (!lib.empty() && lib[0] != '/')
        lib = (args->base_dir && *args->base_dir ? std::string(args->base_dir) : std::string(".")) +
              "/" + lib;
    inst->library = lib;
    // A FIFO would block dlopen for ever: regular files only.
    struct stat st {};
    if (::stat(lib.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
        return fail(e, -1,
                    "library: '" + lib + "' is " +
                        (S_ISDIR(st.st_mode)    ? "a directory"
                         : S_ISFIFO(st.st_mode) ? "a FIFO"
                                                : "a device or socket") +
                        ", not a file: the UMAT library must be a regular file");
    inst->handle = dlopen(lib.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!inst->handle) {
        const char *why = dlerror();
        return fail(e, -1,
                    "library: cannot load the UMAT library '" + lib +
                        "': " + (why ? why : "unknown dlopen error"));
    }
    const std::string convention = v[kConvention]->string;
    if (convention != "fortran" && convention != "c")
        return fail(e, -1,
                    "calling_convention: expected 'fortran' (hidden CHARACTER length, the "
                    "default) or 'c', got '" +
                        convention + "'");
    dlerror();
    void *sym = dlsym(inst->handle, v[kEntry]->string);
    if (!sym)
        return fail(e, -1,
                    "entry: the UMAT library '" + lib + "' exports no symbol '" +
                        v[kEntry]->string +
                        "' (gfortran names SUBROUTINE UMAT 'umat_'; `nm -D` lists the symbols)");
    if (convention == "fortran")
        inst->fortran = reinterpret_cast<FortranUmat>(sym);
    else
        inst->c = reinterpret_cast<CUmat>(sym);
    inst->props.assign(v[kProps]->reals, v[kProps]->reals + v[kProps]->count);
    inst->nstatv = static_cast<std::int32_t>(v[kNstatv]->scalar);
    inst->p_wave_modulus = v[kPWave]->scalar;

    // State names: as given (lower_snake_case, NSTATV of them) or statev_N.
    std::vector<std::string> names = split_names(v[kStateNames]->string);
    if (names.empty())
        for (std::int32_t i = 1; i <= inst->nstatv; ++i)
            names.push_back("statev_" + std::to_string(i));
    if (static_cast<std::int32_t>(names.size()) != inst->nstatv)
        return fail(e, -1,
                    "state_names: " + std::to_string(names.size()) + " names for nstatv = " +
                        std::to_string(inst->nstatv) + "; give one per state variable");
    for (const std::string &n : names)
        if (!snake(n) || n == "umat_strain")
            return fail(e, -1,
                        "state_names: '" + n +
                            "' is not a usable name (lower_snake_case, not umat_strain)");
    const talus_param_value *depvar = v[kDepvar];
    if (depvar->count != 0 && depvar->count != static_cast<std::uint64_t>(inst->nstatv))
        return fail(e, -1,
                    "depvar: " + std::to_string(depvar->count) + " initial values for nstatv = " +
                        std::to_string(inst->nstatv) + "; give one per state variable or none");
    inst->names = std::move(names);
    inst->names.push_back("umat_strain");
    for (std::int32_t i = 0; i < inst->nstatv; ++i)
        inst->initial.push_back(depvar->count ? depvar->reals[i] : 0.0);
    for (std::size_t i = 0; i < inst->names.size(); ++i) {
        const bool strain = i + 1 == inst->names.size();
        inst->descs.push_back(talus_state_desc{
            sizeof(talus_state_desc), TALUS_STATE_OUTPUT | (strain ? 0u : TALUS_STATE_USER_INIT),
            strain ? 6u : 1u, 0, inst->names[i].c_str(), "-",
            strain ? "Total strain the UMAT sees as STRAN (Talus order, engineering shear)."
                   : "A UMAT state variable (STATEV).",
            strain ? 0.0 : inst->initial[i]});
    }
    for (const talus_state_desc &d : inst->descs)
        inst->desc_ptrs.push_back(&d);
    // CMNAME: given, else the material's own name (its last path part),
    // upper case and blank-padded to 80 characters as Abaqus passes it.
    std::string cm = v[kCmname]->string;
    if (cm.empty() && args->material_name) {
        cm = args->material_name;
        const auto dot = cm.rfind('.');
        if (dot != std::string::npos) cm = cm.substr(dot + 1);
    }
    std::fill(inst->cmname.begin(), inst->cmname.end(), ' ');
    for (std::size_t i = 0; i < std::min<std::size_t>(80, cm.size()); ++i)
        inst->cmname[i] = static_cast<char>(std::toupper(static_cast<unsigned char>(cm[i])));
    *out = reinterpret_cast<talus_instance *>(inst.release());
    return TALUS_STATUS_OK;
}

std::int32_t create(const double *, std::uint32_t, talus_instance **, talus_error *e) {
    return fail(e, -1,
                "the UMAT adapter takes a library name and a PROPS list: it needs a host of "
                "Talus material ABI 1.1 or later");
}

void destroy(talus_instance *i) { delete reinterpret_cast<Instance *>(i); }

std::int32_t instance_state(const talus_instance *i, talus_state_layout *layout, talus_error *e) {
    const auto *inst = reinterpret_cast<const Instance *>(i);
    if (!TALUS_HAS_FIELD(talus_state_layout, layout, state))
        return fail(e, -1, "instance_state: layout structure too small");
    layout->n_state = static_cast<std::uint32_t>(inst->desc_ptrs.size());
    layout->state = inst->desc_ptrs.data();
    return TALUS_STATUS_OK;
}

std::int32_t update(const talus_instance *i, const talus_batch *b, talus_error *e) {
    const auto *inst = reinterpret_cast<const Instance *>(i);
    if (!TALUS_HAS_FIELD(talus_batch, b, rotation))
        return fail(e, -1, "the UMAT adapter needs a host of ABI 1.1 (the increment's rotation)");
    const std::uint32_t ns = b->state_size;
    const auto nstatv = static_cast<std::uint32_t>(inst->nstatv);
    if (ns != nstatv + 6) return fail(e, -1, "state size mismatch");
    if (b->n_points > 0 && (!b->rotation || !b->point_id || !b->characteristic_length))
        return fail(e, -1, "the batch lacks the increment's rotation or the points' context");
    const bool want_c = (b->flags & TALUS_BATCH_WANT_WAVE_SPEED) != 0;
    const bool want_t = (b->flags & TALUS_BATCH_WANT_TANGENT) != 0;
    std::int32_t ndi = 3, nshr = 3, ntens = 6, nstatv_arg = inst->nstatv;
    auto nprops = static_cast<std::int32_t>(inst->props.size());
    double *props = const_cast<double *>(inst->props.data());
    double dummy_props = 0.0, dummy_statev = 0.0;
    char cmname[80];
    for (std::uint64_t p = 0; p < b->n_points; ++p) {
        const double *s0 = b->stress_start + 6 * p;
        const double *de = b->strain_increment + 6 * p;
        const double *q0 = b->state_start + ns * p;
        if (!finite(s0, 6) || !finite(de, 6) || !finite(q0, ns) || !(b->density[p] > 0.0))
            return fail(e, static_cast<std::int64_t>(p),
                        "non-finite input (stress, strain increment or state) or non-positive "
                        "density at point " +
                            std::to_string(p));
        // Inputs in Abaqus' order, read before any output is written (the
        // host may update in place).
        double stress[6], stran[6], dstran[6], ddsdde[36] = {};
        double strain_start[6];
        std::memcpy(strain_start, q0 + nstatv, sizeof strain_start);
        const double *Q = b->rotation + 9 * p;
        rotate_strain(Q, strain_start);
        for (int a = 0; a < 6; ++a) {
            stress[a] = s0[kFromAbaqus[static_cast<std::size_t>(a)]];
            stran[a] = strain_start[kFromAbaqus[static_cast<std::size_t>(a)]];
            dstran[a] = de[kFromAbaqus[static_cast<std::size_t>(a)]];
        }
        double *q1 = b->state_end + ns * p;
        if (q1 != q0) std::memcpy(q1, q0, nstatv * sizeof(double));
        double *statev = nstatv ? q1 : &dummy_statev;
        double sse = 0, spd = 0, scd = 0, rpl = 0, drpldt = 0, ddsddt[6] = {}, drplde[6] = {};
        double time[2] = {b->time, b->time}, dtime = b->dt, temp = 0, dtemp = 0;
        double predef[1] = {0}, dpred[1] = {0}, coords[3] = {0, 0, 0};
        double drot[9], dfgrd0[9], dfgrd1[9];
        const double *F0 = b->F_start + 9 * p, *F1 = b->F_end + 9 * p;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) { // column-major: (r, c) at 3 c + r
                drot[3 * c + r] = Q[3 * r + c];
                dfgrd0[3 * c + r] = F0[3 * r + c];
                dfgrd1[3 * c + r] = F1[3 * r + c];
            }
        double pnewdt = 1.0e36; // Abaqus passes a large value; the UMAT lowers it
        double celent = b->characteristic_length[p];
        std::int32_t noel = static_cast<std::int32_t>(b->point_id[p] + 1), npt = 1, layer = 1,
                     kspt = 1, kstep = 1, kinc = static_cast<std::int32_t>(b->step);
        std::memcpy(cmname, inst->cmname.data(), sizeof cmname);
        double *pr = nprops ? props : &dummy_props;
        if (inst->fortran)
            inst->fortran(stress, statev, ddsdde, &sse, &spd, &scd, &rpl, ddsddt, drplde, &drpldt,
                          stran, dstran, time, &dtime, &temp, &dtemp, predef, dpred, cmname, &ndi,
                          &nshr, &ntens, &nstatv_arg, pr, &nprops, coords, drot, &pnewdt, &celent,
                          dfgrd0, dfgrd1, &noel, &npt, &layer, &kspt, &kstep, &kinc, sizeof cmname);
        else
            inst->c(stress, statev, ddsdde, &sse, &spd, &scd, &rpl, ddsddt, drplde, &drpldt, stran,
                    dstran, time, &dtime, &temp, &dtemp, predef, dpred, cmname, &ndi, &nshr, &ntens,
                    &nstatv_arg, pr, &nprops, coords, drot, &pnewdt, &celent, dfgrd0, dfgrd1, &noel,
                    &npt, &layer, &kspt, &kstep, &kinc);
        if (pnewdt < 1.0) {
            if (e) {
                e->point_index = static_cast<std::int64_t>(p);
                e->cut_factor = std::clamp(pnewdt, 0.01, 0.99);
            }
            message(e, "the UMAT set PNEWDT = " + std::to_string(pnewdt) + " at point " +
                           std::to_string(p) + " (particle " + std::to_string(b->point_id[p]) +
                           ")");
            return TALUS_STATUS_CUT_STEP;
        }
        // Outputs back in Talus' order.
        double *s1 = b->stress_end + 6 * p;
        for (int a = 0; a < 6; ++a)
            s1[kFromAbaqus[static_cast<std::size_t>(a)]] = stress[a];
        double *strain_end = q1 + nstatv;
        for (int a = 0; a < 6; ++a)
            strain_end[a] = strain_start[a] + de[a];
        double D[36]; // Talus order, row-major
        for (int r = 0; r < 6; ++r)
            for (int c = 0; c < 6; ++c)
                D[6 * kFromAbaqus[static_cast<std::size_t>(r)] +
                  kFromAbaqus[static_cast<std::size_t>(c)]] = ddsdde[6 * c + r];
        if (want_t) std::memcpy(b->tangent + 36 * p, D, sizeof D);
        if (want_c) {
            double M = inst->p_wave_modulus;
            if (!(M > 0.0)) {
                // The 13 eigenvalue problems cost more than most UMATs: a
                // tangent equal to the thread's last one (an elastic UMAT,
                // or points in the same elastic state) reuses its modulus.
                thread_local double last_D[36] = {};
                thread_local double last_M = -1.0;
                if (last_M < 0.0 || std::memcmp(last_D, D, sizeof D) != 0) {
                    last_M = p_wave_modulus(D);
                    std::memcpy(last_D, D, sizeof D);
                }
                M = last_M;
            }
            b->wave_speed[p] = std::sqrt(M / b->density[p]);
        }
    }
    return TALUS_STATUS_OK;
}

// ------------------------------------------------------------ descriptors --

constexpr double kInf = std::numeric_limits<double>::infinity();

// One optional parameter: a string (with its default, also the example), or
// a number or list of numbers (default 0 or empty, within [lo, hi]).
constexpr talus_param_desc param(std::uint32_t type, const char *key, const char *unit,
                                 const char *doc, double lo = -kInf, double hi = kInf,
                                 const char *default_string = nullptr) {
    return talus_param_desc{
        sizeof(talus_param_desc), type,          0, 0, key, unit, doc, 0.0, lo, hi, 0.0, 0, 0,
        default_string,           default_string};
}
constexpr talus_param_desc text(const char *key, const char *doc, const char *default_string) {
    return param(TALUS_PARAM_STRING, key, "-", doc, -kInf, kInf, default_string);
}
constexpr talus_param_desc required(talus_param_desc p) {
    p.flags |= TALUS_PARAM_REQUIRED;
    return p;
}

constexpr talus_param_desc p_library =
    required(text("library",
                  "The shared library holding the compiled UMAT (e.g. gfortran -shared -fPIC "
                  "umat.f -o umat.so); a relative path is relative to the input file's folder.",
                  nullptr));
constexpr talus_param_desc p_entry = text(
    "entry", "The UMAT's symbol in the library: 'umat_' for gfortran's SUBROUTINE UMAT.", "umat_");
constexpr talus_param_desc p_convention =
    text("calling_convention",
         "'fortran': every argument by reference and CMNAME's hidden length appended; 'c': the "
         "same without the hidden length.",
         "fortran");
constexpr talus_param_desc p_props =
    param(TALUS_PARAM_REAL_ARRAY, "props", "-",
          "PROPS: the UMAT's material constants, in its own order and units.");
constexpr talus_param_desc p_nstatv =
    param(TALUS_PARAM_INTEGER, "nstatv", "-",
          "NSTATV: the number of state variables (STATEV) per point.", 0.0, 10000.0);
constexpr talus_param_desc p_names =
    text("state_names",
         "Names of the NSTATV state variables, comma-separated, lower_snake_case (default "
         "statev_1, statev_2, ...).",
         "");
constexpr talus_param_desc p_depvar =
    param(TALUS_PARAM_REAL_ARRAY, "depvar", "-",
          "Initial values of the NSTATV state variables (default 0), as Abaqus' *DEPVAR with "
          "SDVINI would set them.");
constexpr talus_param_desc p_cmname =
    text("cmname", "CMNAME as the UMAT sees it (default: the material's name, upper case).", "");
constexpr talus_param_desc p_pwave =
    param(TALUS_PARAM_REAL, "p_wave_modulus", "Pa",
          "rho c^2 for the time step: 0 takes the largest acoustic-tensor eigenvalue of DDSDDE "
          "over 13 directions; give the elastic P-wave modulus for a UMAT whose DDSDDE softens.",
          0.0, kInf);
constexpr const talus_param_desc *params[kParams] = {&p_library, &p_entry,  &p_convention,
                                                     &p_props,   &p_nstatv, &p_names,
                                                     &p_depvar,  &p_cmname, &p_pwave};

constexpr const char *kDoc =
    "Runs a compiled Abaqus UMAT unchanged: STRESS, STATEV, DDSDDE, STRAN, DSTRAN, DROT, "
    "DFGRD0/1, CELENT and PNEWDT in Abaqus' conventions (component order 11 22 33 12 13 23, "
    "engineering shear strains), the state layout sized by nstatv. Temperatures, predefined "
    "fields, COORDS and the energies SSE, SPD, SCD are not passed (zero). docs/umat.md.";

constexpr talus_model make_model(const char *id, const char *name, std::uint32_t extra_flags) {
    return talus_model{sizeof(talus_model),
                       TALUS_MODEL_TANGENT | TALUS_MODEL_INSTANCE_STATE |
                           TALUS_MODEL_WANTS_ROTATION | extra_flags,
                       kParams,
                       0,
                       id,
                       name,
                       "1.0.0",
                       kDoc,
                       params,
                       nullptr,
                       create,
                       destroy,
                       update,
                       create_ex,
                       instance_state,
                       nullptr};
}

// `umat` serialises its calls (Fortran SAVE and COMMON data are common in
// UMATs); `umat_reentrant` is for UMATs known to keep no such data.
constexpr talus_model model_serial =
    make_model("umat", "Abaqus UMAT (calls serialised)", TALUS_MODEL_NOT_REENTRANT);
constexpr talus_model model_parallel =
    make_model("umat_reentrant", "Abaqus UMAT (reentrant: called from several threads)", 0);
constexpr const talus_model *models[] = {&model_serial, &model_parallel};

constexpr talus_library library = {sizeof(talus_library),
                                   TALUS_ABI_VERSION_MAJOR,
                                   TALUS_ABI_VERSION_MINOR,
                                   2,
                                   "talus_umat_adapter",
                                   "1.0.0",
                                   models,
                                   nullptr};

} // namespace

TALUS_PLUGIN_EXPORT std::int32_t talus_material_entry(const talus_host_info *host,
                                                      const talus_library **lib, talus_error *e) {
    if (!host || !lib) return fail(e, -1, "entry: null host or library pointer");
    if (host->abi_major != TALUS_ABI_VERSION_MAJOR || host->abi_minor < 1)
        return fail(e, -1,
                    "talus_umat_adapter was built for Talus material ABI " +
                        std::to_string(TALUS_ABI_VERSION_MAJOR) + "." +
                        std::to_string(TALUS_ABI_VERSION_MINOR) +
                        " and needs ABI 1.1; the host "
                        "speaks ABI " +
                        std::to_string(host->abi_major) + "." + std::to_string(host->abi_minor));
    *lib = &library;
    return TALUS_STATUS_OK;
}
