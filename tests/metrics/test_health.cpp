// Tests of metrics/health.hpp: each warning is raised by a state that has the failure and not by
// one just inside the threshold.
#include "metrics/health.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace pbdbench {
namespace {

Model one_particle(double radius) {
  Model m;
  m.rest_positions = Points(1, 3);
  m.rest_positions.row(0) = Vec3(0, 1, 0);
  m.inv_mass = {1.0};
  m.radius = {radius};
  m.gravity = Vec3(0, -10, 0);
  return m;
}

std::vector<std::string> codes(const HealthMonitor& h) {
  std::vector<std::string> out;
  for (const RunWarning& w : h.warnings()) out.push_back(w.code);
  return out;
}

TEST(Health, EnergyGainedWithoutSourceIsWarnedAboveTheThreshold) {
  const Model m = one_particle(0.0);
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  // Energy scale: m g H = 1 * 10 * 1e-3 (one particle: extent 0, H = 1 mm) = 0.01 J.
  HealthMonitor h(m, s, s0, 10, false);
  s.v.row(0) = Vec3(0.1, 0, 0);  // +0.005 J: above 0.1 x 0.01 J
  s.time = 0.1;
  h.observe(1, s, measure(m, s, b));
  ASSERT_EQ(codes(h), std::vector<std::string>{"energy_gain"});
  EXPECT_EQ(h.warnings()[0].step, 1);
  // The same gain in a scene with an energy source is not warned.
  HealthMonitor sourced(m, rest_state(m), s0, 10, true);
  sourced.observe(1, s, measure(m, s, b));
  EXPECT_TRUE(sourced.warnings().empty());
  // A gain below the threshold: 0.5 * 0.04^2 = 8e-4 J < 1e-3 J.
  HealthMonitor small(m, rest_state(m), s0, 10, false);
  s.v.row(0) = Vec3(0.04, 0, 0);
  small.observe(1, s, measure(m, s, b));
  EXPECT_TRUE(small.warnings().empty());
}

// Steps whose solve stopped short of what the solver claims (an untrusted stop reason) are one
// warning, solver_stop: the first such step, and the count per reason of the steps observed.
TEST(Health, UntrustedSolverStopsAreCountedInOneWarning) {
  const Model m = one_particle(0.0);
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  HealthMonitor h(m, s, s0, 10, true);
  for (long k = 1; k <= 5; ++k) {
    s.time = 0.1 * static_cast<double>(k);
    h.observe(k, s, measure(m, s, b));
    if (k >= 3) h.observe_untrusted_stop(k, s.time, k == 5 ? "line_search_failed" : "iteration_limit");
  }
  ASSERT_EQ(codes(h), std::vector<std::string>{"solver_stop"});
  const RunWarning w = h.warnings()[0];
  EXPECT_EQ(w.step, 3);
  EXPECT_DOUBLE_EQ(w.time, 0.3);
  EXPECT_EQ(w.message, "the solver's step stopped short of what it claims in 3 of 5 steps: 2 "
                       "iteration_limit, 1 line_search_failed");
  HealthMonitor clean(m, rest_state(m), s0, 10, true);
  clean.observe(1, s, measure(m, s, b));
  EXPECT_TRUE(clean.warnings().empty());
}

// The watched quantity is the motion energy (kinetic + gravitational) against the initial total:
// elastic energy that grows without motion (an unconverged stiff constraint) is not a gain, a
// stretched spring may turn its elastic energy into motion, and motion beyond it is warned.
TEST(Health, EnergyGainIsMotionBeyondTheInitialTotalEnergy) {
  Model m;
  m.rest_positions = Points(2, 3);
  m.rest_positions << 0, 0, 0, 2.5, 0, 0;
  m.inv_mass = {1.0, 1.0};
  m.radius = {0.0, 0.0};
  m.gravity = Vec3::Zero();
  const std::uint16_t g = m.group_index("stretch");
  Constraint spring;  // C = 2.5 - 2 = 0.5, alpha = 0.01: E_el(0) = 12.5 J
  spring.particles = {0, 1, -1, -1};
  spring.rest = 2.0;
  spring.compliance = 0.01;
  spring.group = g;
  m.constraints = {spring};
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  ASSERT_DOUBLE_EQ(s0.total_energy, 12.5);
  // The warnings after one step to the second particle at x1, the two moving apart at speed u each.
  const auto after_one_step = [&](double x1, double u) {
    HealthMonitor h(m, s, s0, 10, false);
    State t = s;
    t.x.row(1) = Vec3(x1, 0, 0);
    t.v.row(0) = Vec3(u, 0, 0);
    t.v.row(1) = Vec3(-u, 0, 0);
    h.observe(1, t, measure(m, t, b));
    return codes(h);
  };
  // Stretched further at rest: E_el = 2^2 / 0.02 = 200 J, no motion: not a gain.
  EXPECT_TRUE(after_one_step(4.0, 0.0).empty());
  // Released: at rest length each particle moves at 2.5 m/s, K = 2 x 0.5 x 2.5^2 = 6.25 J <= 12.5 J.
  EXPECT_TRUE(after_one_step(2.0, 2.5).empty());
  // Moving at 4 m/s each: K = 16 J > 12.5 J + 0.1 x the scale (12.5 J): 1.25 J.
  EXPECT_EQ(after_one_step(2.0, 4.0), std::vector<std::string>{"energy_gain"});
}

TEST(Health, VolumeLostBeyondTheThresholdIsWarned) {
  Model m;
  m.rest_positions = Points(4, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.inv_mass = {1, 1, 1, 1};
  m.radius = {0, 0, 0, 0};
  m.gravity = Vec3::Zero();
  m.tets = {{0, 1, 2, 3}};
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  HealthMonitor h(m, s, measure(m, s, b), 10, false);
  s.x(3, 2) = 0.95;  // -5 %: inside
  h.observe(1, s, measure(m, s, b));
  EXPECT_TRUE(h.warnings().empty());
  s.x(3, 2) = 0.7;  // -30 %
  h.observe(2, s, measure(m, s, b));
  ASSERT_EQ(codes(h), std::vector<std::string>{"volume"});
  EXPECT_EQ(h.warnings()[0].step, 2);
  EXPECT_NE(h.warnings()[0].message.find("lost 30 %"), std::string::npos) << h.warnings()[0].message;
}

TEST(Health, ErrorGrowingInEveryQuarterIsWarnedAndABoundedOneIsNot) {
  Model m = one_particle(0.0);
  m.gravity = Vec3::Zero();
  const State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  HealthMonitor growing(m, s, s0, 8, false), bounded(m, s, s0, 8, false);
  for (long k = 1; k <= 8; ++k) {
    Sample g = s0, f = s0;
    g.constraint_error_rms = 1e-3 * std::pow(2.0, static_cast<double>(k));  // 2e-3 .. 0.256: last quarter 0.19
    f.constraint_error_rms = k <= 2 ? 1e-3 * static_cast<double>(k) : 0.5;  // jumps, then flat
    growing.observe(k, s, g);
    bounded.observe(k, s, f);
  }
  EXPECT_EQ(codes(growing), std::vector<std::string>{"error_growth"});
  EXPECT_TRUE(bounded.warnings().empty());
}

TEST(Health, TunnellingThroughAPlaneAndThroughASphere) {
  Model m = one_particle(0.01);
  m.gravity = Vec3::Zero();
  m.planes.push_back(PlaneCollider{});  // y >= 0
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  HealthThresholds wide;
  wide.region_factor = 1e6;  // the particle is moved 1 m in no time: not what is tested here
  HealthMonitor h(m, s, measure(m, s, b), 10, false, 0.0, wide);
  s.x.row(0) = Vec3(0, -0.005, 0);  // overlapping by less than its radius: a contact, not a tunnel
  h.observe(1, s, measure(m, s, b));
  EXPECT_TRUE(h.warnings().empty());
  s.x.row(0) = Vec3(0, -0.5, 0);
  h.observe(2, s, measure(m, s, b));
  ASSERT_EQ(codes(h), std::vector<std::string>{"tunnelling"});
  EXPECT_EQ(h.warnings()[0].step, 2);

  // Through a sphere of radius 0.1 at the origin in one step, from x = -1 to x = +1.
  Model ms = one_particle(0.01);
  ms.gravity = Vec3::Zero();
  ms.spheres.push_back(SphereCollider{Vec3::Zero(), 0.1, SphereSide::Outside});
  Points a(1, 3), c(1, 3), d(1, 3);
  a << -1, 0, 0;
  c << 1, 0, 0;
  d << 1, 0.5, 0;
  EXPECT_EQ(tunnelled_particles(ms, a, c, 0.0).count, 1);
  EXPECT_EQ(tunnelled_particles(ms, a, d, 0.0).count, 0) << "a path that passes by the sphere";
}

}  // namespace
}  // namespace pbdbench

namespace pbdbench {
namespace {

// Two balls overlapping without gravity or motion (seed article 5.4's staging): the energy scale
// was a degenerate 1e-12 J, so any push-out warned. With the step, the initial overlap d0 is an
// energy source of at most 1/2 m (d0 / dt)^2 (metrics/health.hpp): the push-out is not warned,
// motion beyond it is.
TEST(Health, ThePushOutOfAnInitialOverlapIsNotAnEnergyGain) {
  Model m;
  m.rest_positions = Points(2, 3);
  m.rest_positions << 0, 0, 0, 0.08, 0, 0;  // radius 0.05: 0.02 m of overlap
  m.inv_mass = {10.0, 10.0};                 // 0.1 kg each
  m.radius = {0.05, 0.05};
  m.gravity = Vec3::Zero();
  m.particle_contact = true;
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  ASSERT_NEAR(s0.penetration_max, 0.02, 1e-12);
  const double dt = 1.0 / 60.0;
  // One step that pushes the pair apart: each ball moves 0.01 m, at 0.01 / dt = 0.6 m/s,
  // 0.036 J in all; the bound is 1/2 (0.2 kg) (0.02 / dt)^2 = 0.144 J.
  State pushed = s;
  pushed.x(0, 0) = -0.01;
  pushed.x(1, 0) = 0.09;
  pushed.v(0, 0) = -0.01 / dt;
  pushed.v(1, 0) = 0.01 / dt;
  pushed.time = dt;
  HealthMonitor without_dt(m, s, s0, 10, false);
  without_dt.observe(1, pushed, measure(m, pushed, b));
  // The 1e-12 J floor; and without the push-out nothing explains a speed in a scene at rest
  // without gravity.
  EXPECT_EQ(codes(without_dt), (std::vector<std::string>{"too_fast", "energy_gain"}));
  HealthMonitor with_dt(m, s, s0, 10, false, dt);
  with_dt.observe(1, pushed, measure(m, pushed, b));
  EXPECT_TRUE(with_dt.warnings().empty());
  // Five times that speed, 0.9 J: beyond the push-out, warned.
  State faster = pushed;
  faster.v *= 5.0;
  HealthMonitor fast(m, s, s0, 10, false, dt);
  fast.observe(1, faster, measure(m, faster, b));
  EXPECT_EQ(codes(fast), std::vector<std::string>{"energy_gain"});
}

}  // namespace
}  // namespace pbdbench

namespace pbdbench {
namespace {

bool warned(const HealthMonitor& h, const std::string& code) {
  for (const RunWarning& w : h.warnings())
    if (w.code == code) return true;
  return false;
}

// Two particles joined by one link of rest length 1 m, without gravity.
Model link_model() {
  Model m;
  m.rest_positions = Points(2, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0;
  m.inv_mass = {1.0, 1.0};
  m.radius = {0.0, 0.0};
  m.gravity = Vec3::Zero();
  Constraint link;
  link.particles = {0, 1, -1, -1};
  link.rest = 1.0;
  link.group = m.group_index("stretch");
  m.constraints = {link};
  return m;
}

// A link over twice its rest length is named, one just under is not, and a scene that starts
// overstretched is named at step 0.
TEST(Health, ALinkBeyondTwiceItsRestLengthIsOverstretched) {
  const Model m = link_model();
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  HealthThresholds wide;
  wide.region_factor = 1e6;
  HealthMonitor h(m, s, measure(m, s, b), 10, true, 0.0, wide);
  s.x(1, 0) = 1.95;
  EXPECT_NEAR(measure(m, s, b).link_stretch_max, 0.95, 1e-12);
  h.observe(1, s, measure(m, s, b));
  EXPECT_FALSE(warned(h, "overstretched"));
  s.x(1, 0) = 2.2;
  h.observe(2, s, measure(m, s, b));
  ASSERT_TRUE(warned(h, "overstretched"));
  EXPECT_EQ(h.warnings()[0].step, 2);
  EXPECT_NE(h.warnings()[0].message.find("2.2 times its rest length"), std::string::npos) << h.warnings()[0].message;

  State start = rest_state(m);
  start.x(1, 0) = 3.0;  // starts at three times its rest length
  HealthMonitor violated(m, start, measure(m, start, b), 10, true, 0.0, wide);
  ASSERT_TRUE(warned(violated, "overstretched"));
  EXPECT_EQ(violated.warnings()[0].step, 0);
  // A link of rest length 0 has no stretch ratio: it is not a link here.
  Model zero = link_model();
  zero.constraints[0].rest = 0.0;
  EXPECT_EQ(measure(zero, start, measure_baseline(zero, start)).link_stretch_max, 0.0);
}

TEST(Health, ATetTurnedInsideOutIsInverted) {
  Model m;
  m.rest_positions = Points(4, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.inv_mass = {1, 1, 1, 1};
  m.radius = {0, 0, 0, 0};
  m.gravity = Vec3::Zero();
  m.tets = {{0, 1, 2, 3}};
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  HealthThresholds wide;
  wide.region_factor = 1e6;
  HealthMonitor h(m, s, measure(m, s, b), 10, true, 0.0, wide);
  s.x(3, 2) = 0.01;  // flattened, still positive
  h.observe(1, s, measure(m, s, b));
  EXPECT_FALSE(warned(h, "inverted"));
  s.x(3, 2) = -0.5;  // through the opposite face
  EXPECT_EQ(measure(m, s, b).tets_inverted, 1);
  h.observe(2, s, measure(m, s, b));
  EXPECT_TRUE(warned(h, "inverted"));
}

// One particle at rest 1 m up, gravity 10 m/s^2: the region is 10 x 1 cm + 2 x g t^2 / 2 and the
// speed the scene explains 10 x (g t + sqrt(2 g H)), H = 1 mm.
TEST(Health, LeavingTheRegionAndOutrunningGravity) {
  const Model m = one_particle(0.0);
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  const auto after = [&](double drop, double speed, bool sources) {
    HealthMonitor h(m, s, s0, 10, sources);
    State t = s;
    t.time = 1.0;
    t.x(0, 1) = 1.0 - drop;
    t.v(0, 1) = -speed;
    h.observe(1, t, measure(m, t, b));
    return h;
  };
  // A free fall of 1 s: 5 m at 10 m/s. Within the region (0.1 + 10 m) and the speed (10 x 10.14).
  EXPECT_FALSE(warned(after(5.0, 10.0, false), "left_region"));
  EXPECT_FALSE(warned(after(5.0, 10.0, false), "too_fast"));
  // 10.2 m away: beyond the region; 102 m/s: beyond the speed.
  EXPECT_TRUE(warned(after(10.2, 10.0, false), "left_region"));
  EXPECT_TRUE(warned(after(5.0, 102.0, false), "too_fast"));
  // Where a kinematic particle or collider moves, both are off.
  EXPECT_FALSE(warned(after(10.2, 102.0, true), "left_region"));
  EXPECT_FALSE(warned(after(10.2, 102.0, true), "too_fast"));
}

// The whole energy is watched where the elastic energy means something: a spring stretched at
// rest holds more elastic energy than the scene had, which the motion energy does not show.
TEST(Health, TheWholeEnergyCountsTheElasticEnergyWhereItMeansSomething) {
  Model m = link_model();
  m.constraints[0].compliance = 0.01;
  State s = rest_state(m);
  s.x(1, 0) = 1.5;  // E_el(0) = 0.5^2 / 0.02 = 12.5 J
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  State t = s;
  t.x(1, 0) = 3.0;  // 2^2 / 0.02 = 200 J, at rest
  const Sample st = measure(m, t, b);
  HealthMonitor whole(m, s, s0, HealthRun{10, false, 0.01, true});
  HealthMonitor motion(m, s, s0, HealthRun{10, false, 0.01, false});
  whole.observe(1, t, st);
  motion.observe(1, t, st);
  EXPECT_TRUE(whole.whole_energy());
  EXPECT_TRUE(warned(whole, "energy_gain"));
  EXPECT_FALSE(warned(motion, "energy_gain"));
}

// A particle of radius 1 cm on the ground y = 0, 8 steps: a penetration of 2 mm through the last
// quarter (steps 7 and 8) is named, one in an earlier step only is not.
TEST(Health, PenetrationThatStaysThroughTheLastQuarter) {
  Model m = one_particle(0.01);
  m.gravity = Vec3::Zero();
  m.planes.push_back(PlaneCollider{});
  State s = rest_state(m);
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  const auto run = [&](double depth_late, double depth_early) {
    HealthMonitor h(m, s, s0, 8, true);
    for (long k = 1; k <= 8; ++k) {
      State t = s;
      t.time = 0.01 * static_cast<double>(k);
      t.x(0, 1) = 0.01 - (k >= 7 ? depth_late : k == 3 ? depth_early : 0.0);
      h.observe(k, t, measure(m, t, b));
    }
    return h;
  };
  EXPECT_TRUE(warned(run(0.002, 0.0), "penetration"));
  EXPECT_FALSE(warned(run(0.0005, 0.0), "penetration"));  // under 0.1 x the radius
  EXPECT_FALSE(warned(run(0.0, 0.005), "penetration"));   // an impact's transient
}

// Jitter through the last quarter above g dt, in a scene with gravity and a collider.
TEST(Health, ASceneThatShouldRestButKeepsTremblingIsNotSettling) {
  Model m = one_particle(0.01);
  m.planes.push_back(PlaneCollider{});
  State s = rest_state(m);
  s.x(0, 1) = 0.01;
  const MetricsBaseline b = measure_baseline(m, s);
  const Sample s0 = measure(m, s, b);
  const double dt = 0.01;  // g dt = 0.1 m/s
  const auto run = [&](double jitter) {
    HealthMonitor h(m, s, s0, 8, false, dt);
    for (long k = 1; k <= 8; ++k) {
      State t = s;
      t.time = dt * static_cast<double>(k);
      Sample sk = measure(m, t, b);
      sk.velocity_hf_rms = jitter;
      h.observe(k, t, sk);
    }
    return h;
  };
  EXPECT_TRUE(warned(run(0.2), "not_settling"));
  EXPECT_FALSE(warned(run(0.05), "not_settling"));
}

}  // namespace
}  // namespace pbdbench
