// Return mapping of linear elastic - perfectly plastic Mohr-Coulomb with a
// tension cut-off, in principal stress space.
//
// The method is the one of Clausen, Damkilde & Andersen: "Efficient return
// algorithms for associated plasticity with multiple yield planes", Int. J.
// Numer. Meth. Engng 66 (2006) 1036-1059, and "An efficient return algorithm
// for non-associated plasticity with linear yield criteria in principal
// stress space", Computers & Structures 85 (2007) 1795-1807. With the
// principal stresses ordered, sigma_1 >= sigma_2 >= sigma_3 (tension
// positive), every yield criterion is a plane, so the backward-Euler return
// of a trial stress onto a plane, onto the line where two planes meet or onto
// the point where three meet is the solution of a linear system of at most
// three equations, and is exact (no iteration). Which of them is the answer
// follows from the trial stress: the return is valid when its plastic
// multipliers are non-negative, the returned stress keeps the principal
// order and violates no plane. The candidates are tried from the simplest
// (one plane) to the points, and the first valid one is the return; the
// regions of the trial space that lead to each are exactly the ones the
// papers construct from the flow directions (tests/unit/plugins/test_mohr_coulomb.cpp
// checks that at most one candidate is valid at random trial stresses).
//
// Planes, ordered principal stresses s = (s1, s2, s3), tension positive:
//   shear, Mohr-Coulomb  f = (1 + sin phi) s1 - (1 - sin phi) s3 - 2 c cos phi
//                        (tau = c - sigma_n tan phi on the plane of s1, s3)
//   tension cut-off      f = s1 - T
// and their permutations for the edges (s1 = s2: triaxial compression in
// the soil-mechanics sense, the axial stress the most compressive; s2 = s3:
// triaxial extension). The plastic potential of the shear planes has the
// dilation angle psi in place of phi (non-associated flow); the cut-off is
// associated.
//
// Header-only so that the tests can reach each piece directly; the plugin
// (mohr_coulomb.cpp) is the only other user.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU> // Matrix3d::inverse and determinant (closed form for 3 x 3)

#include <algorithm>
#include <array>
#include <cmath>

// Functions written once over a lane type (see "The validity tests
// below") are always inlined.
#if defined(__GNUC__) || defined(__clang__)
#define TALUS_MC_LANE_INLINE [[gnu::always_inline]] inline
#else
#define TALUS_MC_LANE_INLINE inline
#endif

namespace talus_mc {

using V3 = Eigen::Vector3d;
using M3 = Eigen::Matrix3d;

// What a return did: the state variable yield_mode holds this code.
enum Mode : int {
    kElastic = 0,
    kShearPlane = 1,
    kCompressionEdge = 2,         // s1 = s2 on the shear planes (triaxial compression)
    kExtensionEdge = 3,           // s2 = s3 on the shear planes (triaxial extension)
    kShearApex = 4,               // s1 = s2 = s3 = c cot phi (no cut-off below it)
    kTensionPlane = 5,            // s1 = T
    kTensionEdge = 6,             // s1 = s2 = T
    kTensionApex = 7,             // s1 = s2 = s3 = T
    kShearTensionLine = 8,        // s1 = T on the shear plane
    kShearTensionCompression = 9, // s1 = s2 = T on the shear planes
    kShearTensionExtension = 10,  // s1 = T, s2 = s3 on the shear planes
    kModeCount = 11,
};

// Strength at one value of the hardening variable.
struct Strength {
    double sin_phi = 0.0;
    double cos_phi = 1.0;
    double sin_psi = 0.0;
    double cohesion = 0.0;
    double tension = 0.0; // the cut-off T
    // False when the cut-off lies beyond the shear apex c cot phi (it can
    // then never be reached); always true for phi = 0, which has no apex.
    bool tension_active = true;
};

// Isotropic elasticity in principal space: D = lambda 1 1^T + 2 G I.
struct Elastic {
    double shear = 0.0;
    double lambda = 0.0;
    V3 apply(const V3 &x) const { return lambda * x.sum() * V3::Ones() + 2.0 * shear * x; }
    // D^-1 x = x / 2G - lambda tr(x) / (2G (3 lambda + 2G)) 1, for one
    // point (double) or a vector of them, in one order of operations.
    template <class T>
    TALUS_MC_LANE_INLINE void solve(const T x[3], T out[3]) const {
        const T v = lambda * ((x[0] + x[1]) + x[2]) / (2.0 * shear * (3.0 * lambda + 2.0 * shear));
        for (int i = 0; i < 3; ++i)
            out[i] = x[i] / (2.0 * shear) - v;
    }
    V3 solve(const V3 &x) const {
        V3 out;
        solve(x.data(), out.data());
        return out;
    }
    M3 matrix() const { return lambda * M3::Ones() + 2.0 * shear * M3::Identity(); }
};

// The planes and flow directions of the ordered sector.
//   planes: 0 shear (1,3)  1 shear (2,3)  2 shear (1,2)  3..5 tension s1, s2, s3
//   flows:  0..5 as the planes (potential with psi), 6..8 the shear
//           potentials of the other orderings (2,1), (3,1), (3,2), needed
//           only to span the flow cone at the apex.
struct Planes {
    std::array<V3, 6> a;
    std::array<double, 6> k{};
    std::array<V3, 9> b;

    explicit Planes(const Strength &s) {
        const double p = 1.0 + s.sin_phi, m = 1.0 - s.sin_phi;
        const double pp = 1.0 + s.sin_psi, mp = 1.0 - s.sin_psi;
        const double kc = 2.0 * s.cohesion * s.cos_phi;
        a[0] = V3(p, 0.0, -m);
        a[1] = V3(0.0, p, -m);
        a[2] = V3(p, -m, 0.0);
        k[0] = k[1] = k[2] = kc;
        b[0] = V3(pp, 0.0, -mp);
        b[1] = V3(0.0, pp, -mp);
        b[2] = V3(pp, -mp, 0.0);
        for (int i = 0; i < 3; ++i) {
            a[3 + i] = V3::Unit(i);
            k[3 + i] = s.tension;
            b[3 + i] = V3::Unit(i);
        }
        b[6] = V3(-mp, pp, 0.0);
        b[7] = V3(-mp, 0.0, pp);
        b[8] = V3(0.0, -mp, pp);
    }
};

// The validity tests below are written once over a lane type T: a double
// (one point), or a GCC vector of doubles (one point a lane, with the same
// operations in the same order, so that a point's bits do not depend on
// which form tested it: plane_lanes.hpp). Comparisons give a bool or a lane
// mask; &, | and flip() combine both. Results are out-parameters and the
// functions always inlined (TALUS_MC_LANE_INLINE), so that no vector passes
// by value through code compiled for the baseline target.

// m's complement in place: a bool's !, every bit of a lane mask flipped
// (GCC lowers ! on a vector lane by lane, in scalar code).
template <class M>
TALUS_MC_LANE_INLINE void flip(M &m) {
    m = m ^ (m == m);
}

// Shear yield function of ordered principal stresses, in the form above.
template <class T>
TALUS_MC_LANE_INLINE void shear_yield(const T s[3], const Strength &st, T &f) {
    f = (1.0 + st.sin_phi) * s[0] - (1.0 - st.sin_phi) * s[2] - 2.0 * st.cohesion * st.cos_phi;
}
inline double shear_yield(const V3 &s, const Strength &st) {
    double f;
    shear_yield(s.data(), st, f);
    return f;
}

// A candidate: the planes that hold as equalities and the flow directions
// whose multipliers are unknowns (as many as planes).
struct Candidate {
    Mode mode;
    int n;
    std::array<int, 3> planes;
    std::array<int, 3> flows;
    bool uses_tension;
};

// In the order they are tried: planes, lines, points. The points list each
// choice of three flow directions that spans part of their flow cone
// (Caratheodory: any direction in the cone lies in the cone of three).
//
// The apex (of the cut-off when it is active, else of the shear planes) is
// not a candidate but the answer when no candidate is valid. With
// associated flow that region is exactly the apex's normal cone. With psi <
// phi the potentials' cone at the apex is narrower than the surface's, and
// trial stresses remain (beyond the apex, in hydrostatic tension) that no
// return along the potentials can reach; their stress goes to the apex as
// well, the plastic strain being what the elastic law then requires. This
// is the usual vertex treatment (de Souza Neto, Peric & Owen 2008, sec.
// 8.2.2) and keeps the return continuous: at the boundary of that region
// the plane and edge returns arrive at the apex.
inline constexpr std::array<Candidate, 12> kCandidates = {{
    {kShearPlane, 1, {0, 0, 0}, {0, 0, 0}, false},
    {kTensionPlane, 1, {3, 0, 0}, {3, 0, 0}, true},
    {kCompressionEdge, 2, {0, 1, 0}, {0, 1, 0}, false},
    {kExtensionEdge, 2, {0, 2, 0}, {0, 2, 0}, false},
    {kShearTensionLine, 2, {0, 3, 0}, {0, 3, 0}, true},
    {kTensionEdge, 2, {3, 4, 0}, {3, 4, 0}, true},
    {kShearTensionExtension, 3, {0, 2, 3}, {0, 2, 3}, true},
    {kShearTensionCompression, 3, {0, 1, 3}, {0, 1, 3}, true},
    {kShearTensionCompression, 3, {0, 1, 3}, {0, 1, 4}, true},
    {kShearTensionCompression, 3, {0, 1, 3}, {0, 3, 4}, true},
    {kShearTensionCompression, 3, {0, 1, 3}, {1, 3, 4}, true},
    {kTensionApex, 3, {3, 4, 5}, {3, 4, 5}, true},
}};

inline constexpr int kNone = -1;
inline constexpr int kApex = -2;

struct Return {
    Mode mode = kElastic;
    V3 stress = V3::Zero(); // ordered principal stresses after the return
    M3 P = M3::Identity();  // d stress / d trial stress (principal, fixed candidate)
    int candidate = -1;     // index into kCandidates; kNone elastic, kApex at the apex
};

// Tolerance of the validity tests, relative to the stress scale of the
// problem: the linear solves lose a few ulps of the largest stress, so 1e-10
// of it separates rounding from a real violation with a wide margin. The
// cut-off T is not part of the scale: a large T (a cut-off in effect
// switched off) would blur the yield point; where T matters the stress is
// of its size anyway.
// (A maximum is exact: any order of comparisons gives the same value.)
template <class T>
TALUS_MC_LANE_INLINE void stress_tolerance(const T t[3], const Strength &st, T &tol) {
    T m = t[0] < 0.0 ? -t[0] : t[0];
    for (int i = 1; i < 3; ++i) {
        const T a = t[i] < 0.0 ? -t[i] : t[i];
        m = m < a ? a : m;
    }
    m = m < st.cohesion ? T{} + st.cohesion : m;
    tol = 1e-10 * (m < 1e-300 ? T{} + 1e-300 : m);
}
inline double stress_tolerance(const V3 &trial, const Strength &st) {
    double tol;
    stress_tolerance(trial.data(), st, tol);
    return tol;
}

// Whether the ordered principal stress s lies inside the yield surface.
template <class T, class M>
TALUS_MC_LANE_INLINE void admissible(const T s[3], const Strength &st, const T &tol, M &in) {
    T f;
    shear_yield(s, st, f);
    in = f > tol;
    if (st.tension_active) in = in | (s[0] - st.tension > tol);
    flip(in);
}
inline bool admissible(const V3 &s, const Strength &st, double tol) {
    bool in = false;
    admissible(s.data(), st, tol, in);
    return in;
}

// Within the validity tolerance of the shear plane or the cut-off: a
// stress left there without plastic flow keeps its yield mode.
template <class T, class M>
TALUS_MC_LANE_INLINE void on_surface(const T s[3], const Strength &st, const T &tol, M &on) {
    T f;
    shear_yield(s, st, f);
    on = f > -tol;
    if (st.tension_active) on = on | (s[0] - st.tension > -tol);
}
inline bool on_surface(const V3 &s, const Strength &st) {
    const double tol = stress_tolerance(s, st);
    bool on = false;
    on_surface(s.data(), st, tol, on);
    return on;
}

// The linear system of one candidate: M = A D B (the planes' normals A, the
// flow directions B, D the elastic matrix) and what follows from it alone,
// M^-1 and P = I - D B M^-1 A, the derivative of the return with respect to
// the trial stress (Clausen et al. 2007, sec. 4). None of it depends on the
// trial stress, so a model with a fixed strength solves it once (Systems).
// Not solvable when M is singular (apex triples that do not span 3D, the
// apex of phi = 0).
struct System {
    bool solvable = false;
    M3 DB = M3::Zero();   // columns D b_j, j < n; zero beyond
    M3 Minv = M3::Zero(); // M^-1 in the top-left n x n; zero beyond
    M3 P = M3::Identity();
};

inline System make_system(const Candidate &c, const Planes &pl, const Elastic &el) {
    System sys;
    const int n = c.n;
    Eigen::Matrix3d M = Eigen::Matrix3d::Identity();
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    for (int j = 0; j < n; ++j)
        sys.DB.col(j) =
            el.apply(pl.b[static_cast<std::size_t>(c.flows[static_cast<std::size_t>(j)])]);
    for (int i = 0; i < n; ++i) {
        const std::size_t pi = static_cast<std::size_t>(c.planes[static_cast<std::size_t>(i)]);
        A.row(i) = pl.a[pi].transpose();
        for (int j = 0; j < n; ++j)
            M(i, j) = pl.a[pi].dot(sys.DB.col(j));
    }
    // The n x n inverse in closed form (cofactors): at most 3 x 3. Singular
    // when the determinant is below 1e-12 of the scale M_max^n: the apex
    // triples that do not span 3D give exactly zero, every other candidate
    // is far above (the products a D b are of the order of the elastic
    // moduli).
    const double scale = M.topLeftCorner(n, n).cwiseAbs().maxCoeff();
    if (n == 1) {
        if (!(std::abs(M(0, 0)) > 0.0)) return sys;
        sys.Minv(0, 0) = 1.0 / M(0, 0);
    } else if (n == 2) {
        const double det = M(0, 0) * M(1, 1) - M(0, 1) * M(1, 0);
        if (!(std::abs(det) > 1e-12 * scale * scale)) return sys;
        sys.Minv(0, 0) = M(1, 1) / det;
        sys.Minv(0, 1) = -M(0, 1) / det;
        sys.Minv(1, 0) = -M(1, 0) / det;
        sys.Minv(1, 1) = M(0, 0) / det;
    } else {
        const double det = M.determinant();
        if (!(std::abs(det) > 1e-12 * scale * scale * scale)) return sys;
        sys.Minv = M.inverse();
    }
    // Rows of A and columns of DB beyond n are zero, so the full 3 x 3
    // products are the n-sized ones.
    sys.P = M3::Identity() - sys.DB * sys.Minv * A;
    sys.solvable = true;
    return sys;
}

// The solve of one candidate at an ordered trial stress, without the
// validity tests: false when its system is singular. Fills the
// multipliers dl = M^-1 (A trial - k) and the returned stress trial - D B dl
// (out.P is left as it was: sys.P is the return's derivative).
inline bool solve_candidate(const Candidate &c, const System &sys, const V3 &trial,
                            const Planes &pl, V3 &dl, Return &out) {
    if (!sys.solvable) return false;
    V3 rhs = V3::Zero();
    for (int i = 0; i < c.n; ++i) {
        const std::size_t pi = static_cast<std::size_t>(c.planes[static_cast<std::size_t>(i)]);
        rhs[i] = pl.a[pi].dot(trial) - pl.k[pi];
    }
    dl = sys.Minv * rhs;
    out.stress = trial - sys.DB * dl;
    out.mode = c.mode;
    return true;
}

// Every candidate's system at one strength: computed once for a model
// without softening, where each return then needs only its right-hand
// sides (a plastic point's solves were a tenth of its update when each
// built and inverted its M).
struct Systems {
    Planes planes;
    std::array<System, kCandidates.size()> of;
    Systems(const Strength &st, const Elastic &el) : planes(st) {
        for (std::size_t i = 0; i < kCandidates.size(); ++i)
            of[i] = make_system(kCandidates[i], planes, el);
    }
};

// The return onto one plane (a candidate with n = 1: the shear plane, the
// cut-off plane) and its tests: the multiplier non-negative, the principal
// order kept, no plane violated. `s`: the returned stress, `valid` the
// verdict (a bool or a lane mask). sys must be solvable.
template <class T, class M>
TALUS_MC_LANE_INLINE void plane_return(const Candidate &c, const System &sys, const T t[3],
                                       const Planes &pl, const Strength &st, const T &tol, T s[3],
                                       M &valid) {
    const std::size_t plane = static_cast<std::size_t>(c.planes[0]);
    const V3 &a = pl.a[plane];
    const T rhs = ((a[0] * t[0] + a[1] * t[1]) + a[2] * t[2]) - pl.k[plane];
    const T dl = sys.Minv(0, 0) * rhs;
    for (int i = 0; i < 3; ++i)
        s[i] = t[i] - sys.DB(i, 0) * dl;
    // Multipliers are strain-like; tested relative to the largest one.
    const T mag = dl < 0.0 ? -dl : dl;
    const T lscale = mag < 1e-300 ? T{} + 1e-300 : mag;
    M in;
    admissible(s, st, tol, in);
    M bad = (dl < -1e-10 * lscale) | (s[0] - s[1] < -tol) | (s[1] - s[2] < -tol);
    flip(bad);
    valid = bad & in;
}

// Solves one candidate and tests it: multipliers non-negative, principal
// order kept, no plane violated.
inline bool try_candidate(const Candidate &c, const System &sys, const V3 &trial, const Planes &pl,
                          const Strength &st, double tol, Return &out) {
    if (c.n == 1) {
        if (!sys.solvable) return false;
        V3 s;
        bool valid = false;
        plane_return(c, sys, trial.data(), pl, st, tol, s.data(), valid);
        if (!valid) return false;
        out.stress = s;
        out.P = sys.P;
        out.mode = c.mode;
        return true;
    }
    V3 dl;
    Return r;
    if (!solve_candidate(c, sys, trial, pl, dl, r)) return false;
    // Multipliers are strain-like; tested relative to the largest one.
    const double lscale = std::max(dl.cwiseAbs().maxCoeff(), 1e-300);
    if (dl.minCoeff() < -1e-10 * lscale) return false;
    const V3 &s = r.stress;
    if (s[0] - s[1] < -tol || s[1] - s[2] < -tol) return false;
    if (!admissible(s, st, tol)) return false;
    out.stress = s;
    out.P = sys.P;
    out.mode = r.mode;
    return true;
}

// Candidates that exist for this strength: the cut-off ones only when the
// cut-off is active.
inline bool enabled(const Candidate &c, const Strength &st) {
    return !c.uses_tension || st.tension_active;
}

// The apex of the surface: of the cut-off when it is active, else of the
// shear planes (then sin phi > 0, see Strength).
inline V3 apex(const Strength &st) {
    return V3::Constant(st.tension_active ? st.tension : st.cohesion * st.cos_phi / st.sin_phi);
}

// The first candidate of a kind of return (kNone for the elastic state and
// the shear apex, which no candidate gives).
inline int candidate_of(Mode mode) {
    for (std::size_t i = 0; i < kCandidates.size(); ++i)
        if (kCandidates[i].mode == mode) return static_cast<int>(i);
    return kNone;
}

namespace detail {

// The return with the systems from system_of(i) (candidate i's System, by
// reference or value).
template <class SystemOf>
Return return_map(const V3 &trial, const Strength &st, const Planes &pl, SystemOf &&system_of,
                  int hint) {
    Return r;
    r.stress = trial;
    const double tol = stress_tolerance(trial, st);
    if (admissible(trial, st, tol)) return r;
    if (hint >= 0 && static_cast<std::size_t>(hint) < kCandidates.size()) {
        const Candidate &c = kCandidates[static_cast<std::size_t>(hint)];
        if (enabled(c, st) && try_candidate(c, system_of(hint), trial, pl, st, tol, r)) {
            r.candidate = hint;
            return r;
        }
    }
    for (std::size_t i = 0; i < kCandidates.size(); ++i) {
        const Candidate &c = kCandidates[i];
        if (!enabled(c, st) || static_cast<int>(i) == hint) continue;
        if (try_candidate(c, system_of(static_cast<int>(i)), trial, pl, st, tol, r)) {
            r.candidate = static_cast<int>(i);
            return r;
        }
    }
    r.stress = apex(st);
    r.P.setZero();
    r.mode = st.tension_active ? kTensionApex : kShearApex;
    r.candidate = kApex;
    return r;
}

} // namespace detail

// The return of an ordered trial stress. Elastic when the trial is
// admissible. `hint`: a candidate to try first (any valid candidate gives
// the same stress, so the hint saves solves without choosing the answer).
// `sys`: the systems of st.
inline Return return_map(const V3 &trial, const Strength &st, const Systems &sys,
                         int hint = kNone) {
    return detail::return_map(
        trial, st, sys.planes,
        [&](int i) -> const System & { return sys.of[static_cast<std::size_t>(i)]; }, hint);
}

// The same, each system made when its candidate is tried (a strength used
// for one return).
inline Return return_map(const V3 &trial, const Strength &st, const Elastic &el, int hint = kNone) {
    const Planes pl(st);
    return detail::return_map(
        trial, st, pl,
        [&](int i) { return make_system(kCandidates[static_cast<std::size_t>(i)], pl, el); }, hint);
}

// The square of deviatoric_measure (below), for the lanes.
template <class T>
TALUS_MC_LANE_INLINE void deviatoric_measure_squared(const T x[3], T &out) {
    const T m = ((x[0] + x[1]) + x[2]) / 3.0;
    const T d0 = x[0] - m, d1 = x[1] - m, d2 = x[2] - m;
    out = 2.0 / 3.0 * ((d0 * d0 + d1 * d1) + d2 * d2);
}
// Equivalent plastic deviatoric strain of a principal plastic strain
// increment x: sqrt(2/3 dev(x) : dev(x)).
inline double deviatoric_measure(const V3 &x) {
    double sq;
    deviatoric_measure_squared(x.data(), sq);
    return std::sqrt(sq);
}

} // namespace talus_mc
