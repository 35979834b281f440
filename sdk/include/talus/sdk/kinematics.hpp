// talus/sdk/kinematics.hpp -- the increment's stretch in the convention of
// talus/material_abi.h: an increment with strain increment d_eps takes F to
// F_end = exp(d_eps) F_start (a pure stretch applied on the left), the
// definition the consistent tangent d sigma / d d_eps refers to. The
// material-point driver and the conformance checks move F this way, and a
// model that wants F_end from d_eps alone can do the same.
#pragma once

#include "talus/sdk/voigt.hpp"

#include <Eigen/Eigenvalues>

namespace talus::sdk {

// exp(A) of a symmetric matrix through its spectral decomposition (exact up
// to the eigensolver's round-off, and symmetric positive definite).
inline Mat3 exp_symmetric(const Mat3 &a) {
    const Eigen::SelfAdjointEigenSolver<Mat3> es(a);
    return es.eigenvectors() * es.eigenvalues().array().exp().matrix().asDiagonal() *
           es.eigenvectors().transpose();
}

// The stretch exp(d_eps) of a strain increment given with engineering shear
// (the ABI's strain_increment).
inline Mat3 increment_stretch(const Vec6 &strain_increment) {
    return exp_symmetric(strain_to_matrix(strain_increment));
}

} // namespace talus::sdk
