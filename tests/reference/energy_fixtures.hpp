// Helpers shared by the tests of reference/: small random models that mix every term of the
// energy (distance, volume and bending constraints, compliant and rigid; stable neo-Hookean and
// corotated elements; pinned and kinematic particles), dense copies of pattern matrices, and
// finite differences over the dofs.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"
#include "core/model.hpp"
#include "reference/energy.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench::test {

// Central differences over the dofs (positions of order 1 m), as in tests/core: truncation
// ~h^2 |U'''| and round-off ~eps |U| / h, both below 1e-9 of the largest entry for the models
// drawn here; the comparisons pass at 1e-7 of the largest analytic entry plus 1e-6 relative.
inline constexpr double kDofStep = 1e-6;
inline constexpr Tolerance kDofTol{1e-7, 1e-6};

struct RandomModelOptions {
  bool at_rest = false;   // rest values measured at the rest positions (every term at its minimum)
  bool damping = false;   // some compliant and FEM-kind constraints damped
  bool kinematic = true;  // a pinned particle and three kinematic ones (static, linear, oscillating)
};

// Indices of the special particles of random_model.
inline constexpr int kPinned = 0;         // inv_mass 0, no attachment: stays at its rest position
inline constexpr int kStaticTarget = 1;   // attached, no motion
inline constexpr int kLinearTarget = 2;   // attached, Linear motion from t = 0
inline constexpr int kOscillating = 3;    // attached, Oscillate motion from t = 0
inline constexpr int kRandomParticles = 12;  // joined by the random terms
inline constexpr int kFreeParticle = 12;      // dynamic, in no term: gravity only

// A random positively oriented 4-tuple of distinct particles whose rest tet is not thin.
inline std::array<int, 4> random_tet(Random& rng, const Points& rest) {
  for (;;) {
    std::array<int, 4> t;
    for (int& p : t) p = rng.integer(0, kRandomParticles - 1);
    if (t[0] == t[1] || t[0] == t[2] || t[0] == t[3] || t[1] == t[2] || t[1] == t[3] || t[2] == t[3])
      continue;
    const double v = tet_signed_volume(rest.row(t[0]), rest.row(t[1]), rest.row(t[2]), rest.row(t[3]));
    if (std::abs(v) < 0.02) continue;
    if (v < 0.0) std::swap(t[1], t[2]);
    return t;
  }
}

inline Model random_model(Random& rng, const RandomModelOptions& o = {}) {
  Model m;
  m.name = "random";
  m.gravity = Vec3(0.3, -9.81, 0.1);
  const int n = kRandomParticles + 1;
  m.rest_positions.resize(n, 3);
  for (int p = 0; p < n; ++p) m.rest_positions.row(p) = rng.vec(-1, 1).transpose();
  m.inv_mass.assign(n, 0.0);
  m.radius.assign(n, 0.01);
  for (int p = 0; p < n; ++p) m.inv_mass[static_cast<size_t>(p)] = 1.0 / rng.uniform(0.5, 2.0);
  if (o.kinematic) {
    for (int p = kPinned; p <= kOscillating; ++p) m.inv_mass[static_cast<size_t>(p)] = 0.0;
    Motion linear;
    linear.kind = MotionKind::Linear;
    linear.velocity = Vec3(0.2, -0.1, 0.3);
    Motion osc;
    osc.kind = MotionKind::Oscillate;
    osc.amplitude = Vec3(0.1, 0.05, -0.2);
    osc.frequency = 0.7;
    m.motions = {linear, osc};
    m.attachments.push_back({kStaticTarget, m.rest_positions.row(kStaticTarget).transpose(), -1});
    m.attachments.push_back({kLinearTarget, m.rest_positions.row(kLinearTarget).transpose(), 0});
    m.attachments.push_back({kOscillating, m.rest_positions.row(kOscillating).transpose(), 1});
  }
  const Points& X = m.rest_positions;
  const auto factor = [&](double spread) { return o.at_rest ? 1.0 : rng.uniform(1.0 - spread, 1.0 + spread); };
  const auto damping = [&]() { return o.damping && rng.uniform() < 0.6 ? rng.uniform(0.05, 0.5) : 0.0; };

  for (int k = 0; k < 10; ++k) {  // distance
    Constraint c;
    c.kind = ConstraintKind::Distance;
    do {
      c.particles[0] = rng.integer(0, kRandomParticles - 1);
      c.particles[1] = rng.integer(0, kRandomParticles - 1);
    } while (c.particles[0] == c.particles[1]);
    c.rest = (X.row(c.particles[0]) - X.row(c.particles[1])).norm() * factor(0.3);
    c.compliance = rng.uniform(0.01, 0.1);
    c.damping = damping();
    m.constraints.push_back(c);
  }
  for (int k = 0; k < 3; ++k) {  // volume
    Constraint c;
    c.kind = ConstraintKind::Volume;
    c.particles = random_tet(rng, X);
    c.rest = tet_signed_volume(X.row(c.particles[0]), X.row(c.particles[1]), X.row(c.particles[2]),
                               X.row(c.particles[3])) * factor(0.3);
    c.compliance = rng.uniform(0.001, 0.01);
    c.damping = damping();
    m.constraints.push_back(c);
  }
  for (int k = 0; k < 4; ++k) {  // bending
    Constraint c;
    c.kind = ConstraintKind::Bending;
    c.particles = random_tet(rng, X);
    c.rest = o.at_rest ? dihedral_angle(X.row(c.particles[0]), X.row(c.particles[1]),
                                        X.row(c.particles[2]), X.row(c.particles[3]))
                       : rng.uniform(0.3, 2.8);
    c.compliance = rng.uniform(0.05, 0.5);
    c.damping = damping();
    m.constraints.push_back(c);
  }
  {  // a rigid distance constraint: listed, not in U
    Constraint c;
    c.kind = ConstraintKind::Distance;
    c.particles[0] = 4;
    c.particles[1] = 5;
    c.rest = (X.row(4) - X.row(5)).norm();
    c.compliance = 0.0;
    m.constraints.push_back(c);
  }
  // FEM elements of both materials (the stable neo-Hookean ones bring their FEM-kind constraints,
  // which U must skip).
  fem::add_fem_elements(m, {random_tet(rng, X), random_tet(rng, X)}, Material::StableNeoHookean, 20.0, 0.3);
  fem::add_fem_elements(m, {random_tet(rng, X), random_tet(rng, X)}, Material::Corotated, 15.0, 0.4);
  if (o.damping)
    for (Constraint& c : m.constraints)
      if (is_fem_kind(c.kind)) c.damping = damping();
  return m;
}

// A random dof vector near the rest positions of the dynamic particles.
inline Eigen::VectorXd random_q(Random& rng, const EnergyModel& energy, const Model& model,
                                double spread = 0.25) {
  Eigen::VectorXd q = energy.gather(model.rest_positions);
  for (Eigen::Index i = 0; i < q.size(); ++i) q(i) += rng.uniform(-spread, spread);
  return q;
}

inline Eigen::MatrixXd dense(const SparsityPattern& p, const std::vector<double>& values) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(p.n, p.n);
  for (int c = 0; c < p.n; ++c)
    for (std::int64_t k = p.column_start[static_cast<size_t>(c)]; k < p.column_start[static_cast<size_t>(c) + 1]; ++k)
      d(p.row[static_cast<size_t>(k)], c) += values[static_cast<size_t>(k)];
  return d;
}

// Central differences of a scalar (vector) function of q: gradient (Jacobian, column j = d/dq_j).
inline Eigen::VectorXd fd_gradient(const std::function<double(const Eigen::VectorXd&)>& f,
                                   const Eigen::VectorXd& q, double h = kDofStep) {
  Eigen::VectorXd g(q.size());
  Eigen::VectorXd y = q;
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    y(i) = q(i) + h;
    const double fp = f(y);
    y(i) = q(i) - h;
    const double fm = f(y);
    y(i) = q(i);
    g(i) = (fp - fm) / (2.0 * h);
  }
  return g;
}

inline Eigen::MatrixXd fd_jacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                   const Eigen::VectorXd& q, double h = kDofStep) {
  Eigen::MatrixXd J(f(q).size(), q.size());
  Eigen::VectorXd y = q;
  for (Eigen::Index j = 0; j < q.size(); ++j) {
    y(j) = q(j) + h;
    const Eigen::VectorXd fp = f(y);
    y(j) = q(j) - h;
    const Eigen::VectorXd fm = f(y);
    y(j) = q(j);
    J.col(j) = (fp - fm) / (2.0 * h);
  }
  return J;
}

// Compares analytic against finite differences entry by entry, |a - b| <= abs * max|a| +
// rel |b|; returns "" or the worst entry. `worst_ratio` (if given) gets the largest
// |a - b| / (abs * max|a| + rel |b|) seen.
inline std::string compare(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, Tolerance tol,
                           double* worst_ratio = nullptr) {
  const double scale = std::max(a.cwiseAbs().maxCoeff(), 1e-300);
  double w = 0.0;
  Eigen::Index wr = 0, wc = 0;
  for (Eigen::Index c = 0; c < a.cols(); ++c)
    for (Eigen::Index r = 0; r < a.rows(); ++r) {
      const double ratio = std::abs(a(r, c) - b(r, c)) / (tol.abs * scale + tol.rel * std::abs(b(r, c)));
      if (!(ratio <= w)) {
        w = ratio;
        wr = r;
        wc = c;
      }
    }
  if (worst_ratio && !(w <= *worst_ratio)) *worst_ratio = w;
  if (w <= 1.0) return "";
  std::ostringstream s;
  s.precision(17);
  s << "entry (" << wr << ", " << wc << "): analytic " << a(wr, wc) << ", finite differences "
    << b(wr, wc) << " (largest analytic entry " << scale << ")";
  return s.str();
}

inline std::string str(const Eigen::VectorXd& q) {
  std::ostringstream s;
  s.precision(17);
  s << "q = [" << q.transpose() << "]";
  return s.str();
}

}  // namespace pbdbench::test
