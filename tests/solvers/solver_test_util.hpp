// Helpers shared by the solver tests: tiny models built by hand (no config module, no
// generators), seeded random numbers with our own uniform mapping, named tolerances, and
// momentum sums.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench::test {

// ---------------------------------------------------------------------------------------------
// Tolerances (each test states which it uses and why).

// Quantities computed two ways in double from data of order 1, over at most a few thousand
// operations: a few hundred to a few thousand ulps.
inline constexpr double kRoundoff = 1e-12;
// The same in float (the seed listing): eps_float = 6e-8, a few hundred ulps.
inline constexpr double kFloatRoundoff = 5e-5;

// ---------------------------------------------------------------------------------------------
// Seeded random numbers with a portable mapping.
class Random {
 public:
  explicit Random(std::uint64_t seed) : rng_(seed) {}
  double uniform() { return static_cast<double>(rng_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  int integer(int lo, int hi) { return lo + static_cast<int>(uniform() * (hi - lo + 1)); }
  Vec3 vec(double lo, double hi) { return Vec3(uniform(lo, hi), uniform(lo, hi), uniform(lo, hi)); }

 private:
  std::mt19937_64 rng_;
};

// ---------------------------------------------------------------------------------------------
// Tiny models.

// A model with no gravity and no colliders.
inline Model empty_model(const Vec3& gravity = Vec3::Zero()) {
  Model m;
  m.name = "test";
  m.rest_positions.resize(0, 3);
  m.gravity = gravity;
  return m;
}

// Appends a particle (mass 0 = pinned with a static attachment). Returns its index.
inline int add_particle(Model& m, const Vec3& x, double mass, double radius = 0.01) {
  const int i = m.particle_count();
  m.rest_positions.conservativeResize(i + 1, 3);
  m.rest_positions.row(i) = x.transpose();
  m.inv_mass.push_back(mass > 0.0 ? 1.0 / mass : 0.0);
  m.radius.push_back(radius);
  if (mass <= 0.0) m.attachments.push_back({i, x, -1});
  return i;
}

inline Constraint& add_distance(Model& m, int a, int b, double rest, double stiffness = 1.0,
                                double compliance = 0.0, double damping = 0.0) {
  Constraint c;
  c.kind = ConstraintKind::Distance;
  c.particles = {a, b, -1, -1};
  c.rest = rest;
  c.stiffness = stiffness;
  c.compliance = compliance;
  c.damping = damping;
  m.constraints.push_back(c);
  return m.constraints.back();
}

// A distance constraint at its rest length in the model's rest configuration.
inline Constraint& add_rest_distance(Model& m, int a, int b, double stiffness = 1.0,
                                     double compliance = 0.0) {
  const double rest = (m.rest_positions.row(a) - m.rest_positions.row(b)).norm();
  return add_distance(m, a, b, rest, stiffness, compliance);
}

inline Constraint& add_volume(Model& m, int a, int b, int c, int d, double rest,
                              double stiffness = 1.0, double compliance = 0.0) {
  Constraint k;
  k.kind = ConstraintKind::Volume;
  k.particles = {a, b, c, d};
  k.rest = rest;
  k.stiffness = stiffness;
  k.compliance = compliance;
  m.constraints.push_back(k);
  return m.constraints.back();
}

inline Constraint& add_bending(Model& m, int a, int b, int c, int d, double rest,
                               double stiffness = 1.0, double compliance = 0.0) {
  Constraint k;
  k.kind = ConstraintKind::Bending;
  k.particles = {a, b, c, d};
  k.rest = rest;
  k.stiffness = stiffness;
  k.compliance = compliance;
  m.constraints.push_back(k);
  return m.constraints.back();
}

// A chain of `links` links of length `link` hanging from a pinned particle at `top` along -y
// (or along `dir`), particles of mass `mass`.
inline Model chain_model(int links, double link, double mass, const Vec3& gravity,
                         double stiffness = 1.0, double compliance = 0.0,
                         const Vec3& top = Vec3::Zero(), const Vec3& dir = Vec3(0, -1, 0)) {
  Model m = empty_model(gravity);
  add_particle(m, top, 0.0);
  for (int i = 1; i <= links; ++i) {
    add_particle(m, top + i * link * dir, mass);
    add_distance(m, i - 1, i, link, stiffness, compliance);
  }
  return m;
}

// pbd with solver.pbd.material = "stiffness": the hand-built models here state pbd's k (their
// `stiffness` arguments); the rule that derives k from the compliance, pbd's default, has its
// own tests (test_pbd_material.cpp) and variants in test_compiled_projection.cpp.
inline SolverOptions options_for(const std::string& name, int iterations = 10, int substeps = 1) {
  SolverOptions o;
  o.name = name;
  o.pbd_material = PbdMaterial::Stiffness;
  o.iterations = iterations;
  o.substeps = substeps;
  return o;
}

// Internal constraints on random particles with random masses, no pins, no gravity, no
// colliders: distance, volume and bending constraints whose rest values differ from the current
// configuration, so that every projection moves something. `kinds` selects which kinds appear.
struct InternalModelSpec {
  bool distance = true, volume = true, bending = true;
  int particles = 10;
};
inline Model random_internal_model(Random& rng, const InternalModelSpec& spec = {}) {
  Model m = empty_model();
  for (int i = 0; i < spec.particles; ++i)
    add_particle(m, rng.vec(-1.0, 1.0), rng.uniform(0.5, 3.0));
  auto pick4 = [&](std::array<int, 4>& q) {
    for (;;) {
      for (int& v : q) v = rng.integer(0, spec.particles - 1);
      if (q[0] != q[1] && q[0] != q[2] && q[0] != q[3] && q[1] != q[2] && q[1] != q[3] &&
          q[2] != q[3])
        return;
    }
  };
  const Points& x = m.rest_positions;
  if (spec.distance)
    for (int k = 0; k < 8; ++k) {
      int a = rng.integer(0, spec.particles - 1), b = rng.integer(0, spec.particles - 1);
      if (a == b) b = (a + 1) % spec.particles;
      add_distance(m, a, b, (x.row(a) - x.row(b)).norm() * rng.uniform(0.8, 1.2),
                   rng.uniform(0.3, 1.0), rng.uniform(0.0, 1e-3), rng.uniform(0.0, 0.1));
    }
  if (spec.volume)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 4> q;
      pick4(q);
      const double v = (x.row(q[1]) - x.row(q[0]))
                           .dot((x.row(q[2]) - x.row(q[0])).cross(x.row(q[3]) - x.row(q[0]))) /
                       6.0;
      Constraint& c = add_volume(m, q[0], q[1], q[2], q[3], v * rng.uniform(0.7, 1.3),
                                 rng.uniform(0.3, 1.0), rng.uniform(0.0, 1e-3));
      c.damping = rng.uniform(0.0, 0.1);
    }
  if (spec.bending)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 4> q;
      pick4(q);
      Constraint& c = add_bending(m, q[0], q[1], q[2], q[3], rng.uniform(0.5, 2.5),
                                  rng.uniform(0.3, 1.0), rng.uniform(0.0, 1e-3));
      c.damping = rng.uniform(0.0, 0.1);
    }
  return m;
}

inline State random_velocities(const Model& m, Random& rng) {
  State s = rest_state(m);
  for (int i = 0; i < m.particle_count(); ++i) s.v.row(i) = rng.vec(-1.0, 1.0).transpose();
  return s;
}

// sum_i m_i |v_i|: the scale against which a momentum difference is round-off.
inline double momentum_scale(const Model& m, const State& s) {
  double sum = 0.0;
  for (int i = 0; i < m.particle_count(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      sum += s.v.row(i).norm() / m.inv_mass[static_cast<size_t>(i)];
  return sum;
}

// ---------------------------------------------------------------------------------------------
// Momentum of the dynamic particles.
inline Vec3 linear_momentum(const Model& m, const State& s) {
  Vec3 p = Vec3::Zero();
  for (int i = 0; i < m.particle_count(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      p += Vec3(s.v.row(i)) / m.inv_mass[static_cast<size_t>(i)];
  return p;
}

inline Vec3 angular_momentum(const Model& m, const State& s) {
  Vec3 l = Vec3::Zero();
  for (int i = 0; i < m.particle_count(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      l += Vec3(s.x.row(i)).cross(Vec3(s.v.row(i))) / m.inv_mass[static_cast<size_t>(i)];
  return l;
}

// One step of `o` on a random internal model (no pins, gravity or contacts) from random
// velocities: the change of linear and angular momentum, relative to sum m |v|.
struct MomentumChange {
  double linear = 0.0;
  double angular = 0.0;
};
inline MomentumChange step_momentum_change(const SolverOptions& o, std::uint64_t seed,
                                           double dt = 0.01) {
  Random rng(seed);
  const Model m = random_internal_model(rng);
  State s = random_velocities(m, rng);
  const Vec3 p0 = linear_momentum(m, s), l0 = angular_momentum(m, s);
  const double scale = momentum_scale(m, s);
  make_solver(o, m)->step(m, s, dt);
  return {(linear_momentum(m, s) - p0).norm() / scale,
          (angular_momentum(m, s) - l0).norm() / scale};
}

inline double max_abs_diff(const Points& a, const Points& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

// A scene that exercises every write of the substep: distance, bending and volume constraints
// (stiffness < 1, compliance and damping > 0), a plane with friction and restitution, a sphere
// that oscillates, a kinematic particle on a circle, and particle-particle contacts.
inline Model mixed_scene() {
  Model m = empty_model(Vec3(0.0, -9.81, 0.0));
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      test::add_particle(m, Vec3(0.1 * i, 0.3 + 0.02 * i, 0.1 * j), 0.5 + 0.1 * ((i + j) % 3), 0.02);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      const int k = 4 * j + i;
      if (i + 1 < 4) add_rest_distance(m, k, k + 1, 0.9, 1e-4).damping = 0.05;
      if (j + 1 < 4) add_rest_distance(m, k, k + 4, 0.9, 1e-4);
      if (i + 1 < 4 && j + 1 < 4) add_rest_distance(m, k, k + 5, 0.5, 1e-3);
    }
  add_bending(m, 5, 6, 1, 10, 0.1, 0.3, 1e-3).damping = 0.02;
  const int t = test::add_particle(m, Vec3(0.5, 0.1, 0.5), 0.2);
  test::add_particle(m, Vec3(0.6, 0.1, 0.5), 0.2);
  test::add_particle(m, Vec3(0.5, 0.2, 0.5), 0.2);
  test::add_particle(m, Vec3(0.5, 0.1, 0.6), 0.2);
  add_volume(m, t, t + 1, t + 2, t + 3, 0.9 * 0.1 * 0.1 * 0.1 / 6.0, 0.8, 1e-6);
  // A kinematic particle on a circle, tied to the cloth's corner.
  const int kin = test::add_particle(m, Vec3(-0.1, 0.3, 0.0), 0.0);
  Motion circle;
  circle.kind = MotionKind::Circle;
  circle.radius = 0.05;
  circle.frequency = 1.5;
  m.motions.push_back(circle);
  m.attachments.back().motion = 0;
  add_rest_distance(m, kin, 0, 1.0, 0.0);
  m.planes.push_back({Vec3::UnitY(), 0.0, 0.3, 0.2});
  Motion bob;
  bob.kind = MotionKind::Oscillate;
  bob.amplitude = Vec3(0.0, 0.05, 0.02);
  bob.frequency = 2.0;
  m.motions.push_back(bob);
  m.spheres.push_back({Vec3(0.15, 0.2, 0.15), 0.1, SphereSide::Outside, 0.2, 0.3, 1});
  m.particle_contact = true;
  m.particle_restitution = 0.1;
  m.particle_friction = 0.2;
  return m;
}

inline const std::vector<ProjectionOrder>& all_orders() {
  static const std::vector<ProjectionOrder> orders = {
      ProjectionOrder::Sequential, ProjectionOrder::Reversed,
      ProjectionOrder::Shuffled,   ProjectionOrder::Colored,
      ProjectionOrder::Jacobi,     ProjectionOrder::GroupedShuffled,
      ProjectionOrder::BottomUp};
  return orders;
}

}  // namespace pbdbench::test
