// Tests of core/model and core/state: motions, attachment targets, rest states, groups.
#include "core/model.hpp"

#include <gtest/gtest.h>

#include <numbers>

#include "core/state.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using test::Random;

Vec3 fd_offset(const Motion& m, double t) {
  const double h = test::kFdStep;
  return (motion_offset(m, t + h) - motion_offset(m, t - h)) / (2 * h);
}

Motion random_motion(Random& rng, MotionKind kind) {
  Motion m;
  m.kind = kind;
  m.velocity = rng.vec(-2, 2);
  m.amplitude = rng.vec(-0.5, 0.5);
  m.axis = rng.vec(-1, 1);  // not unit: the motion normalises it
  m.radius = rng.uniform(0.05, 1.0);
  m.frequency = rng.uniform(0.1, 3.0);
  m.start = rng.uniform(0.0, 1.0);
  m.stop = m.start + rng.uniform(0.5, 3.0);
  return m;
}

TEST(Model, MotionVelocityIsTheDerivativeOfTheOffset) {
  Random rng(41);
  for (MotionKind kind : {MotionKind::Static, MotionKind::Linear, MotionKind::Oscillate, MotionKind::Circle}) {
    for (int n = 0; n < 100; ++n) {
      const Motion m = random_motion(rng, kind);
      // Times before, during and after the motion, away from its kinks at start and stop.
      const double t = rng.uniform(-1.0, m.stop + 2.0);
      if (std::abs(t - m.start) < 1e-4 || std::abs(t - m.stop) < 1e-4) continue;
      const Vec3 v = motion_velocity(m, t), fd = fd_offset(m, t);
      EXPECT_TRUE(test::near(v, fd, test::kFdTol))
          << "kind " << static_cast<int>(kind) << ", t = " << t << ": " << test::str(v) << " vs " << test::str(fd);
    }
  }
}

TEST(Model, MotionOffsetsFollowTheirDefinitions) {
  Motion lin;
  lin.kind = MotionKind::Linear;
  lin.velocity = Vec3(1, 2, 3);
  lin.start = 1.0;
  lin.stop = 3.0;
  EXPECT_EQ(motion_offset(lin, 0.5), Vec3::Zero());                                         // before start
  EXPECT_TRUE(test::near(motion_offset(lin, 2.0), Vec3(1, 2, 3), test::kRoundoff));         // during
  EXPECT_TRUE(test::near(motion_offset(lin, 10.0), Vec3(2, 4, 6), test::kRoundoff));        // held after stop
  EXPECT_EQ(motion_velocity(lin, 10.0), Vec3::Zero());

  Motion osc;
  osc.kind = MotionKind::Oscillate;
  osc.amplitude = Vec3(0, 0.5, 0);
  osc.frequency = 2.0;
  osc.start = 0.25;
  EXPECT_EQ(motion_offset(osc, 0.1), Vec3::Zero());
  // A quarter period after the start (1/8 s) the offset is the full amplitude.
  EXPECT_TRUE(test::near(motion_offset(osc, 0.25 + 0.125), Vec3(0, 0.5, 0), test::kRoundoff));

  Random rng(42);
  for (int n = 0; n < 50; ++n) {
    const Motion c = random_motion(rng, MotionKind::Circle);
    const Vec3 axis = c.axis.normalized();
    const double t = c.start + rng.uniform(0.0, 5.0);
    const Vec3 off = motion_offset(c, t);
    // The offset stays in the plane perpendicular to the axis, on a circle of `radius` that
    // passes through the start point: |off - centre| = radius with |centre| = radius.
    EXPECT_TRUE(test::near(off.dot(axis), 0.0, test::kRoundoff));
    // Half a period after the start the offset is the diameter: the centre is half of it.
    const Vec3 centre = 0.5 * motion_offset(c, c.start + 0.5 / c.frequency);
    EXPECT_TRUE(test::near(centre.norm(), c.radius, test::kRoundoff));
    EXPECT_TRUE(test::near((off - centre).norm(), c.radius, test::kRoundoff)) << "t = " << t;
    // One full period returns to the start.
    EXPECT_TRUE(test::near(motion_offset(c, c.start + 1.0 / c.frequency), Vec3::Zero(), {1e-12, 0.0}));
    // The rotation is positive about the axis: (off x velocity) . axis > 0 around the centre.
    EXPECT_GT((off - centre).cross(motion_velocity(c, t)).dot(axis), 0.0);
  }
  Motion still;
  EXPECT_EQ(motion_offset(still, 3.0), Vec3::Zero());
  EXPECT_EQ(motion_velocity(still, 3.0), Vec3::Zero());
}

TEST(Model, RestStatePlacesAttachedParticlesOnTheirTargets) {
  Model m;
  m.rest_positions.resize(4, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0;
  m.inv_mass = {0, 1, 0, 1};
  m.radius = {0.1, 0.1, 0.1, 0.1};
  Motion lin;
  lin.kind = MotionKind::Linear;
  lin.velocity = Vec3(0, 1, 0);
  lin.start = -2.0;  // already moving at t = 0: offset (0, 2, 0)
  m.motions.push_back(lin);
  m.attachments.push_back({0, Vec3(0, 5, 0), -1});  // a static pin away from the rest position
  m.attachments.push_back({2, Vec3(2, 0, 0), 0});
  Constraint c;
  c.particles = {0, 1, -1, -1};
  m.constraints.assign(3, c);

  const State s = rest_state(m);
  EXPECT_EQ(s.time, 0.0);
  EXPECT_EQ(s.step, 0);
  ASSERT_EQ(s.x.rows(), 4);
  ASSERT_EQ(s.v.rows(), 4);
  EXPECT_EQ(s.lambda, std::vector<double>(3, 0.0));
  for (const Attachment& a : m.attachments)
    EXPECT_TRUE(test::near(Vec3(s.x.row(a.particle)), attachment_target(m, a, 0.0), test::kRoundoff));
  EXPECT_TRUE(test::near(Vec3(s.x.row(0)), Vec3(0, 5, 0), test::kRoundoff));
  EXPECT_TRUE(test::near(Vec3(s.x.row(2)), Vec3(2, 2, 0), test::kRoundoff));
  // Free particles stay at rest, and nothing moves.
  EXPECT_EQ(Vec3(s.x.row(1)), Vec3(1, 0, 0));
  EXPECT_EQ(Vec3(s.x.row(3)), Vec3(3, 0, 0));
  EXPECT_TRUE(s.v.isZero());
  // The attachment target moves with the motion.
  EXPECT_TRUE(test::near(attachment_target(m, m.attachments[1], 1.0), Vec3(2, 3, 0), test::kRoundoff));
}

TEST(Model, GroupIndexAddsEachNameOnce) {
  Model m;
  EXPECT_EQ(m.group_index("stretch"), 0);
  EXPECT_EQ(m.group_index("shear"), 1);
  EXPECT_EQ(m.group_index("stretch"), 0);
  EXPECT_EQ(m.group_names, (std::vector<std::string>{"stretch", "shear"}));
}

TEST(Model, UpIsOppositeToGravity) {
  Model m;
  EXPECT_TRUE(test::near(up_direction(m), Vec3::UnitY(), test::kRoundoff));
  m.gravity = Vec3(0, 0, -3);
  EXPECT_TRUE(test::near(up_direction(m), Vec3::UnitZ(), test::kRoundoff));
  m.gravity = Vec3::Zero();
  EXPECT_EQ(up_direction(m), Vec3::UnitY());
}

TEST(Model, SphereCentreFollowsItsMotion) {
  Model m;
  Motion osc;
  osc.kind = MotionKind::Oscillate;
  osc.amplitude = Vec3(1, 0, 0);
  osc.frequency = 0.25;  // a quarter period is 1 s
  m.motions.push_back(osc);
  SphereCollider s;
  s.center = Vec3(0, 1, 0);
  EXPECT_EQ(sphere_center(m, s, 1.0), Vec3(0, 1, 0));  // fixed sphere
  s.motion = 0;
  EXPECT_TRUE(test::near(sphere_center(m, s, 1.0), Vec3(1, 1, 0), test::kRoundoff));
}

}  // namespace
}  // namespace pbdbench
