// Tests of core/contacts: contact gradients against central differences, the grid-based finder
// against brute force, exclusions, bowls, moving spheres and surface velocities.
#include "core/contacts.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <tuple>
#include <utility>

#include "core/generators.hpp"
#include "core/surface_contact.hpp"
#include "tests/core/test_support.hpp"
#include "tests/mesh_fixtures.hpp"

namespace pbdbench {
namespace {

using test::Config4;
using test::Random;

constexpr int kConfigurations = 400;
constexpr double kMaxSkippedFraction = 0.01;

// A model of two free particles of radius 0.05 and 0.08, with no colliders yet.
Model two_particles() {
  Model m;
  m.rest_positions = Points::Zero(2, 3);
  m.inv_mass = {1.0, 2.0};
  m.radius = {0.05, 0.08};
  return m;
}

Points to_points(const Config4& x, int n) {
  Points p(n, 3);
  for (int i = 0; i < n; ++i) p.row(i) = x[static_cast<size_t>(i)].transpose();
  return p;
}

// Gradient checks of one contact over random particle positions; the collider is redrawn by
// `setup` for every configuration. `arity` is 1 for collider contacts and 2 for particle pairs.
void check_contact(const char* name, const std::function<void(Model&, Random&)>& setup,
                   const Contact& contact, int arity, double t, std::uint64_t seed) {
  Random rng(seed);
  int skipped = 0, failures = 0;
  for (int n = 0; n < kConfigurations; ++n) {
    Model model = two_particles();
    setup(model, rng);
    const Config4 x{rng.vec(-2, 2), rng.vec(-2, 2), Vec3::Zero(), Vec3::Zero()};
    const auto eval = [&](const Config4& y) { return eval_contact(model, contact, to_points(y, 2), t); };
    const ConstraintEval e = eval(x);
    if (!e.valid) {
      ++skipped;
      continue;
    }
    std::string problem = test::check_gradient(eval, x, arity);
    if (arity == 2) {
      const std::string momentum = test::check_momentum(e, x, 2);
      problem += (problem.empty() || momentum.empty() ? "" : "; ") + momentum;
    }
    if (!problem.empty()) {
      ADD_FAILURE() << name << ", configuration " << n << " (seed " << seed << "): " << problem;
      if (++failures >= 5) return;
    }
  }
  EXPECT_LE(skipped, kMaxSkippedFraction * kConfigurations) << name << ": too many invalid configurations";
}

TEST(Contacts, PlaneGradientWithNonUnitNormalMatchesFiniteDifferences) {
  const auto setup = [](Model& m, Random& rng) {
    PlaneCollider p;
    // A normal of length 0.1 to 10 in a random direction.
    p.normal = rng.vec(-1, 1).normalized() * rng.uniform(0.1, 10.0);
    p.offset = rng.uniform(-1, 1);
    m.planes.push_back(p);
  };
  check_contact("plane", setup, {ContactKind::Plane, 0, 0}, 1, 0.0, 21);

  // The value uses the unit normal: the distance of x = (0, 3, 0) above the plane 2y - 2 = 0
  // (y = 1), minus the radius 0.05.
  Model m = two_particles();
  PlaneCollider p;
  p.normal = Vec3(0, 2, 0);
  p.offset = -2.0;
  m.planes.push_back(p);
  Points x = Points::Zero(2, 3);
  x(0, 1) = 3.0;
  const ConstraintEval e = eval_contact(m, {ContactKind::Plane, 0, 0}, x, 0.0);
  EXPECT_TRUE(test::near(e.C, 2.0 - 0.05, test::kRoundoff));
  EXPECT_TRUE(test::near(e.grad[0], Vec3::UnitY(), test::kRoundoff));
}

void sphere_setup(Model& m, Random& rng, SphereSide side, bool moving) {
  SphereCollider s;
  s.center = rng.vec(-1, 1);
  s.radius = rng.uniform(0.2, 1.5);
  s.side = side;
  if (moving) {
    Motion mo;
    mo.kind = MotionKind::Oscillate;
    mo.amplitude = rng.vec(-0.5, 0.5);
    mo.frequency = 1.3;
    m.motions.push_back(mo);
    s.motion = 0;
  }
  m.spheres.push_back(s);
}

TEST(Contacts, SphereGradientsMatchFiniteDifferences) {
  for (bool moving : {false, true}) {
    check_contact(moving ? "sphere outside (moving)" : "sphere outside",
                  [&](Model& m, Random& r) { sphere_setup(m, r, SphereSide::Outside, moving); },
                  {ContactKind::Sphere, 0, 0}, 1, 0.37, 22);
    check_contact(moving ? "sphere inside (moving)" : "sphere inside",
                  [&](Model& m, Random& r) { sphere_setup(m, r, SphereSide::Inside, moving); },
                  {ContactKind::Sphere, 0, 0}, 1, 0.37, 23);
    check_contact(moving ? "bowl (moving)" : "bowl",
                  [&](Model& m, Random& r) { sphere_setup(m, r, SphereSide::Bowl, moving); },
                  {ContactKind::Sphere, 0, 0}, 1, 0.37, 24);
  }
}

void mesh_setup(Model& m, Random& rng, bool moving) {
  // An icosphere (closed: inside and outside) or a cube, at a random place and size.
  const Vec3 c = rng.vec(-1, 1);
  const double size = rng.uniform(0.3, 1.5);
  const test::TriMesh t = rng.uniform() < 0.5 ? test::icosphere_mesh(1, size, c) : test::cube_mesh(size, c);
  m.meshes.push_back(test::collider_of(t));
  if (moving) {
    Motion mo;
    mo.kind = MotionKind::Circle;
    mo.axis = rng.vec(-1, 1).normalized();
    mo.radius = 0.4;
    mo.frequency = 0.7;
    m.motions.push_back(mo);
    m.meshes.back().motion = 0;
  }
}

TEST(Contacts, MeshGradientsMatchFiniteDifferences) {
  for (bool moving : {false, true})
    check_contact(moving ? "mesh (moving)" : "mesh",
                  [&](Model& m, Random& r) { mesh_setup(m, r, moving); },
                  {ContactKind::Mesh, 0, 0}, 1, 0.37, moving ? 26 : 25);
}

TEST(Contacts, MeshContactsAreFoundAsTheirDistanceSays) {
  // Particles on a line through a cube of half-size 0.5: found when C < margin, with C the
  // signed distance minus the radius; the mesh's contacts come after the spheres'.
  Model m;
  for (int i = 0; i < 21; ++i) add_particle(m, Vec3(-1.0 + 0.1 * i, 0.1, 0.05), 1.0, 0.05);
  m.spheres.push_back(SphereCollider{Vec3(5.0, 0.0, 0.0), 0.1, SphereSide::Inside});
  m.meshes.push_back(test::collider_of(test::cube_mesh(0.5)));
  const double margin = 0.02;
  const std::vector<Contact> found = find_contacts(m, m.rest_positions, 0.0, margin);
  std::vector<int> mesh_particles;
  bool after_spheres = true, seen_mesh = false;
  for (const Contact& c : found) {
    if (c.kind == ContactKind::Mesh) {
      seen_mesh = true;
      mesh_particles.push_back(c.a);
    } else if (seen_mesh) {
      after_spheres = false;
    }
  }
  EXPECT_TRUE(after_spheres);
  std::vector<int> expected;
  for (int i = 0; i < 21; ++i) {
    const double x = -1.0 + 0.1 * i;
    const double dist = std::abs(x) > 0.5 ? std::abs(x) - 0.5 : -std::min(0.5 - std::abs(x), 0.4);
    if (dist - 0.05 < margin) expected.push_back(i);
  }
  EXPECT_EQ(mesh_particles, expected);
  const ConstraintEval e = eval_contact(m, {ContactKind::Mesh, 14, 0}, m.rest_positions, 0.0);
  EXPECT_NEAR(e.C, 0.4 - 0.5 - 0.05, 1e-12);  // x = 0.4: 0.1 inside the face x = 0.5
  EXPECT_TRUE(test::near(e.grad[0], Vec3::UnitX(), test::kRoundoff));
  EXPECT_STREQ(to_string(ContactKind::Mesh), "mesh");
}

TEST(Contacts, VertexTriangleGradientMatchesFiniteDifferencesAndConservesMomentum) {
  // Particle 0 against the triangle of particles 1, 2, 3 (random positions: face, edge and
  // vertex regions all occur); the gradient over all four particles, and its momentum
  // properties (an internal contact: the gradients sum to zero and exert no torque).
  Random rng(31);
  int failures = 0;
  for (int n = 0; n < kConfigurations && failures < 5; ++n) {
    Model m;
    for (int i = 0; i < 4; ++i) add_particle(m, Vec3::Zero(), 1.0, 0.01 * (i + 1));
    m.triangles.push_back({1, 2, 3});
    m.surface_contact = true;
    const Config4 x{rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1)};
    const Contact c{ContactKind::Triangle, 0, 0};
    const auto eval = [&](const Config4& y) { return eval_contact(m, c, to_points(y, 4), 0.0); };
    const ConstraintEval e = eval(x);
    ASSERT_TRUE(e.valid);
    std::string problem = test::check_gradient(eval, x, 4);
    const std::string momentum = test::check_momentum(e, x, 4);
    problem += (problem.empty() || momentum.empty() ? "" : "; ") + momentum;
    if (!problem.empty()) {
      ADD_FAILURE() << "configuration " << n << ": " << problem;
      ++failures;
    }
  }
  // The closed form: a particle 0.3 above the triangle's interior, radii 0.01 and max 0.04.
  Model m;
  add_particle(m, Vec3(0.2, 0.2, 0.3), 1.0, 0.01);
  add_particle(m, Vec3(0, 0, 0), 1.0, 0.02);
  add_particle(m, Vec3(1, 0, 0), 1.0, 0.03);
  add_particle(m, Vec3(0, 1, 0), 1.0, 0.04);
  m.inv_mass[3] = 0.0;  // a pinned vertex: the contact is found all the same
  m.triangles.push_back({1, 2, 3});
  m.particle_body = {0, 1, 1, 1};  // two bodies: the particle and the triangle
  m.surface_contact = true;
  const ConstraintEval e = eval_contact(m, {ContactKind::Triangle, 0, 0}, m.rest_positions, 0.0);
  EXPECT_NEAR(e.C, 0.3 - 0.05, 1e-15);
  EXPECT_TRUE(test::near(e.grad[0], Vec3::UnitZ(), test::kRoundoff));
  EXPECT_TRUE(test::near(e.grad[1], -0.6 * Vec3::UnitZ(), test::kRoundoff));
  std::array<int, 4> ps{};
  EXPECT_EQ(contact_particles(m, {ContactKind::Triangle, 0, 0}, ps), 4);
  EXPECT_EQ(ps, (std::array<int, 4>{0, 1, 2, 3}));
  // Found by the finder below a margin, never against its own triangle, sorted.
  const std::vector<Contact> found = find_contacts(m, m.rest_positions, 0.0, 0.3);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].kind, ContactKind::Triangle);
  EXPECT_TRUE(find_contacts(m, m.rest_positions, 0.0, 0.2).empty());
  m.surface_contact = false;
  EXPECT_TRUE(find_contacts(m, m.rest_positions, 0.0, 0.3).empty());
}

TEST(Contacts, EdgeEdgeGradientMatchesFiniteDifferencesAndConservesMomentum) {
  // Edge (0, 1) against edge (2, 3) at random positions (closest points inside both edges, at an
  // end of one, at ends of both all occur); the gradient over all four particles, and its
  // momentum properties.
  Random rng(37);
  int failures = 0, interior = 0, clamped = 0;
  for (int n = 0; n < kConfigurations && failures < 5; ++n) {
    Model m;
    for (int i = 0; i < 4; ++i) add_particle(m, Vec3::Zero(), 1.0, 0.01 * (i + 1));
    m.triangles = {{0, 1, 1}, {2, 3, 3}};  // (the contact reads its particles from the Contact)
    m.surface_contact = true;
    const Config4 x{rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1)};
    const Contact c{ContactKind::Edge, 0, 1, 2, 3};
    const auto eval = [&](const Config4& y) { return eval_contact(m, c, to_points(y, 4), 0.0); };
    const ConstraintEval e = eval(x);
    ASSERT_TRUE(e.valid);
    const SegmentSegment ss = segment_segment(x[0], x[1], x[2], x[3]);
    const bool inside = ss.s > 0.0 && ss.s < 1.0 && ss.t > 0.0 && ss.t < 1.0;
    interior += inside;
    clamped += !inside;
    std::string problem = test::check_gradient(eval, x, 4);
    const std::string momentum = test::check_momentum(e, x, 4);
    problem += (problem.empty() || momentum.empty() ? "" : "; ") + momentum;
    if (!problem.empty()) {
      ADD_FAILURE() << "configuration " << n << " (s " << ss.s << ", t " << ss.t << "): " << problem;
      ++failures;
    }
  }
  EXPECT_GT(interior, 20);
  EXPECT_GT(clamped, 20);
  // The closed form: edge (0, 1) along x at height 0.3, edge (2, 3) along z at height 0, crossing
  // above x = 0.25, z = -0.5 + 0.75: s = 0.25 / 1, t = 0.75; radii 0.01, 0.02 | 0.03, 0.04.
  Model m;
  add_particle(m, Vec3(0, 0.3, 0.25), 1.0, 0.01);
  add_particle(m, Vec3(1, 0.3, 0.25), 1.0, 0.02);
  add_particle(m, Vec3(0.25, 0, -0.5), 1.0, 0.03);
  add_particle(m, Vec3(0.25, 0, 0.5), 1.0, 0.04);
  m.triangles = {{0, 1, 1}, {2, 3, 3}};
  m.particle_body = {0, 0, 1, 1};
  m.surface_contact = true;
  const Contact c{ContactKind::Edge, 0, 1, 2, 3};
  const ConstraintEval e = eval_contact(m, c, m.rest_positions, 0.0);
  EXPECT_NEAR(e.C, 0.3 - (0.02 + 0.04), 1e-15);
  EXPECT_TRUE(test::near(e.grad[0], 0.75 * Vec3::UnitY(), test::kRoundoff));
  EXPECT_TRUE(test::near(e.grad[1], 0.25 * Vec3::UnitY(), test::kRoundoff));
  EXPECT_TRUE(test::near(e.grad[2], -0.25 * Vec3::UnitY(), test::kRoundoff));
  EXPECT_TRUE(test::near(e.grad[3], -0.75 * Vec3::UnitY(), test::kRoundoff));
  std::array<int, 4> ps{};
  EXPECT_EQ(contact_particles(m, c, ps), 4);
  EXPECT_EQ(ps, (std::array<int, 4>{0, 1, 2, 3}));
  EXPECT_STREQ(to_string(ContactKind::Edge), "edge");
  // Found below a margin (the degenerate "triangles" are the two edges; their vertex-triangle
  // distances are larger: 0.3 from a vertex to the other segment at best is not below 0.3).
  std::vector<Contact> found = find_contacts(m, m.rest_positions, 0.0, 0.25);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].kind, ContactKind::Edge);
  EXPECT_EQ(std::tie(found[0].a, found[0].b, found[0].c, found[0].d), std::make_tuple(0, 1, 2, 3));
  EXPECT_TRUE(find_contacts(m, m.rest_positions, 0.0, 0.23).empty());
  m.surface_contact = false;
  EXPECT_TRUE(find_contacts(m, m.rest_positions, 0.0, 0.25).empty());
}

TEST(Contacts, ParticlePairGradientMatchesFiniteDifferencesAndConservesMomentum) {
  check_contact("particle pair", [](Model&, Random&) {}, {ContactKind::Particle, 0, 1}, 2, 0.0, 25);
  Model m = two_particles();
  Points x = Points::Zero(2, 3);
  x(1, 0) = 0.1;
  // |x0 - x1| - (0.05 + 0.08) = -0.03: penetration.
  EXPECT_TRUE(test::near(eval_contact(m, {ContactKind::Particle, 0, 1}, x, 0.0).C, -0.03, test::kRoundoff));
}

TEST(Contacts, SphereValuesMatchTheirDefinitions) {
  Model m = two_particles();
  SphereCollider s;
  s.center = Vec3(1, 0, 0);
  s.radius = 0.5;
  m.spheres.push_back(s);
  Points x = Points::Zero(2, 3);  // particle 0 at the origin, distance 1 from the centre
  s.side = SphereSide::Outside;
  m.spheres[0] = s;
  EXPECT_TRUE(test::near(eval_contact(m, {ContactKind::Sphere, 0, 0}, x, 0).C, 1.0 - 0.55, test::kRoundoff));
  m.spheres[0].side = SphereSide::Inside;
  EXPECT_TRUE(test::near(eval_contact(m, {ContactKind::Sphere, 0, 0}, x, 0).C, 0.45 - 1.0, test::kRoundoff));
  // Inside: the gradient points towards the centre.
  EXPECT_TRUE(test::near(eval_contact(m, {ContactKind::Sphere, 0, 0}, x, 0).grad[0], Vec3::UnitX(), test::kRoundoff));
  // At the centre the direction is undefined.
  x.row(0) = s.center.transpose();
  EXPECT_FALSE(eval_contact(m, {ContactKind::Sphere, 0, 0}, x, 0).valid);
}

// ---------------------------------------------------------------------------------------------
// The finder.

using Key = std::tuple<int, int, int>;  // (kind, a, b)

std::vector<Key> keys(const std::vector<Contact>& contacts) {
  std::vector<Key> k;
  for (const Contact& c : contacts) k.emplace_back(static_cast<int>(c.kind), c.a, c.b);
  return k;
}

// Every contact by testing every particle against every collider and every pair, in the
// documented order: planes, spheres, particle pairs, each sorted by (a, b).
std::vector<Contact> brute_force(const Model& model, const Points& x, double t, double margin) {
  std::vector<Contact> out;
  const int n = model.particle_count();
  for (int a = 0; a < n; ++a)
    for (int p = 0; p < static_cast<int>(model.planes.size()); ++p) {
      if (model.inv_mass[static_cast<size_t>(a)] == 0.0) continue;
      const PlaneCollider& pl = model.planes[static_cast<size_t>(p)];
      const double C = (pl.normal.dot(Vec3(x.row(a))) + pl.offset) / pl.normal.norm() - model.radius[static_cast<size_t>(a)];
      if (C < margin) out.push_back({ContactKind::Plane, a, p});
    }
  const Vec3 up = up_direction(model);
  for (int a = 0; a < n; ++a)
    for (int s = 0; s < static_cast<int>(model.spheres.size()); ++s) {
      if (model.inv_mass[static_cast<size_t>(a)] == 0.0) continue;
      const SphereCollider& sp = model.spheres[static_cast<size_t>(s)];
      const Vec3 d = Vec3(x.row(a)) - sphere_center(model, sp, t);
      if (sp.side == SphereSide::Bowl && d.dot(up) >= 0.0) continue;
      const double r = model.radius[static_cast<size_t>(a)];
      const double C = sp.side == SphereSide::Outside ? d.norm() - (sp.radius + r) : (sp.radius - r) - d.norm();
      if (C < margin) out.push_back({ContactKind::Sphere, a, s});
    }
  if (!model.particle_contact) return out;
  std::vector<std::pair<int, int>> joined;
  for (const Constraint& c : model.constraints)
    for (int i = 0; i < arity(c.kind); ++i)
      for (int j = 0; j < arity(c.kind); ++j)
        if (i != j) joined.emplace_back(c.particles[static_cast<size_t>(i)], c.particles[static_cast<size_t>(j)]);
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b) {
      if (model.inv_mass[static_cast<size_t>(a)] == 0.0 && model.inv_mass[static_cast<size_t>(b)] == 0.0) continue;
      if (std::find(joined.begin(), joined.end(), std::make_pair(a, b)) != joined.end()) continue;
      const double C = (x.row(a) - x.row(b)).norm() - (model.radius[static_cast<size_t>(a)] + model.radius[static_cast<size_t>(b)]);
      if (C < margin) out.push_back({ContactKind::Particle, a, b});
    }
  return out;
}

// A random cloud of n particles in a box of side `extent`, radii in [r_lo, r_hi], some pinned,
// some pairs joined by distance constraints.
Model random_cloud(Random& rng, int n, double extent, double r_lo, double r_hi) {
  Model m;
  m.rest_positions.resize(n, 3);
  for (int i = 0; i < n; ++i) {
    m.rest_positions.row(i) = rng.vec(-extent / 2, extent / 2).transpose();
    m.inv_mass.push_back(rng.uniform() < 0.2 ? 0.0 : 1.0);
    m.radius.push_back(rng.uniform(r_lo, r_hi));
  }
  m.particle_contact = true;
  const std::uint16_t g = m.group_index("link");
  for (int k = 0; k < n / 4; ++k) {
    Constraint c;
    c.kind = k % 3 == 0 ? ConstraintKind::Volume : ConstraintKind::Distance;
    const int count = arity(c.kind);
    for (int i = 0; i < count; ++i) {
      int p = 0;
      do p = rng.integer(0, n - 1);
      while (std::find(c.particles.begin(), c.particles.begin() + i, p) != c.particles.begin() + i);
      c.particles[static_cast<size_t>(i)] = p;
    }
    c.group = g;
    m.constraints.push_back(c);
  }
  return m;
}

TEST(Contacts, GridFinderEqualsBruteForceOnRandomClouds) {
  Random rng(31);
  int total_pairs = 0, total_excluded_candidates = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const int n = rng.integer(2, 300);
    const double r_lo = rng.uniform(0.001, 0.05), r_hi = r_lo * rng.uniform(1.0, 4.0);
    const double extent = rng.uniform(0.2, 2.0);
    Model m = random_cloud(rng, n, extent, r_lo, r_hi);
    // Colliders too, so that the whole order (planes, spheres, pairs) is checked.
    PlaneCollider pl;
    pl.normal = Vec3(0.1, 3.0, -0.2);
    pl.offset = 0.3 * extent;
    m.planes.push_back(pl);
    SphereCollider s;
    s.center = rng.vec(-0.3, 0.3) * extent;
    s.radius = 0.3 * extent;
    s.side = static_cast<SphereSide>(trial % 3);
    m.spheres.push_back(s);
    for (double margin : {0.0, 0.01, -0.005, 0.1, r_hi}) {
      const Points& x = m.rest_positions;
      const std::vector<Contact> found = find_contacts(m, x, 0.0, margin);
      const std::vector<Contact> expected = brute_force(m, x, 0.0, margin);
      ASSERT_EQ(keys(found), keys(expected)) << "trial " << trial << ", n " << n << ", margin " << margin;
      for (const Contact& c : found) total_pairs += c.kind == ContactKind::Particle;
      // Count the candidates the exclusion removed, to know the exclusion was exercised.
      Model no_constraints = m;
      no_constraints.constraints.clear();
      total_excluded_candidates += static_cast<int>(find_contacts(no_constraints, x, 0.0, margin).size() - found.size());
    }
  }
  // The clouds were dense enough for the comparison to mean something.
  EXPECT_GT(total_pairs, 1000);
  EXPECT_GT(total_excluded_candidates, 20);
}

TEST(Contacts, FinderOutputIsGroupedByKindAndSortedByParticleThenCollider) {
  Random rng(32);
  Model m = random_cloud(rng, 200, 0.5, 0.02, 0.04);
  for (int p = 0; p < 2; ++p) {
    PlaneCollider pl;
    pl.offset = 0.2 - 0.1 * p;
    m.planes.push_back(pl);
  }
  for (int s = 0; s < 2; ++s) {
    SphereCollider sp;
    sp.radius = 0.1 + 0.05 * s;
    m.spheres.push_back(sp);
  }
  const std::vector<Contact> found = find_contacts(m, m.rest_positions, 0.0, 0.01);
  ASSERT_GT(found.size(), 10u);
  for (size_t i = 1; i < found.size(); ++i) {
    const Contact& p = found[i - 1];
    const Contact& c = found[i];
    ASSERT_LE(static_cast<int>(p.kind), static_cast<int>(c.kind)) << "at " << i;
    if (p.kind != c.kind) continue;
    if (c.kind == ContactKind::Particle) {
      EXPECT_LT(c.a, c.b);
    }
    EXPECT_LT(std::make_pair(p.a, p.b), std::make_pair(c.a, c.b)) << "at " << i;
  }
  // The same input gives the same output.
  EXPECT_EQ(keys(find_contacts(m, m.rest_positions, 0.0, 0.01)), keys(found));
}

TEST(Contacts, PairsJoinedByAConstraintAreExcluded) {
  Model m;
  m.rest_positions = Points::Zero(3, 3);
  m.rest_positions(1, 0) = 0.05;  // overlapping with 0
  m.rest_positions(2, 0) = 0.10;  // overlapping with 1
  m.inv_mass = {1, 1, 1};
  m.radius = {0.04, 0.04, 0.04};
  m.particle_contact = true;
  EXPECT_EQ(find_contacts(m, m.rest_positions, 0, 0).size(), 2u);
  Constraint c;
  c.particles = {1, 0, -1, -1};  // the order of the indices in the constraint does not matter
  c.rest = 0.05;
  m.constraints.push_back(c);
  const auto found = find_contacts(m, m.rest_positions, 0, 0);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].a, 1);
  EXPECT_EQ(found[0].b, 2);
  // Two pinned particles never touch; one pinned and one free do.
  m.constraints.clear();
  m.inv_mass = {0, 0, 1};
  const auto pinned = find_contacts(m, m.rest_positions, 0, 0);
  ASSERT_EQ(pinned.size(), 1u);
  EXPECT_EQ(std::make_pair(pinned[0].a, pinned[0].b), std::make_pair(1, 2));
  // Without particle contact, no pairs.
  m.particle_contact = false;
  EXPECT_TRUE(find_contacts(m, m.rest_positions, 0, 0).empty());
}

// An exploding run sends particles far away: the grid must neither overflow (undefined behaviour,
// caught by the sanitizer build) nor lose pairs whose cells are beyond the grid's range.
TEST(Contacts, FarFlungParticlesStillPairAndDoNotOverflowTheGrid) {
  Model m;
  m.rest_positions = Points::Zero(4, 3);
  m.inv_mass = {1, 1, 1, 1};
  m.radius = {0.05, 0.05, 0.05, 0.05};
  m.particle_contact = true;
  Points x(4, 3);
  x << 1e13, 0, 0,         // 1e13 / 0.1 = 1e14 cells: beyond the grid's +-2^40, clamped
       1e13 + 0.05, 0, 0,  // overlapping with particle 0 (distance 0.05 < 0.1)
       -1e300, 1e300, -1e300,
       0, 0, 0;
  const auto found = find_contacts(m, x, 0, 0);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(std::make_pair(found[0].a, found[0].b), std::make_pair(0, 1));
}

TEST(Contacts, BowlIgnoresParticlesAboveItsCentre) {
  Model m;
  m.rest_positions.resize(3, 3);
  m.rest_positions.row(0) << 0.0, 0.95, 0.0;   // above the centre, near the rim
  m.rest_positions.row(1) << 0.0, -0.95, 0.0;  // below, near the bottom
  m.rest_positions.row(2) << 0.95, 0.0, 0.0;   // level with the centre: (x - c) . up = 0
  m.inv_mass = {1, 1, 1};
  m.radius = {0.1, 0.1, 0.1};
  SphereCollider bowl;
  bowl.radius = 1.0;
  bowl.side = SphereSide::Bowl;
  m.spheres.push_back(bowl);
  // All three penetrate the inner wall (C = 0.9 - 0.95 < 0); only the one below counts.
  auto found = find_contacts(m, m.rest_positions, 0, 0);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].a, 1);
  // A closed inside sphere takes all three.
  m.spheres[0].side = SphereSide::Inside;
  EXPECT_EQ(find_contacts(m, m.rest_positions, 0, 0).size(), 3u);
  // "Up" follows gravity: with gravity along +x, up is -x and only particle 2 (at +x) is below.
  m.spheres[0].side = SphereSide::Bowl;
  m.gravity = Vec3(9.81, 0, 0);
  found = find_contacts(m, m.rest_positions, 0, 0);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].a, 2);
}

TEST(Contacts, MovingSphereCentreFollowsItsMotion) {
  Model m;
  m.rest_positions.resize(1, 3);
  m.rest_positions.row(0) << 2.5, 0.0, 0.0;
  m.inv_mass = {1};
  m.radius = {0.1};
  Motion mo;
  mo.kind = MotionKind::Linear;
  mo.velocity = Vec3(1.0, 0.0, 0.0);
  m.motions.push_back(mo);
  SphereCollider s;
  s.radius = 1.0;
  s.motion = 0;
  m.spheres.push_back(s);
  // At t = 0: C = 2.5 - 1.1 = 1.4; at t = 1 the centre is at x = 1: C = 0.4; at t = 2: -0.6.
  EXPECT_TRUE(find_contacts(m, m.rest_positions, 0.0, 0.5).empty());
  ASSERT_EQ(find_contacts(m, m.rest_positions, 1.0, 0.5).size(), 1u);
  const Contact c{ContactKind::Sphere, 0, 0};
  EXPECT_TRUE(test::near(eval_contact(m, c, m.rest_positions, 1.0).C, 0.4, test::kRoundoff));
  EXPECT_TRUE(test::near(eval_contact(m, c, m.rest_positions, 2.0).C, -0.6, test::kRoundoff));
  EXPECT_TRUE(test::near(sphere_center(m, s, 2.0), Vec3(2.0, 0, 0), test::kRoundoff));
}

TEST(Contacts, SurfaceVelocityIsTheDerivativeOfTheSphereCentre) {
  Model m;
  m.rest_positions = Points::Zero(2, 3);
  m.inv_mass = {1, 1};
  m.radius = {0.1, 0.1};
  Motion linear;
  linear.kind = MotionKind::Linear;
  linear.velocity = Vec3(0.3, -1.0, 2.0);
  linear.start = 0.1;
  linear.stop = 5.0;
  Motion osc;
  osc.kind = MotionKind::Oscillate;
  osc.amplitude = Vec3(0.2, 0.5, -0.1);
  osc.frequency = 1.7;
  osc.start = 0.05;
  Motion circle;
  circle.kind = MotionKind::Circle;
  circle.axis = Vec3(1.0, 2.0, 0.5);  // not unit on purpose
  circle.radius = 0.4;
  circle.frequency = 0.8;
  m.motions = {linear, osc, circle};
  for (int k = 0; k < 3; ++k) {
    SphereCollider s;
    s.center = Vec3(k, 1, 2);
    s.motion = k;
    m.spheres.push_back(s);
  }
  const double h = 1e-6;
  // Times away from the motions' kinks (start, stop).
  for (double t : {0.3, 0.77, 1.9, 4.2}) {
    for (int k = 0; k < 3; ++k) {
      const SphereCollider& s = m.spheres[static_cast<size_t>(k)];
      const Vec3 fd = (sphere_center(m, s, t + h) - sphere_center(m, s, t - h)) / (2 * h);
      const Vec3 v = contact_surface_velocity(m, {ContactKind::Sphere, 0, k}, Points::Zero(2, 3), t);
      EXPECT_TRUE(test::near(v, fd, test::kFdTol)) << "motion " << k << " at t = " << t << ": " << test::str(v)
                                                   << " vs " << test::str(fd);
    }
  }
  // Planes and fixed spheres do not move; a particle pair reports the other particle's velocity.
  Points v = Points::Zero(2, 3);
  v.row(1) << 1.0, 2.0, 3.0;
  m.planes.push_back(PlaneCollider{});
  SphereCollider fixed;
  m.spheres.push_back(fixed);
  EXPECT_EQ(contact_surface_velocity(m, {ContactKind::Plane, 0, 0}, v, 1.0), Vec3::Zero());
  EXPECT_EQ(contact_surface_velocity(m, {ContactKind::Sphere, 0, 3}, v, 1.0), Vec3::Zero());
  EXPECT_EQ(contact_surface_velocity(m, {ContactKind::Particle, 0, 1}, v, 1.0), Vec3(1, 2, 3));
}

TEST(Contacts, CoefficientsComeFromTheRightSource) {
  Model m = two_particles();
  PlaneCollider p;
  p.restitution = 0.3;
  p.friction = 0.4;
  m.planes.push_back(p);
  SphereCollider s;
  s.restitution = 0.5;
  s.friction = 0.6;
  m.spheres.push_back(s);
  m.particle_restitution = 0.7;
  m.particle_friction = 0.8;
  EXPECT_EQ(contact_restitution(m, {ContactKind::Plane, 0, 0}), 0.3);
  EXPECT_EQ(contact_friction(m, {ContactKind::Plane, 0, 0}), 0.4);
  EXPECT_EQ(contact_restitution(m, {ContactKind::Sphere, 0, 0}), 0.5);
  EXPECT_EQ(contact_friction(m, {ContactKind::Sphere, 0, 0}), 0.6);
  EXPECT_EQ(contact_restitution(m, {ContactKind::Particle, 0, 1}), 0.7);
  EXPECT_EQ(contact_friction(m, {ContactKind::Particle, 0, 1}), 0.8);
  EXPECT_STREQ(to_string(ContactKind::Plane), "plane");
  EXPECT_STREQ(to_string(ContactKind::Sphere), "sphere");
  EXPECT_STREQ(to_string(ContactKind::Particle), "particle");
}

}  // namespace
}  // namespace pbdbench
