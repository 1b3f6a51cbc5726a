// Tests of core/surface_contact: the point-triangle distance on closed forms, the pair rules
// (bodies, self-contact, neighbours, tet bodies), and the BVH-based finder against brute force.
// The gradient of a vertex-triangle contact against central differences is in test_contacts.cpp
// (it is eval_contact's).
#include "core/surface_contact.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <utility>
#include <vector>

#include "core/contacts.hpp"
#include "core/generators.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using test::Random;

TEST(SurfaceContact, PointTriangleClosedForms) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Above the face: distance 0.5, normal +z, q = (0.25, 0.25, 0) = 0.5 a + 0.25 b + 0.25 c.
  PointTriangle pt = point_triangle(Vec3(0.25, 0.25, 0.5), a, b, c);
  EXPECT_NEAR(pt.distance, 0.5, 1e-15);
  EXPECT_TRUE(test::near(pt.normal, Vec3::UnitZ(), test::kRoundoff));
  EXPECT_TRUE(test::near(pt.bary, Vec3(0.5, 0.25, 0.25), test::kRoundoff));
  // Below: the distance is unsigned, the normal points to the particle (-z).
  pt = point_triangle(Vec3(0.25, 0.25, -0.5), a, b, c);
  EXPECT_NEAR(pt.distance, 0.5, 1e-15);
  EXPECT_TRUE(test::near(pt.normal, -Vec3::UnitZ(), test::kRoundoff));
  // Beyond the edge bc: q = (0.5, 0.5, 0), the distance to (1, 1, 0) is sqrt(0.5).
  pt = point_triangle(Vec3(1, 1, 0), a, b, c);
  EXPECT_NEAR(pt.distance, std::sqrt(0.5), 1e-15);
  EXPECT_TRUE(test::near(pt.bary, Vec3(0.0, 0.5, 0.5), test::kRoundoff));
  // Beyond the vertex a: q = a.
  pt = point_triangle(Vec3(-3, -4, 0), a, b, c);
  EXPECT_NEAR(pt.distance, 5.0, 1e-15);
  EXPECT_TRUE(test::near(pt.bary, Vec3(1, 0, 0), test::kRoundoff));
  // On the triangle (at its vertex b): distance 0, the normal is the face's.
  pt = point_triangle(b, a, b, c);
  EXPECT_EQ(pt.distance, 0.0);
  EXPECT_TRUE(test::near(pt.normal, Vec3::UnitZ(), test::kRoundoff));
}

// A square n x n cloth of side `width` (m) and particle radius `radius` (m) in the xz plane.
ClothSpec square_cloth(int n, double width, double radius) {
  ClothSpec c;
  c.nx = c.ny = n;
  c.width = c.height = width;
  c.radius = radius;
  return c;
}

// Two 6 x 6 cloths (body 0 and body 1), 0.5 m, particles 0.1 m apart of radius 0.02 m.
Model two_cloths() {
  Model m;
  ClothSpec c = square_cloth(6, 0.5, 0.02);
  add_cloth(m, c);
  c.origin = Vec3(0.0, 0.05, 0.0);
  add_cloth(m, c);
  m.particle_body.assign(36, 0);
  m.particle_body.resize(72, 1);
  return m;
}

TEST(SurfaceContact, PairRulesBetweenBodiesAndWithinOne) {
  Model m = two_cloths();
  // Particle 0 of body 0 against triangle 50 (body 1's triangle 0, vertices 36, 42, 43).
  const int other = 50, own_far = 30, own_ring = 0;
  ASSERT_EQ(m.triangles[other][0], 36);
  EXPECT_FALSE(surface_pair_allowed(m, 0, other));  // both switches off
  m.surface_contact = true;
  EXPECT_TRUE(surface_pair_allowed(m, 0, other));
  EXPECT_FALSE(surface_pair_allowed(m, 0, own_far));  // within a body: self-contact is off
  m.self_contact = true;
  // Triangle 30 (cell (0, 3): vertices 18, 24, 25) is beyond particle 0's neighbours (1, 6, 7);
  // triangle 0 (0, 6, 7) holds it, triangle 2 (cell (1, 0): 1, 7, 8) holds its neighbours
  // 1 and 7.
  EXPECT_TRUE(surface_pair_allowed(m, 0, own_far));
  EXPECT_FALSE(surface_pair_allowed(m, 0, own_ring));
  EXPECT_FALSE(surface_pair_allowed(m, 0, 2));
  m.surface_contact = false;
  EXPECT_FALSE(surface_pair_allowed(m, 0, other));
  EXPECT_TRUE(surface_pair_allowed(m, 0, own_far));
  // All four pinned: no contact.
  for (int p : {0, 18, 24, 25}) m.inv_mass[static_cast<size_t>(p)] = 0.0;
  EXPECT_FALSE(surface_pair_allowed(m, 0, own_far));
  m.inv_mass[25] = 1.0;
  EXPECT_TRUE(surface_pair_allowed(m, 0, own_far));

  // A tet body never meets its own triangles (its interior vertices lie within the thickness
  // of its boundary), with self-contact on or off; against another body it does.
  Model b;
  TetBlockSpec t;
  t.cells = {2, 2, 2};
  t.size = Vec3(0.2, 0.2, 0.2);
  t.radius = 0.05;
  add_tet_block(b, t);
  b.self_contact = true;
  b.surface_contact = true;
  const int interior = 13;  // vertex (1, 1, 1)
  for (int tri = 0; tri < static_cast<int>(b.triangles.size()); ++tri)
    EXPECT_FALSE(surface_pair_allowed(b, interior, tri)) << tri;
  EXPECT_TRUE(find_surface_contacts(b, b.rest_positions, 0.0).empty());
}

TEST(SurfaceContact, FlatClothHasNoSelfContactsAtRest) {
  // Spacing 0.1 m, radius 0.035 m: the thickness 0.07 m is below the distance from a particle to
  // every triangle beyond its neighbours' (sqrt(2) spacing = 0.141 m), but above the distance to
  // the diagonal of a neighbouring cell (spacing / sqrt(2) = 0.071 m: those are excluded).
  Model m;
  add_cloth(m, square_cloth(12, 1.1, 0.035));
  m.self_contact = true;
  EXPECT_TRUE(find_surface_contacts(m, m.rest_positions, 0.0).empty());
  EXPECT_TRUE(find_surface_contacts(m, m.rest_positions, 0.07).empty());
  EXPECT_FALSE(find_surface_contacts(m, m.rest_positions, 0.075).empty());
}

TEST(SurfaceContact, FinderMatchesBruteForce) {
  // Two crumpled cloths (positions jittered by up to 0.15 m) with self- and body contact on:
  // the BVH finder returns exactly the pairs that a loop over all pairs finds, sorted.
  Random rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    Model m = two_cloths();
    m.surface_contact = true;
    m.self_contact = trial % 2 == 0;
    Points x = m.rest_positions;
    for (Eigen::Index i = 0; i < x.rows(); ++i) x.row(i) += 0.15 * rng.vec(-1, 1).transpose();
    if (trial == 4) x(5, 1) = std::nan("");  // a non-finite particle is skipped, not fatal
    for (double margin : {0.0, 0.03}) {
      std::vector<std::pair<int, int>> brute;
      for (int p = 0; p < m.particle_count(); ++p) {
        if (!x.row(p).allFinite()) continue;
        for (int t = 0; t < static_cast<int>(m.triangles.size()); ++t) {
          const auto& tri = m.triangles[static_cast<size_t>(t)];
          if (!x.row(tri[0]).allFinite() || !x.row(tri[1]).allFinite() || !x.row(tri[2]).allFinite())
            continue;
          if (!surface_pair_allowed(m, p, t)) continue;
          const PointTriangle pt = point_triangle(x.row(p).transpose(), x.row(tri[0]).transpose(),
                                                  x.row(tri[1]).transpose(), x.row(tri[2]).transpose());
          if (pt.distance - surface_contact_thickness(m, p, t) < margin) brute.emplace_back(p, t);
        }
      }
      const auto found = find_surface_contacts(m, x, margin);
      EXPECT_EQ(found, brute) << "trial " << trial << ", margin " << margin;
      EXPECT_FALSE(found.empty()) << "trial " << trial;  // the check is not vacuous
    }
  }
}

TEST(SurfaceContact, ContactsFollowTheFlagsAndComeLast) {
  Model m = two_cloths();
  m.planes.push_back(PlaneCollider{});  // y = 0: body 0's particles touch it at margin 0.05
  std::vector<Contact> off = find_contacts(m, m.rest_positions, 0.0, 0.05);
  for (const Contact& c : off) EXPECT_NE(c.kind, ContactKind::Triangle);
  m.surface_contact = true;
  const std::vector<Contact> on = find_contacts(m, m.rest_positions, 0.0, 0.05);
  ASSERT_GT(on.size(), off.size());
  // The same contacts first, then the vertex-triangle ones (the layers are 0.05 m apart: the gap
  // 0.05 - 0.04 = 0.01 m is below the margin).
  for (size_t k = 0; k < off.size(); ++k) {
    EXPECT_EQ(on[k].kind, off[k].kind);
    EXPECT_EQ(on[k].a, off[k].a);
    EXPECT_EQ(on[k].b, off[k].b);
  }
  for (size_t k = off.size(); k < on.size(); ++k) {
    EXPECT_EQ(on[k].kind, ContactKind::Triangle);
    const ConstraintEval e = eval_contact(m, on[k], m.rest_positions, 0.0);
    EXPECT_LT(e.C, 0.05);
  }
  std::array<int, 4> ps{};
  EXPECT_EQ(contact_particles(m, on.back(), ps), 4);
  EXPECT_EQ(ps[0], on.back().a);
}

}  // namespace
}  // namespace pbdbench
