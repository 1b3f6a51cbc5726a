#include "solvers/kernels.hpp"

#include <algorithm>
#include <cmath>

namespace pbdbench {

double generalized_inverse_mass(const ConstraintEval& e, const Weights& w, int count) {
  double sum = 0.0;
  for (int i = 0; i < count; ++i)
    sum += w[static_cast<size_t>(i)] * e.grad[static_cast<size_t>(i)].squaredNorm();
  return sum;
}

Projection pbd_project(const ConstraintEval& e, const Weights& w, int count, double k,
                       Correction& out) {
  if (!e.valid) return Projection::Skipped;
  const double denom = generalized_inverse_mass(e, w, count);
  if (!(denom > 0.0)) return Projection::Skipped;
  // Mueller et al. 2007, sec. 3.3: s = C / sum_j w_j |grad_j C|^2, dx_i = -k s w_i grad_i C.
  const double s = e.C / denom;
  for (int i = 0; i < count; ++i) {
    const size_t j = static_cast<size_t>(i);
    out.dx[j] = (-k * s * w[j]) * e.grad[j];
  }
  out.dlambda = -k * s;
  return Projection::Applied;
}

double pbd_corrected_stiffness(double k, int iterations) {
  // Mueller et al. 2007, sec. 3.3: k' = 1 - (1 - k)^(1/n_s).
  return 1.0 - std::pow(1.0 - k, 1.0 / static_cast<double>(iterations));
}

Projection pbd_project_contact(const ConstraintEval& e, const Weights& w, int count,
                               Correction& out) {
  if (!e.valid) return Projection::Skipped;
  if (!(e.C < 0.0)) return Projection::Inactive;
  return pbd_project(e, w, count, 1.0, out);
}

XpbdCoefficients xpbd_coefficients(double compliance, double damping, double h) {
  // Macklin et al. 2016, eqs. 18 and 26.
  XpbdCoefficients c;
  c.alpha_tilde = compliance / (h * h);
  const double beta_tilde = h * h * damping;
  c.gamma = c.alpha_tilde * beta_tilde / h;
  return c;
}

Projection xpbd_project(const ConstraintEval& e, const Weights& w, int count,
                        const XpbdCoefficients& k, double lambda,
                        const std::array<Vec3, 4>& displacement, Correction& out) {
  if (!e.valid) return Projection::Skipped;
  const double wsum = generalized_inverse_mass(e, w, count);
  const double denom = (1.0 + k.gamma) * wsum + k.alpha_tilde;
  if (!(denom > 0.0)) return Projection::Skipped;
  // Macklin et al. 2016, eq. 26: the damping term gamma * grad C . (x - x_n).
  double damping_term = 0.0;
  if (k.gamma != 0.0)
    for (int i = 0; i < count; ++i)
      damping_term += e.grad[static_cast<size_t>(i)].dot(displacement[static_cast<size_t>(i)]);
  const double dlambda = (-e.C - k.alpha_tilde * lambda - k.gamma * damping_term) / denom;
  for (int i = 0; i < count; ++i) {
    const size_t j = static_cast<size_t>(i);
    out.dx[j] = (w[j] * dlambda) * e.grad[j];  // eq. 17: dx = M^-1 grad C^T dlambda
  }
  out.dlambda = dlambda;
  return Projection::Applied;
}

Projection xpbd_project_contact(const ConstraintEval& e, const Weights& w, int count, double lambda,
                                Correction& out) {
  if (!e.valid) return Projection::Skipped;
  if (!(e.C < 0.0)) return Projection::Inactive;
  const double wsum = generalized_inverse_mass(e, w, count);
  if (!(wsum > 0.0)) return Projection::Skipped;
  // Macklin et al. 2016, eq. 18 with alpha = 0; the accumulated multiplier stays >= 0.
  const double dlambda = std::max(lambda - e.C / wsum, 0.0) - lambda;
  for (int i = 0; i < count; ++i) {
    const size_t j = static_cast<size_t>(i);
    out.dx[j] = (w[j] * dlambda) * e.grad[j];
  }
  out.dlambda = dlambda;
  return Projection::Applied;
}

}  // namespace pbdbench
