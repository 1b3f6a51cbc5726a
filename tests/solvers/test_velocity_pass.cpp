// Tests of solver_api/velocity_pass.hpp: friction, restitution and velocity damping, alone and
// through the pbd and xpbd solvers.
#include <gtest/gtest.h>

#include <cmath>

#include "catalog/solver_catalog.hpp"
#include "solver_test_util.hpp"
#include "solver_api/velocity_pass.hpp"

namespace pbdbench::test {
namespace {

constexpr double kG = 9.81;

// A particle of radius r above a floor plane y = 0.
Model floor_model(double restitution, double friction, double radius = 0.05) {
  Model m = empty_model(Vec3(0, -kG, 0));
  add_particle(m, Vec3(0, 1.0, 0), 1.0, radius);
  m.planes.push_back({Vec3::UnitY(), 0.0, restitution, friction});
  return m;
}

TEST(VelocityPass, DroppedParticleRestsOnThePlane) {
  for (const std::string name : {"pbd", "xpbd"}) {
    const Model m = floor_model(0.0, 0.5);
    auto sv = make_solver(options_for(name, 5, 4), m);
    State s = rest_state(m);
    s.x(0, 1) = 0.5;
    for (int i = 0; i < 120; ++i) sv->step(m, s, 1.0 / 60.0);
    // Each substep projects the contact exactly to C = 0 (k = 1 on one linear constraint) and
    // restitution (e = 0) zeroes the normal velocity: at rest to round-off.
    EXPECT_NEAR(s.x(0, 1), 0.05, 1e-12) << name;
    EXPECT_NEAR(s.v.row(0).norm(), 0.0, 1e-12) << name;
  }
}

// The apex heights (of the particle's bottom) after successive bounces.
std::vector<double> bounce_apexes(const std::string& name, double e, double h0, double dt,
                                  int count) {
  const double r = 0.05;
  const Model m = floor_model(e, 0.0, r);
  auto sv = make_solver(options_for(name, 4, 1), m);
  State s = rest_state(m);
  s.x(0, 1) = h0 + r;
  std::vector<double> apexes;
  double prev_v = 0.0, max_y = 0.0;
  for (int i = 0; i < 200000 && static_cast<int>(apexes.size()) < count; ++i) {
    sv->step(m, s, dt);
    const double v = s.v(0, 1);
    if (prev_v < 0.0 && v > 0.0) max_y = 0.0;  // a bounce
    max_y = std::max(max_y, s.x(0, 1) - r);
    if (prev_v > 0.0 && v <= 0.0) apexes.push_back(max_y);  // the top of the flight
    prev_v = v;
  }
  return apexes;
}

TEST(VelocityPass, RestitutionGivesApexRatioESquared) {
  // references.md, closed form 10: apex h_n = e^(2n) h0. The discrete bounce is exact up to
  // where the impact falls inside a step: the particle stops on the surface after penetrating
  // up to v h (4.4 mm for v = 4.4 m/s, h = 1 ms), and the velocity it reverses includes up to
  // one step of gravity, g h. Both shift an apex by O(v h) = O(h / sqrt(h0/g)) relative:
  // 4.4e-3 / 1 m here, 9e-3 after the second bounce (the apex is e^2 lower, v e lower).
  // A 2 % tolerance on the ratio covers that with room; 10x smaller steps must shrink the
  // error, which a wrong formula would not.
  for (const std::string name : {"pbd", "xpbd"}) {
    for (double e : {0.5, 0.8}) {
      const double h0 = 1.0;
      const std::vector<double> coarse = bounce_apexes(name, e, h0, 1e-3, 2);
      ASSERT_EQ(coarse.size(), 2u);
      const double r1 = coarse[0] / h0, r2 = coarse[1] / coarse[0];
      EXPECT_NEAR(r1, e * e, 0.02 * e * e) << name << " e " << e;
      EXPECT_NEAR(r2, e * e, 0.02 * e * e) << name << " e " << e;
      const std::vector<double> fine = bounce_apexes(name, e, h0, 1e-4, 1);
      EXPECT_LT(std::abs(fine[0] / h0 - e * e), std::abs(r1 - e * e) + 1e-4) << name;
      EXPECT_NEAR(fine[0] / h0, e * e, 0.002 * e * e) << name;
    }
  }
}

TEST(VelocityPass, FrictionStopsASlidingParticleInTimeV0OverMuG) {
  // A particle resting on the floor, sliding at v0: dry friction decelerates it at mu g,
  // so it stops at t = v0 / (mu g) after sliding v0^2 / (2 mu g). In the solver each substep
  // removes exactly mu g h of speed (the contact's normal velocity change is g h), so the stop
  // time is exact to one substep; the distance is the discrete sum, within v0 h of the formula.
  for (const std::string name : {"pbd", "xpbd"}) {
    const double mu = 0.4, v0 = 2.0, dt = 1e-3, r = 0.05;
    const Model m = floor_model(0.0, mu, r);
    auto sv = make_solver(options_for(name, 4, 1), m);
    State s = rest_state(m);
    s.x(0, 1) = r;
    s.v(0, 0) = v0;
    double t_stop = -1.0;
    for (int i = 1; i <= 1000 && t_stop < 0.0; ++i) {
      sv->step(m, s, dt);
      if (s.v(0, 0) <= 0.0) t_stop = i * dt;
    }
    const double expected = v0 / (mu * kG);
    EXPECT_NEAR(t_stop, expected, 1.0 * dt + 1e-12) << name;
    EXPECT_NEAR(s.x(0, 0), v0 * v0 / (2 * mu * kG), v0 * dt) << name;
    EXPECT_EQ(s.v(0, 0), 0.0) << name;  // friction does not reverse the motion
    EXPECT_NEAR(s.x(0, 1), r, 1e-12) << name;
  }
}

TEST(VelocityPass, FrictionlessParticleKeepsSliding) {
  const Model m = floor_model(0.0, 0.0);
  auto sv = make_solver(options_for("xpbd", 4, 1), m);
  State s = rest_state(m);
  s.x(0, 1) = 0.05;
  s.v(0, 0) = 2.0;
  for (int i = 0; i < 100; ++i) sv->step(m, s, 1e-3);
  EXPECT_NEAR(s.v(0, 0), 2.0, 1e-12);
}

TEST(VelocityPass, ParticlePairSplitsByInverseMassAndConservesMomentum) {
  // Two touching particles approaching head-on, masses 1 and 3, e = 1: the relative normal
  // velocity reverses and the total momentum is unchanged.
  Model m = empty_model(Vec3::Zero());
  add_particle(m, Vec3(0, 0, 0), 1.0, 0.1);
  add_particle(m, Vec3(0.2, 0, 0), 3.0, 0.1);
  m.particle_contact = true;
  m.particle_restitution = 1.0;
  m.particle_friction = 0.0;
  const Points x = m.rest_positions;
  Points v(2, 3);
  v << 1.5, 0.3, 0.0, -0.5, 0.0, 0.0;
  const Points v_before = v;
  const std::vector<Contact> contacts = {{ContactKind::Particle, 0, 1}};
  const Vec3 p0 = Vec3(v.row(0)) + 3.0 * Vec3(v.row(1));
  velocity_pass(m, contacts, {0.0}, x, v_before, v, 0.0, 0.01);
  const Vec3 p1 = Vec3(v.row(0)) + 3.0 * Vec3(v.row(1));
  EXPECT_NEAR((p1 - p0).norm(), 0.0, kRoundoff);
  EXPECT_NEAR(v(0, 0) - v(1, 0), -(1.5 - (-0.5)), kRoundoff);  // reversed
  EXPECT_NEAR(v(0, 1), 0.3, kRoundoff);                        // tangential untouched (mu = 0)
}

TEST(VelocityPass, SeparatedContactsAreLeftAlone) {
  const Model m = floor_model(0.5, 1.0);
  Points x(1, 3), v(1, 3);
  x << 0.0, 0.2, 0.0;  // 15 cm above the floor
  v << 1.0, -2.0, 0.0;
  const Points before = v;
  velocity_pass(m, {{ContactKind::Plane, 0, 0}}, {0.0}, x, before, v, 0.0, 0.01);
  EXPECT_EQ(max_abs_diff(v, before), 0.0);
}

TEST(VelocityPass, SlowApproachDoesNotBounce) {
  // |v~_n| <= 2 |g| h: e is taken as 0, the particle stays on the surface.
  const Model m = floor_model(0.9, 0.0);
  Points x(1, 3), v(1, 3), v_before(1, 3);
  x << 0.0, 0.05, 0.0;
  v_before << 0.0, -1.5 * kG * 0.01, 0.0;
  v << 0.0, -0.01, 0.0;
  velocity_pass(m, {{ContactKind::Plane, 0, 0}}, {0.001}, x, v_before, v, 0.0, 0.01);
  EXPECT_EQ(v(0, 1), 0.0);
  v_before << 0.0, -3.0 * kG * 0.01, 0.0;  // faster: bounces with e
  v << 0.0, -0.01, 0.0;
  velocity_pass(m, {{ContactKind::Plane, 0, 0}}, {0.001}, x, v_before, v, 0.0, 0.01);
  EXPECT_NEAR(v(0, 1), 0.9 * 3.0 * kG * 0.01, kRoundoff);
}

// A random body: `n` particles with random masses, positions and velocities, all joined.
Model random_body(int n, Random& rng) {
  Model m = empty_model();
  for (int i = 0; i < n; ++i) add_particle(m, rng.vec(-1, 1), rng.uniform(0.5, 3.0));
  for (int i = 1; i < n; ++i) add_rest_distance(m, i - 1, i);
  return m;
}

TEST(VelocityDamping, PreservesRigidMotionAndMomentum) {
  Random rng(21);
  for (int trial = 0; trial < 20; ++trial) {
    const Model m = random_body(7, rng);
    const auto bodies = dynamic_bodies(m);
    ASSERT_EQ(bodies.size(), 1u);
    const Vec3 V = rng.vec(-2, 2), w = rng.vec(-3, 3);
    State s = rest_state(m);
    for (int i = 0; i < 7; ++i) s.v.row(i) = (V + w.cross(Vec3(s.x.row(i)))).transpose();
    const Points rigid = s.v;
    damp_velocities(bodies, m.inv_mass, s.x, s.v, 0.7);
    EXPECT_LT(max_abs_diff(s.v, rigid), 1e-12) << "trial " << trial;
    // A random velocity field: momentum (linear and angular) is unchanged, and k = 1 leaves
    // exactly the rigid part, which a second damping does not change.
    for (int i = 0; i < 7; ++i) s.v.row(i) = rng.vec(-1, 1).transpose();
    const Vec3 P = linear_momentum(m, s), L = angular_momentum(m, s);
    damp_velocities(bodies, m.inv_mass, s.x, s.v, 1.0);
    EXPECT_LT((linear_momentum(m, s) - P).norm(), 1e-12);
    EXPECT_LT((angular_momentum(m, s) - L).norm(), 1e-12);
    const Points once = s.v;
    damp_velocities(bodies, m.inv_mass, s.x, s.v, 0.5);
    EXPECT_LT(max_abs_diff(s.v, once), 1e-12);
  }
}

TEST(VelocityDamping, SingleParticleAndStraightChain) {
  // Singular inertia: a lone particle keeps its velocity; a straight chain spinning about an
  // axis across it keeps its rotation.
  Model m = empty_model();
  add_particle(m, Vec3(1, 2, 3), 2.0);
  State s = rest_state(m);
  s.v.row(0) = Vec3(1, -1, 0.5).transpose();
  damp_velocities(dynamic_bodies(m), m.inv_mass, s.x, s.v, 0.9);
  EXPECT_LT((Vec3(s.v.row(0)) - Vec3(1, -1, 0.5)).norm(), 1e-15);

  Model chain = chain_model(4, 0.1, 1.0, Vec3::Zero(), 1.0, 0.0, Vec3::Zero(), Vec3(1, 0, 0));
  chain.inv_mass[0] = 1.0;  // free the top: a straight 5-particle body
  chain.attachments.clear();
  State c = rest_state(chain);
  for (int i = 0; i < 5; ++i) c.v.row(i) = Vec3(0.0, 0.1 * i - 0.2, 0.3).transpose();
  const Points before = c.v;
  damp_velocities(dynamic_bodies(chain), chain.inv_mass, c.x, c.v, 1.0);
  EXPECT_LT(max_abs_diff(c.v, before), 1e-12);
}

TEST(VelocityDamping, BodiesAreTheConnectedDynamicComponents) {
  Model m = empty_model();
  for (int i = 0; i < 6; ++i) add_particle(m, Vec3(i, 0, 0), i == 2 ? 0.0 : 1.0);
  add_rest_distance(m, 0, 1);
  add_rest_distance(m, 1, 2);  // through the pinned particle 2: no link
  add_rest_distance(m, 2, 3);
  add_rest_distance(m, 4, 5);
  const auto bodies = dynamic_bodies(m);
  ASSERT_EQ(bodies.size(), 3u);
  EXPECT_EQ(bodies[0], (std::vector<int>{0, 1}));
  EXPECT_EQ(bodies[1], (std::vector<int>{3}));
  EXPECT_EQ(bodies[2], (std::vector<int>{4, 5}));
}

TEST(VelocityDamping, PbdDampsRelativeMotionOnly) {
  // Two free particles on a link, spinning and vibrating: damping removes the vibration, the
  // spin and the drift stay.
  Model m = empty_model();
  add_particle(m, Vec3(-0.5, 0, 0), 1.0);
  add_particle(m, Vec3(0.5, 0, 0), 1.0);
  add_distance(m, 0, 1, 1.0, 0.0);  // k = 0: the link does nothing; damping acts alone
  SolverOptions o = options_for("pbd", 1);
  o.pbd_velocity_damping = 0.5;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  s.v << 0.2, 1.0, 0.0, 0.2, -1.0, 0.0;  // drift 0.2 x plus a spin about z
  s.v(0, 0) -= 0.3;                      // plus a stretching vibration
  s.v(1, 0) += 0.3;
  sv->step(m, s, 1e-3);
  EXPECT_NEAR(s.v(1, 0) - s.v(0, 0), 0.3, 1e-9);  // 0.6 relative along the link, halved
  EXPECT_NEAR(linear_momentum(m, s).x(), 0.4, 1e-12);
}

}  // namespace
}  // namespace pbdbench::test
