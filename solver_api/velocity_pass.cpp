#include "solver_api/velocity_pass.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "solver_api/substep_driver.hpp"

namespace pbdbench {

void velocity_pass(const Model& model, const std::vector<Contact>& contacts,
                   const std::vector<double>& lambda, const Points& x, const Points& v_before,
                   Points& v, double t_end, double h, Precision precision) {
  const bool single = precision == Precision::Float;
  const double rest_speed = 2.0 * model.gravity.norm() * h;
  for (size_t j = 0; j < contacts.size(); ++j) {
    const Contact& c = contacts[j];
    const ConstraintEval e = eval_contact(model, c, x, t_end);
    if (!e.valid) continue;
    if (!(e.C <= kTouchingTolerance || lambda[j] > 0.0)) continue;
    // The contact's particles and their weights along n: s_i = grad_i . n (1 for a, -1 for a
    // pair's b, -u, -v, -w for a triangle's vertices); the relative velocity is sum s_i v_i
    // minus a collider's surface velocity, and W = sum w_i s_i^2 its inverse mass along n
    // (edge-edge: 1 - s, s, t - 1, -t).
    std::array<int, 4> ps{};
    const int count = contact_particles(model, c, ps);
    // n: grad[0], a unit vector, for all kinds but edge-edge, whose first edge's two gradients
    // (1 - s) n and s n sum to it.
    const bool edge = c.kind == ContactKind::Edge;
    const Vec3 n = edge ? Vec3(e.grad[0] + e.grad[1]) : e.grad[0];
    std::array<double, 4> s{}, w{};
    double W = 0.0;
    for (int i = 0; i < count; ++i) {
      // Exactly 1 and -1 for a and a pair's b (n . n is 1 only to round-off).
      s[static_cast<size_t>(i)] = i == 0 && !edge ? 1.0
                                  : c.kind == ContactKind::Particle
                                      ? -1.0
                                      : e.grad[static_cast<size_t>(i)].dot(n);
      w[static_cast<size_t>(i)] = model.inv_mass[static_cast<size_t>(ps[static_cast<size_t>(i)])];
      W += w[static_cast<size_t>(i)] * s[static_cast<size_t>(i)] * s[static_cast<size_t>(i)];
    }
    if (!(W > 0.0)) continue;
    Vec3 v_rel = -contact_surface_velocity(model, c, v, t_end);
    Vec3 v_rel_before = -contact_surface_velocity(model, c, v_before, t_end);
    if (c.kind == ContactKind::Particle) {  // contact_surface_velocity is v_b
      v_rel = Vec3(v.row(c.a)) - Vec3(v.row(c.b));
      v_rel_before = Vec3(v_before.row(c.a)) - Vec3(v_before.row(c.b));
    } else {
      for (int i = 0; i < count; ++i) {
        v_rel += s[static_cast<size_t>(i)] * Vec3(v.row(ps[static_cast<size_t>(i)]));
        v_rel_before += s[static_cast<size_t>(i)] * Vec3(v_before.row(ps[static_cast<size_t>(i)]));
      }
    }
    const double vn = n.dot(v_rel);
    const double vn_before = n.dot(v_rel_before);
    const Vec3 vt = v_rel - vn * n;
    Vec3 dv = Vec3::Zero();
    // Friction: the tangential relative velocity shrinks by at most mu times the normal
    // velocity change this contact applied during the substep.
    const double mu = contact_friction(model, c);
    const double vt_len = vt.norm();
    if (mu > 0.0 && vt_len > 0.0) {
      const double dvn = W * std::max(lambda[j], 0.0) / h;
      dv -= (std::min(mu * dvn, vt_len) / vt_len) * vt;
    }
    // Restitution: the normal relative velocity becomes max(-e v~_n, 0); e = 0 for a slow
    // approach, which stops resting contacts from jittering.
    const double e_eff = std::abs(vn_before) <= rest_speed ? 0.0 : contact_restitution(model, c);
    dv += (-vn + std::max(-e_eff * vn_before, 0.0)) * n;
    for (int i = 0; i < count; ++i) {
      const double f = w[static_cast<size_t>(i)] * s[static_cast<size_t>(i)] / W;
      v.row(ps[static_cast<size_t>(i)]) += (f * dv).transpose();
      if (single) round_row_to_float(v, ps[static_cast<size_t>(i)]);
    }
  }
}

std::vector<std::vector<int>> dynamic_bodies(const Model& model) {
  const int n = model.particle_count();
  std::vector<int> parent(static_cast<size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int p) {
    while (parent[static_cast<size_t>(p)] != p) {
      parent[static_cast<size_t>(p)] = parent[static_cast<size_t>(parent[static_cast<size_t>(p)])];
      p = parent[static_cast<size_t>(p)];
    }
    return p;
  };
  for (const Constraint& c : model.constraints) {
    int first = -1;
    for (int i = 0; i < arity(c.kind); ++i) {
      const int p = c.particles[static_cast<size_t>(i)];
      if (!(model.inv_mass[static_cast<size_t>(p)] > 0.0)) continue;
      if (first < 0) {
        first = p;
        continue;
      }
      const int ra = find(first), rb = find(p);
      if (ra != rb) parent[static_cast<size_t>(std::max(ra, rb))] = std::min(ra, rb);
    }
  }
  std::vector<int> body_of(static_cast<size_t>(n), -1);
  std::vector<std::vector<int>> bodies;
  for (int p = 0; p < n; ++p) {  // ascending p: bodies ordered by their smallest particle
    if (!(model.inv_mass[static_cast<size_t>(p)] > 0.0)) continue;
    const int r = find(p);
    if (body_of[static_cast<size_t>(r)] < 0) {
      body_of[static_cast<size_t>(r)] = static_cast<int>(bodies.size());
      bodies.emplace_back();
    }
    bodies[static_cast<size_t>(body_of[static_cast<size_t>(r)])].push_back(p);
  }
  return bodies;
}

void damp_velocities(const std::vector<std::vector<int>>& bodies,
                     const std::vector<double>& inv_mass, const Points& x, Points& v, double k) {
  if (k == 0.0) return;
  for (const std::vector<int>& body : bodies) {
    double M = 0.0;
    Vec3 x_cm = Vec3::Zero(), v_cm = Vec3::Zero();
    for (int p : body) {
      const double m = 1.0 / inv_mass[static_cast<size_t>(p)];
      M += m;
      x_cm += m * Vec3(x.row(p));
      v_cm += m * Vec3(v.row(p));
    }
    x_cm /= M;
    v_cm /= M;
    Vec3 L = Vec3::Zero();
    Mat3 I = Mat3::Zero();
    for (int p : body) {
      const double m = 1.0 / inv_mass[static_cast<size_t>(p)];
      const Vec3 r = Vec3(x.row(p)) - x_cm;
      L += r.cross(m * Vec3(v.row(p)));
      // [r]^T [r] = |r|^2 Id - r r^T, with [r] the cross-product matrix of r.
      I += m * (r.squaredNorm() * Mat3::Identity() - r * r.transpose());
    }
    // omega = I^-1 L through the eigen-decomposition, dropping (near-)zero eigenvalues: the
    // inertia of a single particle is zero, that of a straight chain is singular along it.
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(I);
    const double largest = eig.eigenvalues().cwiseAbs().maxCoeff();
    Vec3 omega = Vec3::Zero();
    for (int i = 0; i < 3; ++i) {
      const double ev = eig.eigenvalues()(i);
      if (largest > 0.0 && ev > 1e-12 * largest) {
        const Vec3 u = eig.eigenvectors().col(i);
        omega += (u.dot(L) / ev) * u;
      }
    }
    for (int p : body) {
      const Vec3 r = Vec3(x.row(p)) - x_cm;
      const Vec3 dv = v_cm + omega.cross(r) - Vec3(v.row(p));
      v.row(p) += (k * dv).transpose();
    }
  }
}

}  // namespace pbdbench
