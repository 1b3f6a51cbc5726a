// Tests of metrics/: energies, momenta, constraint error normalisation (per kind and per group),
// volume drift of tets and of a closed surface, penetration, and the explosion indicators, each
// against values computed by hand for small configurations.
#include "metrics/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>

namespace pbdbench {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Sums of a handful of products of numbers of order 1-10: a few ulps of the result.
constexpr double kRel = 1e-13;

::testing::AssertionResult Near(double actual, double expected, double rel = kRel) {
  if (std::abs(actual - expected) <= rel * std::max(1.0, std::abs(expected)))
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "actual " << actual << ", expected " << expected;
}

Model particles(const std::vector<Vec3>& x, const std::vector<double>& inv_mass) {
  Model m;
  m.rest_positions.resize(static_cast<Eigen::Index>(x.size()), 3);
  for (size_t i = 0; i < x.size(); ++i) m.rest_positions.row(static_cast<Eigen::Index>(i)) = x[i];
  m.inv_mass = inv_mass;
  m.radius.assign(x.size(), 0.0);
  return m;
}

State state_of(const Model& m, const std::vector<Vec3>& v) {
  State s = rest_state(m);
  for (size_t i = 0; i < v.size(); ++i) s.v.row(static_cast<Eigen::Index>(i)) = v[i];
  return s;
}

// ---------------------------------------------------------------------------------------------
// Energy and momentum.

// Two dynamic particles (m = 2 kg and 0.5 kg) and one pinned particle that moves (it is excluded
// from energy and momentum, not from max_speed).
struct ThreeParticles {
  Model m = particles({{1, 2, 0}, {0, -1, 3}, {5, 5, 5}}, {0.5, 2.0, 0.0});
  State s = state_of(m, {{3, 0, 0}, {0, 0, -4}, {10, 0, 0}});
};

TEST(metrics, KineticAndPotentialEnergy) {
  ThreeParticles t;
  const MetricsBaseline b = measure_baseline(t.m, t.s);
  const Sample s = measure(t.m, t.s, b);
  // KE = 1/2 2 9 + 1/2 0.5 16 = 9 + 4 = 13 J.
  EXPECT_TRUE(Near(s.kinetic_energy, 13.0));
  // PE = -sum m g . x = m 9.81 y: 2 * 9.81 * 2 + 0.5 * 9.81 * (-1) = 39.24 - 4.905 = 34.335 J.
  EXPECT_TRUE(Near(s.potential_energy, 34.335));
  EXPECT_EQ(s.elastic_energy, 0.0);  // no constraints
  EXPECT_TRUE(Near(s.total_energy, 13.0 + 34.335));
}

TEST(metrics, LinearAndAngularMomentum) {
  ThreeParticles t;
  const Sample s = measure(t.m, t.s, measure_baseline(t.m, t.s));
  // p = 2 (3,0,0) + 0.5 (0,0,-4) = (6, 0, -2).
  EXPECT_TRUE(Near(s.linear_momentum.x(), 6.0));
  EXPECT_TRUE(Near(s.linear_momentum.y(), 0.0));
  EXPECT_TRUE(Near(s.linear_momentum.z(), -2.0));
  // L = 2 (1,2,0) x (3,0,0) + 0.5 (0,-1,3) x (0,0,-4)
  //   = 2 (0, 0, -6) + 0.5 (4, 0, 0) = (2, 0, -12).
  EXPECT_TRUE(Near(s.angular_momentum.x(), 2.0));
  EXPECT_TRUE(Near(s.angular_momentum.y(), 0.0));
  EXPECT_TRUE(Near(s.angular_momentum.z(), -12.0));
}

TEST(metrics, ElasticEnergyOfCompliantConstraintsOnly) {
  Model m = particles({{0, 0, 0}, {2.5, 0, 0}, {0, 3, 0}}, {1, 1, 1});
  m.gravity = Vec3::Zero();
  const std::uint16_t g = m.group_index("stretch");
  Constraint soft;  // C = 2.5 - 2 = 0.5, alpha = 0.01: C^2 / (2 alpha) = 12.5 J
  soft.particles = {0, 1, -1, -1};
  soft.rest = 2.0;
  soft.compliance = 0.01;
  soft.group = g;
  Constraint rigid;  // alpha = 0: no elastic energy however stretched (C = 3 - 1 = 2)
  rigid.particles = {0, 2, -1, -1};
  rigid.rest = 1.0;
  rigid.group = g;
  m.constraints = {soft, rigid};
  const State s = rest_state(m);
  const Sample out = measure(m, s, measure_baseline(m, s));
  EXPECT_TRUE(Near(out.elastic_energy, 12.5));
  EXPECT_TRUE(Near(out.total_energy, 12.5));
  EXPECT_EQ(out.kinetic_energy, 0.0);
  EXPECT_EQ(out.potential_energy, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Constraint error.

TEST(metrics, ConstraintErrorNormalisedPerKindAndGroup) {
  // Particles: a 2.5 m segment (0-1), a tet (0, 2, 3, 4) and a hinge (0, 2 | 3, 5).
  Model m = particles({{0, 0, 0}, {2.5, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, -1}},
                      {1, 1, 1, 1, 1, 1});
  const std::uint16_t stretch = m.group_index("stretch");
  const std::uint16_t volume = m.group_index("volume");
  const std::uint16_t bending = m.group_index("bending");
  Constraint d;  // |2.5 - 2| / 2 = 0.25
  d.particles = {0, 1, -1, -1};
  d.rest = 2.0;
  d.group = stretch;
  Constraint d0;  // rest 0: absolute, |1 - 0| = 1 m
  d0.particles = {0, 2, -1, -1};
  d0.rest = 0.0;
  d0.group = stretch;
  Constraint v;  // the unit tet has volume 1/6; rest 1/5: |1/6 - 1/5| / (1/5) = 1/6
  v.kind = ConstraintKind::Volume;
  v.particles = {0, 2, 3, 4};
  v.rest = 0.2;
  v.group = volume;
  Constraint h;  // hinge on edge 0-2 (x axis); wings (0,1,0) and (0,0,-1): 90 degrees apart.
  h.kind = ConstraintKind::Bending;  // rest pi: |pi/2 - pi| = pi/2 rad, not divided by rest
  h.particles = {0, 2, 3, 5};
  h.rest = std::numbers::pi;
  h.group = bending;
  m.constraints = {d, d0, v, h};
  const State s = rest_state(m);
  const Sample out = measure(m, s, measure_baseline(m, s));

  const double ed = 0.25, ed0 = 1.0, ev = 1.0 / 6.0, eh = std::numbers::pi / 2;
  EXPECT_TRUE(Near(out.constraint_error_max, eh));
  EXPECT_TRUE(Near(out.constraint_error_rms,
                   std::sqrt((ed * ed + ed0 * ed0 + ev * ev + eh * eh) / 4.0)));
  ASSERT_EQ(out.groups.size(), 3u);
  EXPECT_EQ(out.groups[stretch].count, 2);
  EXPECT_TRUE(Near(out.groups[stretch].max, 1.0));
  EXPECT_TRUE(Near(out.groups[stretch].rms, std::sqrt((ed * ed + ed0 * ed0) / 2.0)));
  EXPECT_EQ(out.groups[volume].count, 1);
  EXPECT_TRUE(Near(out.groups[volume].max, ev));
  EXPECT_TRUE(Near(out.groups[volume].rms, ev));
  EXPECT_EQ(out.groups[bending].count, 1);
  EXPECT_TRUE(Near(out.groups[bending].max, eh));
  EXPECT_TRUE(Near(out.groups[bending].rms, eh));
}

TEST(metrics, ConstraintErrorIsScaleFreeForDistance) {
  // The same 10 % stretch at two scales gives the same normalised error.
  for (double scale : {1e-3, 1.0, 1e3}) {
    Model m = particles({{0, 0, 0}, {1.1 * scale, 0, 0}}, {1, 1});
    Constraint c;
    c.particles = {0, 1, -1, -1};
    c.rest = scale;
    c.group = m.group_index("stretch");
    m.constraints = {c};
    const State s = rest_state(m);
    EXPECT_TRUE(Near(measure(m, s, measure_baseline(m, s)).constraint_error_max, 0.1, 1e-12))
        << "scale " << scale;
  }
}

TEST(metrics, NoConstraintsGiveZeroError) {
  const Model m = particles({{0, 0, 0}}, {1});
  const State s = rest_state(m);
  const Sample out = measure(m, s, measure_baseline(m, s));
  EXPECT_EQ(out.constraint_error_max, 0.0);
  EXPECT_EQ(out.constraint_error_rms, 0.0);
  EXPECT_TRUE(out.groups.empty());
}

TEST(metrics, NaNPositionsGiveNaNErrorOverallAndPerGroup) {
  Model m = particles({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {1, 1, 1});
  const std::uint16_t g = m.group_index("stretch");
  Constraint a, b;
  a.particles = {0, 1, -1, -1};
  a.rest = 1.0;
  a.group = g;
  b.particles = {1, 2, -1, -1};
  b.rest = 0.5;  // error 1: larger than a's, so a NaN must not be hidden behind it
  b.group = g;
  m.constraints = {a, b};
  State s = rest_state(m);
  const MetricsBaseline base = measure_baseline(m, s);
  s.x(0, 0) = kNaN;
  const Sample out = measure(m, s, base);
  EXPECT_TRUE(std::isnan(out.constraint_error_max));
  EXPECT_TRUE(std::isnan(out.constraint_error_rms));
  ASSERT_EQ(out.groups.size(), 1u);
  EXPECT_TRUE(std::isnan(out.groups[0].max)) << "a group's max hides a NaN error";
  EXPECT_TRUE(std::isnan(out.groups[0].rms));
  EXPECT_FALSE(out.finite);
}

// ---------------------------------------------------------------------------------------------
// Volume.

Model unit_tet() {
  Model m = particles({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {1, 1, 1, 1});
  m.tets = {{0, 1, 2, 3}};
  return m;
}

TEST(metrics, VolumeDriftOfAScaledTet) {
  const Model m = unit_tet();
  const State s0 = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s0);
  EXPECT_TRUE(Near(b.tet_volume, 1.0 / 6.0));
  State s = s0;
  s.x *= 1.1;  // volume times 1.331
  const Sample out = measure(m, s, b);
  EXPECT_TRUE(Near(out.tet_volume, 1.331 / 6.0, 1e-12));
  EXPECT_TRUE(Near(out.volume_drift, 0.331, 1e-12));
  EXPECT_TRUE(Near(measure(m, s0, b).volume_drift, 0.0));
  // Not a closed surface: NaN surface volume.
  EXPECT_TRUE(std::isnan(out.surface_volume));
  EXPECT_TRUE(std::isnan(out.surface_volume_drift));
}

TEST(metrics, NaNVolumeDriftWithoutTets) {
  Model m = particles({{0, 0, 0}, {1, 0, 0}}, {1, 1});
  const State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  EXPECT_TRUE(std::isnan(b.tet_volume));
  const Sample out = measure(m, s, b);
  EXPECT_TRUE(std::isnan(out.tet_volume));
  EXPECT_TRUE(std::isnan(out.volume_drift));
}

// The unit cube [0,1]^3 as 12 outward-facing triangles.
Model unit_cube_surface() {
  Model m = particles({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                       {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}},
                      std::vector<double>(8, 1.0));
  m.triangles = {
      {0, 2, 1}, {0, 3, 2},  // z = 0, normal -z
      {4, 5, 6}, {4, 6, 7},  // z = 1, +z
      {0, 1, 5}, {0, 5, 4},  // y = 0, -y
      {3, 7, 6}, {3, 6, 2},  // y = 1, +y
      {0, 4, 7}, {0, 7, 3},  // x = 0, -x
      {1, 2, 6}, {1, 6, 5},  // x = 1, +x
  };
  m.surface_closed = true;
  return m;
}

TEST(metrics, VolumeDriftOfAClosedSurface) {
  const Model m = unit_cube_surface();
  // Every triangle faces outward: (b - a) x (c - a) points away from the cube's centre.
  for (const auto& t : m.triangles) {
    const Vec3 a = m.rest_positions.row(t[0]), b = m.rest_positions.row(t[1]),
               c = m.rest_positions.row(t[2]);
    EXPECT_GT((b - a).cross(c - a).dot((a + b + c) / 3.0 - Vec3(0.5, 0.5, 0.5)), 0.0);
  }
  const State s0 = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s0);
  EXPECT_TRUE(Near(b.surface_volume, 1.0));
  State s = s0;
  s.x *= 2.0;
  s.x.rowwise() += Eigen::RowVector3d(5, -3, 7);  // translation does not change the volume
  const Sample out = measure(m, s, b);
  EXPECT_TRUE(Near(out.surface_volume, 8.0, 1e-12));
  EXPECT_TRUE(Near(out.surface_volume_drift, 7.0, 1e-12));
  // No tets: NaN tet volume.
  EXPECT_TRUE(std::isnan(out.tet_volume));
  EXPECT_TRUE(std::isnan(out.volume_drift));
}

// ---------------------------------------------------------------------------------------------
// Penetration.

TEST(metrics, PenetrationAgainstAPlane) {
  Model m = particles({{0, 0.05, 0}, {1, -0.2, 0}, {2, 1.0, 0}, {3, -5.0, 0}},
                      {1, 1, 1, 0});  // particle 3 is pinned: never in contact
  m.radius = {0.1, 0.1, 0.1, 0.1};
  PlaneCollider floor;
  floor.normal = Vec3(0, 2, 0);  // not unit: the metric uses n / |n| and offset / |n|
  floor.offset = 0.0;
  m.planes = {floor};
  const State s = rest_state(m);
  const Sample out = measure(m, s, measure_baseline(m, s));
  // Particle 0: C = 0.05 - 0.1 = -0.05; particle 1: C = -0.2 - 0.1 = -0.3; particle 2: clear.
  EXPECT_EQ(out.penetration_count, 2);
  EXPECT_TRUE(Near(out.penetration_max, 0.3, 1e-12));
}

TEST(metrics, PenetrationAgainstASphere) {
  Model m = particles({{0.9, 0, 0}, {0, 2, 0}}, {1, 1});
  m.radius = {0.0, 0.0};
  SphereCollider ball;
  ball.center = Vec3::Zero();
  ball.radius = 1.0;
  ball.side = SphereSide::Outside;
  m.spheres = {ball};
  const State s = rest_state(m);
  const Sample out = measure(m, s, measure_baseline(m, s));
  EXPECT_EQ(out.penetration_count, 1);  // |x| - R = 0.9 - 1 = -0.1
  EXPECT_TRUE(Near(out.penetration_max, 0.1, 1e-12));
}

TEST(metrics, NoPenetrationWithoutContacts) {
  const Model m = unit_tet();
  const State s = rest_state(m);
  const Sample out = measure(m, s, measure_baseline(m, s));
  EXPECT_EQ(out.penetration_count, 0);
  EXPECT_EQ(out.penetration_max, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Explosion indicators.

TEST(metrics, SpeedAndExtent) {
  ThreeParticles t;
  const Sample s = measure(t.m, t.s, measure_baseline(t.m, t.s));
  EXPECT_TRUE(Near(s.max_speed, 10.0));  // the pinned particle's 10 m/s counts here
  // Centroid (2, 2, 8/3); the farthest particle is (5,5,5): sqrt(9 + 9 + 49/9).
  EXPECT_TRUE(Near(s.extent, std::sqrt(18.0 + 49.0 / 9.0)));
  EXPECT_TRUE(s.finite);
}

TEST(metrics, ExplosionReasons) {
  ThreeParticles t;
  const MetricsBaseline b = measure_baseline(t.m, t.s);
  ExplosionLimits limits;
  limits.max_speed = 100.0;
  limits.max_extent_ratio = 3.0;  // 3 x the initial 4.84 m
  limits.max_distance = 50.0;
  EXPECT_EQ(explosion_reason(t.m, t.s, measure(t.m, t.s, b), limits, b), "");

  State fast = t.s;
  fast.v(1, 1) = 200.0;
  std::string why = explosion_reason(t.m, fast, measure(t.m, fast, b), limits, b);
  EXPECT_NE(why.find("max speed"), std::string::npos) << why;
  EXPECT_NE(why.find("limits.max_speed"), std::string::npos) << why;

  State wide = t.s;
  wide.x.row(0) = Eigen::RowVector3d(40, 0, 0);  // inside max_distance, beyond 10x the extent
  why = explosion_reason(t.m, wide, measure(t.m, wide, b), limits, b);
  EXPECT_NE(why.find("limits.max_extent_ratio"), std::string::npos) << why;

  ExplosionLimits loose = limits;
  loose.max_extent_ratio = 1e6;
  State far = t.s;
  far.x.rowwise() += Eigen::RowVector3d(100, 0, 0);  // moved as a whole: extent unchanged
  why = explosion_reason(t.m, far, measure(t.m, far, b), loose, b);
  EXPECT_NE(why.find("limits.max_distance"), std::string::npos) << why;
  EXPECT_NE(why.find("particle 0"), std::string::npos) << why;
}

TEST(metrics, ExplosionReasonForNaN) {
  ThreeParticles t;
  const MetricsBaseline b = measure_baseline(t.m, t.s);
  State bad = t.s;
  bad.x(1, 2) = kNaN;
  Sample out = measure(t.m, bad, b);
  EXPECT_FALSE(out.finite);
  EXPECT_TRUE(std::isnan(out.max_speed));
  EXPECT_TRUE(std::isnan(out.extent));
  EXPECT_TRUE(std::isnan(out.penetration_max));
  EXPECT_EQ(explosion_reason(t.m, bad, out, ExplosionLimits{}, b),
            "non-finite position of particle 1");

  State vel = t.s;
  vel.v(2, 0) = std::numeric_limits<double>::infinity();
  out = measure(t.m, vel, b);
  EXPECT_FALSE(out.finite);
  EXPECT_TRUE(std::isnan(out.max_speed));
  EXPECT_EQ(explosion_reason(t.m, vel, out, ExplosionLimits{}, b),
            "non-finite velocity of particle 2");
}

}  // namespace
}  // namespace pbdbench
