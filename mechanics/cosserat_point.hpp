// The Cosserat rod equations at one parameter value, templated on the scalar so that the same code
// gives residuals (double) and exact derivatives (Eigen's forward-mode AutoDiffScalar). Internal to
// mechanics/.
//
// Conventions: quaternions are (w, x, y, z) and need not be unit: R(q) = P(q) / |q|^2 with P the
// quadratic form of the rotation matrix, which is orthogonal for every q != 0. The material
// curvature is kappa = axial(R^T R') = 2 vec(conj(q) q') / |q|^2, again valid for any q != 0.
// Derivatives ' are with respect to the curve parameter u; J0 = |r0'(u)| converts to reference arc
// length s.
#pragma once

#include <Eigen/Core>

namespace rodfab::mechanics::detail {

template <class T> using V3 = Eigen::Matrix<T, 3, 1>;
template <class T> using V4 = Eigen::Matrix<T, 4, 1>;
template <class T> using M3 = Eigen::Matrix<T, 3, 3>;

// P(q) = |q|^2 R(q).
template <class T>
M3<T> rotationNumerator(const V4<T>& q) {
  const T &w = q[0], &x = q[1], &y = q[2], &z = q[3];
  M3<T> p;
  p << w * w + x * x - y * y - z * z, T(2) * (x * y - w * z), T(2) * (x * z + w * y),
       T(2) * (x * y + w * z), w * w - x * x + y * y - z * z, T(2) * (y * z - w * x),
       T(2) * (x * z - w * y), T(2) * (y * z + w * x), w * w - x * x - y * y + z * z;
  return p;
}

// d/du P(q(u)) for q' = dq.
template <class T>
M3<T> rotationNumeratorDerivative(const V4<T>& q, const V4<T>& dq) {
  const T &w = q[0], &x = q[1], &y = q[2], &z = q[3];
  const T &dw = dq[0], &dx = dq[1], &dy = dq[2], &dz = dq[3];
  M3<T> p;
  p << T(2) * (w * dw + x * dx - y * dy - z * dz), T(2) * (dx * y + x * dy - dw * z - w * dz),
       T(2) * (dx * z + x * dz + dw * y + w * dy),
       T(2) * (dx * y + x * dy + dw * z + w * dz), T(2) * (w * dw - x * dx + y * dy - z * dz),
       T(2) * (dy * z + y * dz - dw * x - w * dx),
       T(2) * (dx * z + x * dz - dw * y - w * dy), T(2) * (dy * z + y * dz + dw * x + w * dx),
       T(2) * (w * dw - x * dx - y * dy + z * dz);
  return p;
}

// vec(conj(a) b): the vector part of the product of a's conjugate with b.
template <class T>
V3<T> conjugateProductVector(const V4<T>& a, const V4<T>& b) {
  const V3<T> av = a.template tail<3>(), bv = b.template tail<3>();
  return a[0] * bv - b[0] * av - av.cross(bv);
}

// Hamilton product a b.
template <class T>
V4<T> quaternionProduct(const V4<T>& a, const V4<T>& b) {
  V4<T> r;
  const V3<T> av = a.template tail<3>(), bv = b.template tail<3>();
  r[0] = a[0] * b[0] - av.dot(bv);
  r.template tail<3>() = a[0] * bv + b[0] * av + av.cross(bv);
  return r;
}

// The strain measures in the parameter, before subtracting the reference: Gamma = R^T r' and
// K = 2 vec(conj(q) q') / |q|^2, and their u-derivatives.
template <class T>
struct StrainMeasures {
  M3<T> R, dR;
  V3<T> gamma, dGamma, curvature, dCurvature;
};

template <class T>
StrainMeasures<T> strainMeasures(const V3<T>& dr, const V3<T>& ddr, const V4<T>& q, const V4<T>& dq, const V4<T>& ddq) {
  StrainMeasures<T> m;
  const T s = q.squaredNorm();
  const T ds = T(2) * q.dot(dq);
  const M3<T> p = rotationNumerator(q);
  m.R = p / s;
  m.dR = rotationNumeratorDerivative(q, dq) / s - p * (ds / (s * s));
  m.gamma = m.R.transpose() * dr;
  m.dGamma = m.dR.transpose() * dr + m.R.transpose() * ddr;
  m.curvature = conjugateProductVector(q, dq) * (T(2) / s);
  // vec(conj(q') q') = 0, so only q'' contributes to the derivative of the numerator.
  m.dCurvature = conjugateProductVector(q, ddq) * (T(2) / s) - m.curvature * (ds / s);
  return m;
}

// Per collocation point constants: reference geometry, stiffness and loads.
struct PointConstants {
  double J0 = 1.0, dJ0 = 0.0;                // |r0'| and its u-derivative
  Eigen::Vector3d gamma0, dGamma0, curvature0, dCurvature0;  // reference strain measures
  double E = 0.0, dE = 0.0;                  // modulus and its u-derivative
  Eigen::Vector3d shearExtension;            // (k G A, k G A, E A) / E
  Eigen::Vector3d bendingTorsion;            // (E I1, E I2, G J) / E
  Eigen::Vector3d distributedForce = Eigen::Vector3d::Zero();  // n_ext per reference length, at full load
};

// Stress resultants in space: n = R C eps, m = R D kappa.
template <class T>
void stressResultants(const StrainMeasures<T>& sm, const PointConstants& c, V3<T>& n, V3<T>& m) {
  const V3<T> eps = (sm.gamma - c.gamma0.cast<T>()) / T(c.J0);
  const V3<T> kappa = (sm.curvature - c.curvature0.cast<T>()) / T(c.J0);
  n = sm.R * (eps.cwiseProduct(c.shearExtension.cast<T>()) * T(c.E));
  m = sm.R * (kappa.cwiseProduct(c.bendingTorsion.cast<T>()) * T(c.E));
}

// Equilibrium in u at an interior collocation point: n' + J0 n_ext, m' + r' x n + J0 m_ext, and
// the unit-norm condition |q|^2 - 1; `load` scales the external loads.
template <class T>
Eigen::Matrix<T, 7, 1> equilibriumResidual(const V3<T>& dr, const V3<T>& ddr, const V4<T>& q, const V4<T>& dq,
                                           const V4<T>& ddq, const PointConstants& c, double load) {
  const StrainMeasures<T> sm = strainMeasures(dr, ddr, q, dq, ddq);
  const T J0(c.J0), dJ0(c.dJ0);
  const V3<T> eps = (sm.gamma - c.gamma0.cast<T>()) / J0;
  const V3<T> dEps = (sm.dGamma - c.dGamma0.cast<T>()) / J0 - eps * (dJ0 / J0);
  const V3<T> kappa = (sm.curvature - c.curvature0.cast<T>()) / J0;
  const V3<T> dKappa = (sm.dCurvature - c.dCurvature0.cast<T>()) / J0 - kappa * (dJ0 / J0);
  const V3<T> C = c.shearExtension.cast<T>(), D = c.bendingTorsion.cast<T>();
  const V3<T> nLocal = eps.cwiseProduct(C) * T(c.E);
  const V3<T> dnLocal = eps.cwiseProduct(C) * T(c.dE) + dEps.cwiseProduct(C) * T(c.E);
  const V3<T> mLocal = kappa.cwiseProduct(D) * T(c.E);
  const V3<T> dmLocal = kappa.cwiseProduct(D) * T(c.dE) + dKappa.cwiseProduct(D) * T(c.E);
  const V3<T> n = sm.R * nLocal;
  const V3<T> dn = sm.dR * nLocal + sm.R * dnLocal;
  const V3<T> dm = sm.dR * mLocal + sm.R * dmLocal;
  Eigen::Matrix<T, 7, 1> f;
  f.template head<3>() = dn + (c.distributedForce * (c.J0 * load)).cast<T>();
  f.template segment<3>(3) = dm + dr.cross(n);
  f[6] = q.squaredNorm() - T(1);
  return f;
}

}  // namespace rodfab::mechanics::detail
