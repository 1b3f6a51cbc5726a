// Tests of core/model_checks: sound generated models report nothing; each kind of problem is
// found and named.
#include "core/model_checks.hpp"

#include <gtest/gtest.h>

#include <limits>

#include "core/generators.hpp"
#include "core/mesh_io.hpp"
#include "core/state.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string joined(const std::vector<ModelProblem>& problems) {
  std::string s;
  for (const ModelProblem& p : problems) s += p.what + "\n";
  return s;
}

// Expects exactly one problem, whose message contains `fragment`.
void expect_one(const std::vector<ModelProblem>& problems, const std::string& fragment) {
  ASSERT_EQ(problems.size(), 1u) << joined(problems);
  EXPECT_NE(problems[0].what.find(fragment), std::string::npos) << problems[0].what;
}

// A sound model with a bit of everything: a pinned cloth, a chain, a tet block, colliders and a
// motion.
Model sound_model() {
  Model m;
  ClothSpec cloth;
  cloth.nx = 4;
  cloth.ny = 3;
  cloth.plane = "xy";
  add_cloth(m, cloth);
  ChainSpec chain;
  chain.links = 3;
  chain.top = Vec3(3, 0, 0);
  add_chain(m, chain);
  TetBlockSpec block;
  block.cells = {2, 1, 1};
  block.origin = Vec3(-3, 0, 0);
  add_tet_block(m, block);
  // Pin a cloth corner with a moving attachment.
  Motion circle;
  circle.kind = MotionKind::Circle;
  circle.radius = 0.1;
  circle.frequency = 1;
  m.motions.push_back(circle);
  m.inv_mass[0] = 0.0;
  m.attachments.push_back({0, Vec3(m.rest_positions.row(0)), 0});
  PlaneCollider floor;
  floor.offset = 2.0;
  m.planes.push_back(floor);
  SphereCollider ball;
  ball.center = Vec3(0, -1, 0);
  ball.radius = 0.3;
  ball.motion = 0;
  m.spheres.push_back(ball);
  return m;
}

TEST(ModelChecks, SoundModelsReportNothing) {
  const Model m = sound_model();
  EXPECT_TRUE(check_model(m).empty()) << joined(check_model(m));
  EXPECT_TRUE(check_state(m, rest_state(m)).empty()) << joined(check_state(m, rest_state(m)));
  Model spheres;
  add_packed_spheres(spheres, PackedSpheresSpec{});
  EXPECT_TRUE(check_model(spheres).empty());
  Model sphere_mesh;
  add_surface_mesh(sphere_mesh, read_obj((test::mesh_dir() / "icosphere.obj").string()), {}, "icosphere.obj");
  EXPECT_TRUE(check_model(sphere_mesh).empty()) << joined(check_model(sphere_mesh));
  Model box;
  add_tet_mesh(box, read_tet_mesh((test::mesh_dir() / "box.node").string()), {}, "box.node");
  EXPECT_TRUE(check_model(box).empty()) << joined(check_model(box));
  EXPECT_TRUE(check_model(Model{}).empty());
}

TEST(ModelChecks, ParticleProblems) {
  Model m = sound_model();
  m.inv_mass[5] = -1.0;
  expect_one(check_model(m), "particle 5: inverse mass -1 is negative");
  m = sound_model();
  m.inv_mass[5] = std::numeric_limits<double>::infinity();
  expect_one(check_model(m), "particle 5: inverse mass inf is not finite");
  m = sound_model();
  m.rest_positions(7, 1) = kNaN;
  // A NaN position also makes the elements around it degenerate-looking; the position is named.
  const auto problems = check_model(m);
  ASSERT_FALSE(problems.empty());
  EXPECT_NE(problems[0].what.find("particle 7: position"), std::string::npos) << joined(problems);
  m = sound_model();
  m.radius[2] = 0.0;
  expect_one(check_model(m), "particle 2: radius 0");
  m = sound_model();
  m.radius.pop_back();
  expect_one(check_model(m), "radius has");
  m = sound_model();
  m.particle_body.assign(static_cast<size_t>(m.particle_count()) - 1, 0);
  expect_one(check_model(m), "particle_body has");
  m.particle_body.assign(static_cast<size_t>(m.particle_count()), 0);
  EXPECT_TRUE(check_model(m).empty());
  m.particle_body[3] = -1;
  expect_one(check_model(m), "particle 3: body -1");
  m = sound_model();
  m.gravity.x() = kNaN;
  expect_one(check_model(m), "gravity");
}

TEST(ModelChecks, IndexProblems) {
  Model m = sound_model();
  const int n = m.particle_count();
  m.constraints[3].particles[1] = n;
  expect_one(check_model(m), "constraint 3 (distance) (particles");
  EXPECT_NE(check_model(m)[0].what.find("index " + std::to_string(n) + " is out of range"), std::string::npos);
  m = sound_model();
  m.constraints[3].particles[1] = m.constraints[3].particles[0];
  expect_one(check_model(m), "repeats particle");
  m = sound_model();
  m.edges[0][0] = -1;
  expect_one(check_model(m), "edge 0 (particles -1");
  m = sound_model();
  m.triangles[2][2] = n + 4;
  expect_one(check_model(m), "triangle 2");
  m = sound_model();
  m.tets[1][0] = -3;
  expect_one(check_model(m), "tet 1");
  m = sound_model();
  m.attachments[0].particle = n;
  expect_one(check_model(m), "attachment 0: particle");
  m = sound_model();
  m.attachments[0].motion = 5;
  expect_one(check_model(m), "attachment 0: motion 5 is out of range");
  m = sound_model();
  m.spheres[0].motion = -2;
  expect_one(check_model(m), "sphere 0: motion -2 is out of range");
  m = sound_model();
  m.constraints[0].group = 99;
  expect_one(check_model(m), "group 99 is out of range");
}

TEST(ModelChecks, ParameterProblems) {
  Model m = sound_model();
  m.constraints[4].stiffness = 1.5;
  expect_one(check_model(m), "constraint 4 (distance): stiffness 1.5 is outside [0, 1]");
  m = sound_model();
  m.constraints[4].stiffness = -0.1;
  expect_one(check_model(m), "stiffness -0.1 is outside [0, 1]");
  m = sound_model();
  m.constraints[4].compliance = -1e-6;
  expect_one(check_model(m), "compliance -1e-06 is negative");
  m = sound_model();
  m.constraints[4].damping = -1.0;
  expect_one(check_model(m), "damping -1 is negative");
  m = sound_model();
  m.constraints[4].rest = -0.1;
  expect_one(check_model(m), "rest length -0.1 is negative");
  m = sound_model();
  m.constraints[4].rest = kNaN;
  expect_one(check_model(m), "rest nan is not finite");
  m = sound_model();
  m.planes[0].normal = Vec3::Zero();
  expect_one(check_model(m), "plane 0: normal is zero");
  m = sound_model();
  m.planes[0].restitution = 1.2;
  expect_one(check_model(m), "plane 0: restitution 1.2 is outside [0, 1]");
  m = sound_model();
  m.spheres[0].radius = -1.0;
  expect_one(check_model(m), "sphere 0: radius -1");
  m = sound_model();
  m.spheres[0].friction = -0.5;
  expect_one(check_model(m), "sphere 0: friction -0.5");
  m = sound_model();
  m.particle_restitution = -0.5;
  expect_one(check_model(m), "particle contact: restitution");
  m = sound_model();
  m.motions[0].axis = Vec3::Zero();
  expect_one(check_model(m), "motion 0: circle axis is zero");
}

TEST(ModelChecks, AttachmentToADynamicParticle) {
  // Attachment 0 is the chain's pin (particle 12), attachment 1 the cloth corner (particle 0).
  Model m = sound_model();
  ASSERT_EQ(m.attachments.size(), 2u);
  ASSERT_EQ(m.attachments[1].particle, 0);
  m.inv_mass[0] = 2.0;
  expect_one(check_model(m), "attachment 1: particle 0 has inverse mass 2, not 0");
  m = sound_model();
  m.attachments.push_back(m.attachments[1]);
  expect_one(check_model(m), "particle 0 is attached more than once");
}

TEST(ModelChecks, DegenerateElements) {
  Model m;
  m.rest_positions.resize(5, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1;
  m.inv_mass.assign(5, 1.0);
  m.radius.assign(5, 0.01);
  m.tets = {{0, 1, 2, 4}, {0, 1, 2, 3}};  // the second is flat
  expect_one(check_model(m), "tet 1 (particles 0 1 2 3) is degenerate: volume 0");
  m.tets = {{0, 1, 2, 4}};
  m.triangles = {{0, 1, 2}, {0, 1, 1}};
  expect_one(check_model(m), "triangle 1 (particles 0 1 1) repeats particle 1");
  m.rest_positions.row(3) << 2, 0, 0;  // on the line through 0 and 1
  m.triangles = {{0, 1, 3}};
  expect_one(check_model(m), "triangle 0 (particles 0 1 3) is degenerate: area 0");
  // Small but well-shaped elements are not degenerate: the test is relative to the edge length.
  Model tiny;
  tiny.rest_positions.resize(4, 3);
  tiny.rest_positions << 0, 0, 0, 1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-4;
  tiny.inv_mass.assign(4, 1.0);
  tiny.radius.assign(4, 1e-5);
  tiny.tets = {{0, 1, 2, 3}};
  tiny.triangles = {{0, 2, 1}};
  EXPECT_TRUE(check_model(tiny).empty()) << joined(check_model(tiny));
  // A sliver below 1e-9 (max edge)^3 is degenerate.
  tiny.rest_positions(3, 2) = 1e-4 * 1e-9;
  expect_one(check_model(tiny), "tet 0 (particles 0 1 2 3) is degenerate");
}

TEST(ModelChecks, StateProblems) {
  const Model m = sound_model();
  State s = rest_state(m);
  s.v(4, 2) = kNaN;
  expect_one(check_state(m, s), "particle 4: velocity");
  s = rest_state(m);
  s.x(1, 0) = std::numeric_limits<double>::infinity();
  expect_one(check_state(m, s), "particle 1: position");
  s = rest_state(m);
  s.lambda.pop_back();
  expect_one(check_state(m, s), "lambda has");
  s = rest_state(m);
  s.lambda[2] = kNaN;
  expect_one(check_state(m, s), "constraint 2: lambda nan");
  s = rest_state(m);
  s.x.conservativeResize(s.x.rows() - 1, 3);
  expect_one(check_state(m, s), "x has");
  s = rest_state(m);
  s.time = kNaN;
  expect_one(check_state(m, s), "time nan");
}

}  // namespace
}  // namespace pbdbench
