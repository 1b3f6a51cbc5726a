// Tests of metrics/: energies, momenta, constraint error normalisation (per kind and per group),
// volume drift of tets and of a closed surface, penetration, and the explosion indicators, each
// against values computed by hand for small configurations.
#include "metrics/metrics.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"

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
// Failure detectors: height_min, sunk_particles, velocity_hf_rms.

TEST(metrics, HeightMinIsTheLowestDynamicParticleAlongUp) {
  // Particle 2 is lowest but pinned; particle 3 has a negative inverse mass (a scene defect): it
  // is dynamic (inv_mass != 0) and counts.
  Model m = particles({{0, 0.5, 9}, {1, -0.25, -9}, {2, -7, 0}, {3, 0.1, -1}}, {1, 2, 0, -1});
  State s = rest_state(m);
  EXPECT_EQ(height_min(m, s), -0.25);
  EXPECT_EQ(measure(m, s, measure_baseline(m, s)).height_min, -0.25);
  // Gravity along -z: up is +z, and particle 1 (z = -9) is the lowest.
  m.gravity = Vec3(0, 0, -2);
  EXPECT_EQ(height_min(m, s), -9.0);
  // Without gravity up is +y.
  m.gravity = Vec3::Zero();
  EXPECT_EQ(height_min(m, s), -0.25);
  // No dynamic particle, or a non-finite one: NaN.
  Model pinned = particles({{0, 1, 0}}, {0});
  EXPECT_TRUE(std::isnan(height_min(pinned, rest_state(pinned))));
  s.x(3, 1) = kNaN;
  EXPECT_TRUE(std::isnan(height_min(m, s)));
}

TEST(metrics, SunkDepthBelowAPlaneIsTheCentresDepth) {
  // Particle 0 sits d = 0.3 below the plane y = 0, particle 1 overlaps it by its radius only
  // (a penetration, not sunk), particle 2 is pinned below it (not counted).
  const double d = 0.3;
  Model m = particles({{0, -d, 0}, {1, 0.05, 0}, {2, -5, 0}}, {1, 1, 0});
  m.radius = {0.1, 0.1, 0.1};
  PlaneCollider floor;
  floor.normal = Vec3(0, 2, 0);  // not unit: the detector uses n / |n| and offset / |n|
  m.planes = {floor};
  State s = rest_state(m);
  SunkParticles sunk = sunk_particles(m, s);
  EXPECT_EQ(sunk.count, 1);
  EXPECT_TRUE(Near(sunk.depth, d, 1e-15));
  const Sample out = measure(m, s, measure_baseline(m, s));
  EXPECT_EQ(out.sunk_count, 1);
  EXPECT_TRUE(Near(out.sunk_depth, d, 1e-15));
  EXPECT_EQ(out.penetration_count, 2);  // the radius overlaps: particles 0 and 1
  // The plane 2 y + 1 = 0 is y = -0.5: nothing below it.
  m.planes[0].offset = 1.0;
  EXPECT_EQ(sunk_particles(m, s).count, 0);
  EXPECT_EQ(sunk_particles(m, s).depth, 0.0);
  // The plane 2 y - 1 = 0 is y = 0.5: particles 0 and 1 are below it, particle 0 by 0.8.
  m.planes[0].offset = -1.0;
  EXPECT_EQ(sunk_particles(m, s).count, 2);
  EXPECT_TRUE(Near(sunk_particles(m, s).depth, 0.5 + d, 1e-15));
  // A non-finite position: not counted, depth NaN.
  s.x(1, 0) = kNaN;
  EXPECT_EQ(sunk_particles(m, s).count, 1);
  EXPECT_TRUE(std::isnan(sunk_particles(m, s).depth));
}

// measure takes its particle quantities in one pass (and, without colliders, no pass for the
// sunk particles): they agree with the detectors' own functions, and with what a non-finite
// coordinate must do to each, wherever it is (a dynamic or a pinned particle, x or v).
TEST(metrics, MeasuresParticleQuantitiesAgreeWithTheDetectors) {
  const Model m = particles({{0, 0.5, 9}, {1, -0.25, -9}, {2, -7, 0}, {3, 0.1, -1}}, {1, 2, 0, -1});
  struct Case {
    int particle;
    bool velocity;
    bool finite_height;  // height_min stays a number
  };
  for (const Case c : {Case{-1, false, true}, Case{2, false, true}, Case{2, true, true}, Case{1, true, true},
                       Case{1, false, false}, Case{3, false, false}}) {
    State s = rest_state(m);
    s.v = Points::Constant(4, 3, 0.5);
    if (c.particle >= 0) (c.velocity ? s.v : s.x)(c.particle, 1) = kNaN;
    const Sample out = measure(m, s, measure_baseline(m, rest_state(m)));
    const SunkParticles sunk = sunk_particles(m, s);
    SCOPED_TRACE(::testing::Message() << "NaN in particle " << c.particle << (c.velocity ? " v" : " x"));
    EXPECT_EQ(out.finite, c.particle < 0);
    EXPECT_EQ(std::isnan(out.height_min), !c.finite_height);
    if (c.finite_height) {
      EXPECT_EQ(out.height_min, height_min(m, s));
    }
    EXPECT_TRUE(std::isnan(height_min(m, s)) == std::isnan(out.height_min));
    EXPECT_EQ(out.sunk_count, sunk.count);
    EXPECT_EQ(std::isnan(out.sunk_depth), std::isnan(sunk.depth));
    if (!std::isnan(sunk.depth)) {
      EXPECT_EQ(out.sunk_depth, sunk.depth);
    }
    EXPECT_EQ(std::isnan(out.sunk_depth), !c.finite_height);
    if (c.particle < 0) {
      // Dynamic particles 0, 1 and 3 (masses 1, 1/2, -1), |v|^2 = 0.75 each.
      EXPECT_EQ(out.kinetic_energy, 0.5 * 1.0 * 0.75 + 0.5 * 0.5 * 0.75 + 0.5 * -1.0 * 0.75);
      EXPECT_EQ(out.max_speed, std::sqrt(0.75));
    } else {
      EXPECT_TRUE(std::isnan(out.max_speed));
    }
  }
}

TEST(metrics, SunkIntoSpheresOutsideInsideAndBowl) {
  // Spheres of radius 1 about the origin. Particles at distance 0.75 below the centre, 1.5
  // below it, and 1.25 above it.
  Model m = particles({{0, -0.75, 0}, {0, -1.5, 0}, {0, 1.25, 0}}, {1, 1, 1});
  SphereCollider ball;
  ball.radius = 1.0;
  m.spheres = {ball};
  const State s = rest_state(m);
  m.spheres[0].side = SphereSide::Outside;  // particle 0 is inside it, 0.25 deep
  EXPECT_EQ(sunk_particles(m, s).count, 1);
  EXPECT_EQ(sunk_particles(m, s).depth, 0.25);
  m.spheres[0].side = SphereSide::Inside;  // particles 1 and 2 are out, 0.5 and 0.25
  EXPECT_EQ(sunk_particles(m, s).count, 2);
  EXPECT_EQ(sunk_particles(m, s).depth, 0.5);
  m.spheres[0].side = SphereSide::Bowl;  // only below the centre: particle 1
  EXPECT_EQ(sunk_particles(m, s).count, 1);
  EXPECT_EQ(sunk_particles(m, s).depth, 0.5);
  // Two colliders: a particle sunk into both counts once, with its larger depth.
  m.spheres[0].side = SphereSide::Outside;
  PlaneCollider floor;
  floor.offset = 0.5;  // y = -0.5
  m.planes = {floor};
  const SunkParticles both = sunk_particles(m, s);
  EXPECT_EQ(both.count, 2);  // particle 0 (0.25 in the sphere, 0.25 below the plane), particle 1
  EXPECT_EQ(both.depth, 1.0);  // particle 1, 1 below the plane
}

TEST(metrics, VelocityHighFrequencyOfAnAlternatingVelocityIsItsAmplitude) {
  // v alternates +a, -a, +a: the second difference is 4a, and the detector reads |a|.
  const Model m = particles({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {1, 1, 0});
  const Vec3 a(0.5, -1.0, 2.0);  // |a| = sqrt(5.25)
  Points plus(3, 3), minus(3, 3);
  plus << a.transpose(), a.transpose(), 100, 0, 0;   // the pinned particle is left out
  minus << -a.transpose(), -a.transpose(), -100, 0, 0;
  EXPECT_TRUE(Near(velocity_hf_rms(m, plus, minus, plus), std::sqrt(5.25)));
  EXPECT_TRUE(Near(velocity_hf_rms(m, minus, plus, minus), std::sqrt(5.25)));
  // Only particle 0 jitters: the RMS over the two dynamic particles is |a| / sqrt(2).
  Points still = plus;
  still.row(1) = a.transpose();
  Points still_minus = minus;
  still_minus.row(1) = a.transpose();
  EXPECT_TRUE(Near(velocity_hf_rms(m, plus, still_minus, still), std::sqrt(5.25 / 2.0)));
}

TEST(metrics, VelocityHighFrequencyOfAConstantAccelerationIsZero) {
  // v_n = v_0 + n g h with values exact in binary: the second difference is exactly 0.
  const Model m = particles({{0, 0, 0}, {1, 0, 0}}, {1, 0.5});
  Points v0(2, 3), v1(2, 3), v2(2, 3);
  v0 << 1.0, -0.5, 0.0, 3.0, 0.0, 0.0;
  v1 << 1.0, -0.75, 0.0, 3.0, 0.0, 0.25;
  v2 << 1.0, -1.0, 0.0, 3.0, 0.0, 0.5;
  EXPECT_EQ(velocity_hf_rms(m, v2, v1, v0), 0.0);
  // A velocity kink (the particle hits something) is not 0: 0.25 / 4 over sqrt(2) particles.
  v2(0, 1) = -0.75;
  EXPECT_TRUE(Near(velocity_hf_rms(m, v2, v1, v0), 0.25 / 4.0 / std::sqrt(2.0)));
  // measure() cannot know earlier velocities: NaN until the runner fills it in.
  const State s = rest_state(m);
  EXPECT_TRUE(std::isnan(measure(m, s, measure_baseline(m, s)).velocity_hf_rms));
  // Without dynamic particles: NaN.
  const Model pinned = particles({{0, 0, 0}}, {0});
  const Points z = Points::Zero(1, 3);
  EXPECT_TRUE(std::isnan(velocity_hf_rms(pinned, z, z, z)));
}

TEST(metrics, NegativeInverseMassGivesNegativeMassNotACrash) {
  // A particle with inverse mass -1 (a scene defect) has mass -1 kg: its kinetic energy is
  // -1/2 v^2 and its momentum -v. The metrics take it as given.
  const Model m = particles({{0, 1, 0}, {1, 1, 0}}, {-1.0, 1.0});
  const State s = state_of(m, {{2, 0, 0}, {0, 0, 1}});
  const Sample out = measure(m, s, measure_baseline(m, s));
  EXPECT_TRUE(Near(out.kinetic_energy, -2.0 + 0.5));
  EXPECT_TRUE(Near(out.linear_momentum.x(), -2.0));
  EXPECT_TRUE(Near(out.linear_momentum.z(), 1.0));
  EXPECT_TRUE(out.finite);
  EXPECT_EQ(out.height_min, 1.0);
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

// ---------------------------------------------------------------------------------------------
// Observables of the scene: tip displacement, support force, pendulum angle.

TEST(metrics, TipDisplacementIsTheMeanDisplacementOfTheTip) {
  Model m = particles({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 0}}, {0, 1, 1, 1});
  State s = rest_state(m);
  EXPECT_TRUE(tip_displacement(m, s).array().isNaN().all());  // no tip
  EXPECT_TRUE(measure(m, s, measure_baseline(m, s)).tip_displacement.array().isNaN().all());
  m.observables.tip = {2, 3};
  s.x.row(1) += Eigen::RowVector3d(5, 5, 5);  // not a tip particle
  s.x.row(2) += Eigen::RowVector3d(0.1, -0.2, 0.0);
  s.x.row(3) += Eigen::RowVector3d(0.3, 0.0, 0.4);
  const Vec3 d = tip_displacement(m, s);  // ((0.1, -0.2, 0) + (0.3, 0, 0.4)) / 2
  EXPECT_TRUE(Near(d.x(), 0.2));
  EXPECT_TRUE(Near(d.y(), -0.1));
  EXPECT_TRUE(Near(d.z(), 0.2));
  EXPECT_EQ(measure(m, s, measure_baseline(m, s)).tip_displacement, d);
}

// A chain hanging from a pin at the origin: particle 0 pinned, 1 kg at y = -1 and 3 kg at y = -2,
// links of rest 1 m. At rest the top link carries 4 kg, the lower one 3 kg; in State::lambda's
// convention the force of link j on its lower particle, grad C lambda = (0, -1, 0) lambda, is the
// tension upward, so lambda = -tension.
struct HangingChain {
  static constexpr double g = 9.81;
  Model m = particles({{0, 0, 0}, {0, -1, 0}, {0, -2, 0}}, {0.0, 1.0, 1.0 / 3.0});
  State s;
  HangingChain() {
    m.gravity = Vec3(0, -g, 0);
    const std::uint16_t stretch = m.group_index("stretch");
    for (int i = 0; i < 2; ++i) {
      Constraint c;
      c.particles = {i, i + 1, -1, -1};
      c.rest = 1.0;
      c.group = stretch;
      m.constraints.push_back(c);
    }
    s = rest_state(m);
    s.step = 1;  // the multipliers of a step
    s.lambda = {-4.0 * g, -3.0 * g};
  }
};

TEST(metrics, SupportForceOfAHangingChainIsItsWeightUpward) {
  HangingChain c;
  const Vec3 f = support_force(c.m, c.s);
  EXPECT_TRUE(Near(f.x(), 0.0));
  EXPECT_TRUE(Near(f.y(), 4.0 * HangingChain::g));  // the whole weight, upward
  EXPECT_TRUE(Near(f.z(), 0.0));
  EXPECT_EQ(measure(c.m, c.s, measure_baseline(c.m, c.s)).support_force, f);
  // The lower link's multiplier is not involved: NaN there changes nothing.
  c.s.lambda[1] = kNaN;
  EXPECT_EQ(support_force(c.m, c.s), f);
}

TEST(metrics, SupportForceFollowsTheGradients) {
  // A link from a pin at the origin to a particle at (2, 0, 0), rest 1 m, lambda = -5 N: the
  // link pulls the pin towards the particle with grad_0 C lambda = (-1, 0, 0)(-5) = (5, 0, 0);
  // the support holds the body back with (-5, 0, 0).
  Model m = particles({{0, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}, {3, 1, 0}, {3, 0, 1}},
                      {0, 1, 0, 1, 1, 1});
  const std::uint16_t g = m.group_index("stretch");
  Constraint link;
  link.particles = {0, 1, -1, -1};
  link.rest = 1.0;
  link.group = g;
  // A unit tet at (3, 0, 0) with its vertex 0 (particle 2) pinned: grad_0 V = -(1/6) (e1 + e2 +
  // e3), so with lambda = 3 the force on the pin is -(1/2)(1, 1, 1) and the support's
  // (1/2)(1, 1, 1).
  Constraint tet;
  tet.kind = ConstraintKind::Volume;
  tet.particles = {2, 3, 4, 5};
  tet.rest = 1.0 / 6.0;
  tet.group = m.group_index("volume");
  // A link between the two pins: its forces on them cancel.
  Constraint pins;
  pins.particles = {0, 2, -1, -1};
  pins.rest = 2.5;
  pins.group = g;
  m.constraints = {link, tet, pins};
  State s = rest_state(m);
  s.step = 3;
  s.lambda = {-5.0, 3.0, 7.0};
  const Vec3 f = support_force(m, s);
  EXPECT_TRUE(Near(f.x(), -5.0 + 0.5));
  EXPECT_TRUE(Near(f.y(), 0.5));
  EXPECT_TRUE(Near(f.z(), 0.5));
}

// measure() sums the errors, the group sums and the elastic energy in one pass over runs of one
// group, and takes the supports' constraints from the baseline: the same bits as one constraint
// at a time into each group, with the supports found again (a baseline that does not list them).
TEST(metrics, TheTableListedSupportsAndOnePassGiveTheSameBits) {
  Model m = particles({{0, 0, 0}, {2.1, 0.2, 0}, {3, 0, 0}, {4.3, 0, 0.1}, {3, 1.2, 0}, {3, 0, 0.9}},
                      {0, 1, 0, 1, 1, 1});
  const std::uint16_t stretch = m.group_index("stretch"), volume = m.group_index("volume");
  auto link = [&](int a, int b, double rest, double compliance) {
    Constraint c;
    c.particles = {a, b, -1, -1};
    c.rest = rest;
    c.compliance = compliance;
    c.group = stretch;
    return c;
  };
  Constraint tet;
  tet.kind = ConstraintKind::Volume;
  tet.particles = {2, 3, 4, 5};
  tet.rest = 1.0 / 6.0;
  tet.compliance = 1e-3;
  tet.group = volume;
  // The groups interleave (stretch, volume, stretch, stretch): three runs; the last link's
  // rest length is 0 (its error absolute).
  m.constraints = {link(0, 1, 1.0, 0.01), tet, link(0, 2, 2.5, 0.0), link(1, 3, 2.2, 0.3), link(4, 5, 0.0, 0.02)};
  State s = rest_state(m);
  s.x = m.rest_positions * 1.1;
  s.step = 3;
  s.lambda = {-5.0, 3.0, 7.0, 0.5, 1.5};
  const MetricsBaseline listed = measure_baseline(m, rest_state(m));
  ASSERT_TRUE(listed.supports_listed);
  EXPECT_EQ(listed.support_constraints, (std::vector<int>{0, 1, 2}));
  ASSERT_NE(listed.table, nullptr);
  MetricsBaseline unlisted = listed;  // and without the table: measure builds it
  unlisted.support_constraints.clear();
  unlisted.supports_listed = false;
  unlisted.table.reset();
  const Sample a = measure(m, s, listed), b = measure(m, s, unlisted);
  // From the records, as measure documents its sums: a run of one group at a time, its sum of
  // squares in lanes added in a tree (with no run longer than a lane here, the tree adds the
  // run's constraints in order), the runs' sums in model order.
  std::vector<GroupError> groups(m.group_names.size());
  double max = 0.0, sum_sq = 0.0, elastic = 0.0;
  for (size_t j = 0; j < m.constraints.size();) {
    const std::uint16_t group = m.constraints[j].group;
    double run_sq = 0.0;
    for (; j < m.constraints.size() && m.constraints[j].group == group; ++j) {
      const Constraint& c = m.constraints[j];
      const double C = eval_constraint(c, s.x).C, err = normalized_error(c, C);
      GroupError& g = groups[c.group];
      g.max = std::max(g.max, err);
      ++g.count;
      max = std::max(max, err);
      run_sq += err * err;
      if (c.compliance > 0.0) elastic += C * C / (2.0 * c.compliance);
    }
    groups[group].rms += run_sq;
    sum_sq += run_sq;
  }
  for (GroupError& g : groups) g.rms = g.count > 0 ? std::sqrt(g.rms / g.count) : 0.0;
  for (const Sample* x : {&a, &b}) {
    EXPECT_EQ(x->constraint_error_max, max);
    EXPECT_EQ(x->constraint_error_rms, std::sqrt(sum_sq / 5.0));
    EXPECT_EQ(x->elastic_energy, elastic);
    ASSERT_EQ(x->groups.size(), groups.size());
    for (size_t k = 0; k < groups.size(); ++k) {
      EXPECT_EQ(x->groups[k].max, groups[k].max);
      EXPECT_EQ(x->groups[k].rms, groups[k].rms);
      EXPECT_EQ(x->groups[k].count, groups[k].count);
    }
  }
  EXPECT_EQ(a.support_force, b.support_force);
  EXPECT_EQ(a.support_force, support_force(m, s));
  EXPECT_TRUE(a.support_force.allFinite());
}

// Runs longer than measure's 8 lanes, with tails: the sums are the lane sums measure documents
// (lane k of a run takes its constraints begin + k, begin + k + 8, ...; the lanes added in the
// tree ((0+1)+(2+3))+((4+5)+(6+7)); the runs in model order), within round-off of the
// one-at-a-time sums, and a NaN error deep in a run marks its group's and the overall maxima.
TEST(metrics, LongRunsAreSummedInLanesAndANaNInsideOneIsSeen) {
  const int n = 60;
  std::vector<Vec3> x;
  for (int i = 0; i < n; ++i) x.push_back(Vec3(0.1 * i, 0.02 * (i % 7), 0.0));
  Model m = particles(x, std::vector<double>(static_cast<size_t>(n), 1.0));
  const std::uint16_t stretch = m.group_index("stretch"), shear = m.group_index("shear");
  // 21 stretch links, 13 shear links, 19 stretch links: runs of 21, 13 and 19.
  const int lengths[] = {21, 13, 19};
  const std::uint16_t groups_of_runs[] = {stretch, shear, stretch};
  int at = 0;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < lengths[r]; ++k, ++at) {
      Constraint c;
      c.particles = {at % (n - 1), at % (n - 1) + 1, -1, -1};
      c.rest = 0.05 + 0.003 * at;  // every link stretched or compressed by its own amount
      c.compliance = at % 3 == 0 ? 0.0 : 1e-3 * (1 + at % 5);
      c.group = groups_of_runs[r];
      m.constraints.push_back(c);
    }
  State s = rest_state(m);
  const MetricsBaseline base = measure_baseline(m, s);
  const Sample out = measure(m, s, base);

  std::vector<double> err, term;
  for (const Constraint& c : m.constraints) {
    const double C = eval_constraint(c, s.x).C;
    err.push_back(normalized_error(c, C));
    term.push_back(c.compliance > 0.0 ? C * C / (2.0 * c.compliance) : 0.0);
  }
  const auto tree = [](const double* a) { return ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7])); };
  double sum_sq = 0.0, lanes_elastic[8] = {}, seq_sq = 0.0, seq_elastic = 0.0;
  double group_sq[2] = {0.0, 0.0};
  size_t begin = 0;
  for (int r = 0; r < 3; ++r) {
    double sq[8] = {};
    for (size_t j = begin; j < begin + static_cast<size_t>(lengths[r]); ++j) {
      sq[(j - begin) % 8] += err[j] * err[j];
      lanes_elastic[(j - begin) % 8] += term[j];
      seq_sq += err[j] * err[j];
      seq_elastic += term[j];
    }
    const double run = tree(sq);
    sum_sq += run;
    group_sq[groups_of_runs[r] == stretch ? 0 : 1] += run;
    begin += static_cast<size_t>(lengths[r]);
  }
  EXPECT_EQ(out.constraint_error_rms, std::sqrt(sum_sq / 53.0));
  EXPECT_EQ(out.elastic_energy, tree(lanes_elastic));
  EXPECT_EQ(out.groups[stretch].rms, std::sqrt(group_sq[0] / 40.0));
  EXPECT_EQ(out.groups[shear].rms, std::sqrt(group_sq[1] / 13.0));
  EXPECT_EQ(out.groups[stretch].count, 40);
  EXPECT_EQ(out.groups[shear].count, 13);
  EXPECT_TRUE(Near(out.constraint_error_rms, std::sqrt(seq_sq / 53.0), 1e-14));
  EXPECT_TRUE(Near(out.elastic_energy, seq_elastic, 1e-14));
  EXPECT_GT(out.elastic_energy, 0.0);
  EXPECT_EQ(out.constraint_error_max, *std::max_element(err.begin(), err.end()));

  // A NaN position under the 30th link (the shear run's 9th: past its first 8 lanes).
  s.x(m.constraints[29].particles[1], 1) = kNaN;
  const Sample bad = measure(m, s, base);
  EXPECT_TRUE(std::isnan(bad.groups[shear].max));
  EXPECT_TRUE(std::isnan(bad.constraint_error_max));
  EXPECT_TRUE(std::isnan(bad.constraint_error_rms));
}

TEST(metrics, SupportForceIsNaNWithoutMultipliersAndZeroWithoutSupports) {
  HangingChain c;
  auto is_nan = [](const Vec3& v) { return v.array().isNaN().all(); };
  {
    State s = c.s;  // pbd and pbd-seed leave NaN
    s.lambda = {kNaN, kNaN};
    EXPECT_TRUE(is_nan(support_force(c.m, s)));
    EXPECT_TRUE(is_nan(measure(c.m, s, measure_baseline(c.m, s)).support_force));
  }
  {
    State s = c.s;  // the initial state: no step has computed lambda
    s.step = 0;
    EXPECT_TRUE(is_nan(support_force(c.m, s)));
  }
  {
    State s = c.s;
    s.lambda.pop_back();
    EXPECT_TRUE(is_nan(support_force(c.m, s)));
  }
  {
    Model m = c.m;  // an FEM element touching the pin: its forces are not in lambda
    FemElement e;
    e.particles = {0, 1, 2, 1};
    m.elements.push_back(e);
    EXPECT_TRUE(is_nan(support_force(m, c.s)));
    m.elements[0].particles = {1, 2, 1, 2};  // not touching it: fine
    EXPECT_FALSE(is_nan(support_force(m, c.s)));
  }
  {
    Model m = c.m;  // nothing pinned: 0, whatever lambda holds, initial state included
    m.inv_mass[0] = 1.0;
    State s = c.s;
    s.lambda = {kNaN, kNaN};
    s.step = 0;
    EXPECT_EQ(support_force(m, s), Vec3::Zero());
  }
}

TEST(metrics, PendulumAngleFromGravityPositiveTowardsX) {
  Model m = particles({{1, 2, 0}, {1, 1, 0}}, {0, 1});
  m.observables.pivot = Vec3(1, 2, 0);
  State s = rest_state(m);
  EXPECT_TRUE(std::isnan(pendulum_angle(m, s)));  // no bob
  EXPECT_TRUE(std::isnan(measure(m, s, measure_baseline(m, s)).pendulum_angle));
  m.observables.bob = 1;
  const double L = 1.5;
  for (double theta : {0.0, 0.3, -0.7, 2.5, -3.0}) {
    // gravity -y: the plane x-y; an out-of-plane offset in z is ignored.
    s.x.row(1) = Eigen::RowVector3d(1 + L * std::sin(theta), 2 - L * std::cos(theta), 0.25);
    EXPECT_TRUE(Near(pendulum_angle(m, s), theta)) << theta;
    EXPECT_TRUE(Near(measure(m, s, measure_baseline(m, s)).pendulum_angle, theta)) << theta;
    // gravity -z, tilted: the plane of gravity and +x.
    Model mz = m;
    mz.gravity = Vec3(0, 0, -9.81);
    s.x.row(1) = Eigen::RowVector3d(1 + L * std::sin(theta), 2 + 0.4, -L * std::cos(theta));
    EXPECT_TRUE(Near(pendulum_angle(mz, s), theta)) << theta;
  }
  Model none = m;
  none.gravity = Vec3::Zero();
  EXPECT_TRUE(std::isnan(pendulum_angle(none, s)));
  none.gravity = Vec3(-9.81, 0, 0);  // along x: no plane
  EXPECT_TRUE(std::isnan(pendulum_angle(none, s)));
}

// ---------------------------------------------------------------------------------------------
// FEM elements and their constraints (core/fem.hpp).

// The unit right tet on particles 0-3 with a stable neo-Hookean element (E = 1e5 Pa, nu = 0.3:
// two FEM-kind constraints), and a 2.5 m segment 0-4 with a distance constraint of rest 2 m in
// group "stretch" (error 0.25).
Model tet_and_segment() {
  Model m = particles({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {2.5, 0, 0}}, {1, 1, 1, 1, 1});
  m.gravity = Vec3::Zero();
  m.tets = {{0, 1, 2, 3}};
  Constraint d;
  d.particles = {0, 4, -1, -1};
  d.rest = 2.0;
  d.group = m.group_index("stretch");
  m.constraints = {d};
  fem::add_fem_elements(m, m.tets, Material::StableNeoHookean, 1e5, 0.3);
  return m;
}

TEST(metrics, FemKindsCountByTheirDeviationFromTheRestShape) {
  const Model m = tet_and_segment();
  ASSERT_EQ(m.constraint_count(), 3);
  ASSERT_EQ(m.group_names, (std::vector<std::string>{"stretch", "fem_deviatoric", "fem_hydrostatic"}));
  State s = rest_state(m);
  const MetricsBaseline base = measure_baseline(m, s);
  // At rest the FEM constraints read 0 (C_D = sqrt(3), C_H = -mu / lambda_snh are their rest
  // values), so only the segment's 0.25 shows.
  const Sample rest = measure(m, s, base);
  EXPECT_TRUE(Near(rest.constraint_error_max, 0.25));
  EXPECT_TRUE(Near(rest.constraint_error_rms, 0.25 / std::sqrt(3.0)));  // over 3 constraints
  ASSERT_EQ(rest.groups.size(), 3u);
  for (size_t g : {1u, 2u}) {
    EXPECT_EQ(rest.groups[g].count, 1) << m.group_names[g];
    EXPECT_NEAR(rest.groups[g].max, 0.0, 1e-12) << m.group_names[g];
  }
  // The tet squashed to half its height along z (F = diag(1, 1, 0.5)): det F - 1 = -0.5, and
  // sqrt(tr F^T F) = sqrt(2.25) = 1.5 against sqrt(3).
  s.x(3, 2) = 0.5;
  const Sample squashed = measure(m, s, base);
  EXPECT_TRUE(Near(squashed.groups[2].max, 0.5)) << squashed.groups[2].max;
  EXPECT_TRUE(Near(squashed.groups[1].max, (std::sqrt(3.0) - 1.5) / std::sqrt(3.0))) << squashed.groups[1].max;
  EXPECT_TRUE(Near(squashed.constraint_error_max, 0.5));
  // A model of FEM constraints only: a collapsing block never reads 0.
  Model only = tet_and_segment();
  only.constraints.erase(only.constraints.begin());
  const Sample fem_only = measure(only, s, measure_baseline(only, s));
  EXPECT_TRUE(Near(fem_only.constraint_error_max, 0.5));
}

// Psi_snh(s I) - Psi_snh(I) and Psi_corotated(s I), written out: with ls = lambda + mu,
// Psi_snh(F) = mu/2 (|F|^2 - 3) + ls/2 (det F - 1 - mu/ls)^2, Psi_snh(I) = mu^2 / (2 ls);
// Psi_corotated(F) = mu |F - R|^2 + lambda/2 (det F - 1)^2 with R = I for F = s I.
double snh_uniform(double mu, double lambda, double s) {
  const double ls = lambda + mu, t = s * s * s - 1.0 - mu / ls;
  return 0.5 * mu * (3.0 * s * s - 3.0) + 0.5 * ls * t * t - mu * mu / (2.0 * ls);
}
double corotated_uniform(double mu, double lambda, double s) {
  const double j = s * s * s - 1.0;
  return mu * 3.0 * (s - 1.0) * (s - 1.0) + 0.5 * lambda * j * j;
}

TEST(metrics, ElasticEnergyCountsEachElementOnce) {
  Model m = tet_and_segment();
  m.constraints[0].compliance = 0.01;  // the segment: C^2 / (2 alpha) = 0.25 / 0.02 = 12.5 J
  // A second, corotated element on a tet scaled by 2 (particles 5-8, V0 = 8/6 m^3).
  const Eigen::Index first = m.rest_positions.rows();
  m.rest_positions.conservativeResize(first + 4, 3);
  m.rest_positions.bottomRows(4) << 5, 0, 0, 7, 0, 0, 5, 2, 0, 5, 0, 2;
  m.inv_mass.resize(static_cast<size_t>(first + 4), 1.0);
  m.radius.resize(static_cast<size_t>(first + 4), 0.0);
  fem::add_fem_elements(m, {{5, 6, 7, 8}}, Material::Corotated, 1e5, 0.3);
  ASSERT_EQ(m.elements.size(), 2u);
  const double mu = m.elements[0].mu, lambda = m.elements[0].lambda;

  // At rest the elements store no energy; the FEM-kind constraints' C^2/(2 alpha), which is
  // V0 (Psi_snh + 3 mu / 2) (about 1e4 J here), must not be added.
  State s = rest_state(m);
  const Sample rest = measure(m, s, measure_baseline(m, s));
  EXPECT_NEAR(rest.elastic_energy, 12.5, 1e-9 * mu);  // round-off of F = Ds Dm^-1 against I

  // Both tets stretched uniformly by 1.1 about their first vertex.
  for (int i : {1, 2, 3}) s.x.row(i) = 1.1 * m.rest_positions.row(i);
  for (int i : {6, 7, 8}) s.x.row(i) = m.rest_positions.row(5) + 1.1 * (m.rest_positions.row(i) - m.rest_positions.row(5));
  const Sample out = measure(m, s, measure_baseline(m, s));
  const double expected = 12.5 + (1.0 / 6.0) * snh_uniform(mu, lambda, 1.1) + (8.0 / 6.0) * corotated_uniform(mu, lambda, 1.1);
  // The element energies go through Dm^-1, det F and an SVD: a few dozen ulps of the result.
  EXPECT_TRUE(Near(out.elastic_energy, expected, 1e-12)) << out.elastic_energy - expected;
  EXPECT_TRUE(Near(out.total_energy, expected, 1e-12));
}

}  // namespace
}  // namespace pbdbench
