// Tests of core/surface_contact: the point-triangle and segment-segment distances on closed
// forms, the pair rules (bodies, self-contact, neighbours, tet bodies), the BVH-based finders
// (vertex-triangle, edge-edge) against brute force, and the cached (refit) broad phase against
// a fresh one. The gradients of both contacts against central differences are in
// test_contacts.cpp (they are eval_contact's).
#include "core/surface_contact.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <new>
#include <set>
#include <string>
#include <utility>

#include <sys/resource.h>
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

// A 64 x 64 self-contact cloth of side 1 m whose radius (1 m) spans the whole cloth: every edge
// within the thickness of every other, 12,097 edges, 73 million edge pairs (1.2 GB as pairs,
// 1.5 GB more as contacts): the searches stop at contact_pair_limit with their message.
Model swollen_cloth(int n) {
  Model m;
  add_cloth(m, square_cloth(n, 1.0, 1.0));
  m.self_contact = true;
  return m;
}

TEST(SurfaceContact, SearchesStopAtThePairLimit) {
  const Model m = swollen_cloth(32);
  try {
    find_edge_contacts(m, m.rest_positions, 0.0);
    ADD_FAILURE() << "no ContactPairLimit from the edge-edge search";
  } catch (const ContactPairLimit& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("edge-edge contacts: more than " + std::to_string(contact_pair_limit(surface_edges(m).size()))),
              std::string::npos) << what;
  }
  EXPECT_THROW(find_surface_contacts(m, m.rest_positions, 0.0), ContactPairLimit);
  EXPECT_THROW(find_contacts(m, m.rest_positions, 0.0, 0.0), ContactPairLimit);
  // Below the limit, more than kMaxPairsPerElement pairs an element are found: a 16 x 16 cloth,
  // 705 edges and 240,000 pairs, within the slack (kPairSlack) that small scenes always have.
  const Model small = swollen_cloth(16);
  EXPECT_GT(find_edge_contacts(small, small.rest_positions, 0.0).size(), kMaxPairsPerElement * surface_edges(small).size());
}

// The same search on the 64 x 64 cloth in a child whose address space is capped at 1 GB: the
// limit (exit 0), not std::bad_alloc (exit 3; what it was without the limit, at 5 GB).
[[noreturn]] void search_under_a_memory_cap() {
  const rlimit cap{1L << 30, 1L << 30};
  setrlimit(RLIMIT_AS, &cap);
  const Model m = swollen_cloth(64);
  try {
    find_contacts(m, m.rest_positions, 0.0, 0.0);
  } catch (const ContactPairLimit&) {
    std::_Exit(0);
  } catch (const std::bad_alloc&) {
    std::_Exit(3);
  }
  std::_Exit(4);
}

TEST(SurfaceContact, PairLimitKeepsTheSearchUnderAMemoryCap) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(search_under_a_memory_cap(), ::testing::ExitedWithCode(0), "");
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

TEST(SurfaceContact, SegmentSegmentClosedForms) {
  // Crossing skew segments: x axis at height 0 from -1 to 1, z direction at height 0.2 through
  // x = 0.5.
  SegmentSegment ss = segment_segment(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0.2, -1), Vec3(0.5, 0.2, 3));
  EXPECT_NEAR(ss.distance, 0.2, 1e-15);
  EXPECT_NEAR(ss.s, 0.75, 1e-15);
  EXPECT_NEAR(ss.t, 0.25, 1e-15);
  EXPECT_LT((ss.normal + Vec3::UnitY()).norm(), 1e-15);
  // The second beyond the first's end: s clamped to 1.
  ss = segment_segment(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(2, 0.2, -1), Vec3(2, 0.2, 1));
  EXPECT_EQ(ss.s, 1.0);
  EXPECT_NEAR(ss.t, 0.5, 1e-15);
  EXPECT_NEAR(ss.distance, std::sqrt(1.0 + 0.04), 1e-15);
  // Parallel at distance 0.3, overlapping: the distance is right whatever the points chosen.
  ss = segment_segment(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0.3, 0), Vec3(2, 0.3, 0));
  EXPECT_NEAR(ss.distance, 0.3, 1e-15);
  // A point (zero length) against a segment; two points.
  ss = segment_segment(Vec3(0.5, 1, 0), Vec3(0.5, 1, 0), Vec3(0, 0, 0), Vec3(1, 0, 0));
  EXPECT_NEAR(ss.distance, 1.0, 1e-15);
  EXPECT_NEAR(ss.t, 0.5, 1e-15);
  ss = segment_segment(Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 2), Vec3(0, 0, 2));
  EXPECT_NEAR(ss.distance, 2.0, 1e-15);
  // Intersecting: distance 0, the normal the unit cross product of the directions.
  ss = segment_segment(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, -1), Vec3(0, 0, 1));
  EXPECT_EQ(ss.distance, 0.0);
  EXPECT_LT((ss.normal.cwiseAbs() - Vec3::UnitY()).norm(), 1e-15);
  // Against dense sampling of both segments: nothing closer.
  Random rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 a = rng.vec(-1, 1), b = rng.vec(-1, 1), c = rng.vec(-1, 1), d = rng.vec(-1, 1);
    ss = segment_segment(a, b, c, d);
    EXPECT_NEAR(((a + ss.s * (b - a)) - (c + ss.t * (d - c))).norm(), ss.distance, 1e-14);
    double best = 1e300;
    for (int i = 0; i <= 100; ++i)
      for (int j = 0; j <= 100; ++j)
        best = std::min(best, ((a + 0.01 * i * (b - a)) - (c + 0.01 * j * (d - c))).norm());
    EXPECT_LE(ss.distance, best + 1e-14) << trial;
  }
}

TEST(SurfaceContact, EdgeRulesAndEdges) {
  Model m = two_cloths();
  const auto edges = surface_edges(m);
  // A 6 x 6 cloth of 50 triangles: 5 x 6 rows, 6 x 5 columns, 25 diagonals = 85 edges; two.
  EXPECT_EQ(edges.size(), 170u);
  EXPECT_TRUE(std::is_sorted(edges.begin(), edges.end()));
  const std::array<int, 2> e0{0, 1}, far{28, 29}, ring{6, 7}, shared{1, 2}, other{36, 37};
  EXPECT_FALSE(edge_pair_allowed(m, e0, other));  // both switches off
  m.surface_contact = true;
  EXPECT_TRUE(edge_pair_allowed(m, e0, other));
  EXPECT_FALSE(edge_pair_allowed(m, e0, far));  // within a body: self-contact off
  m.self_contact = true;
  EXPECT_TRUE(edge_pair_allowed(m, e0, far));
  EXPECT_FALSE(edge_pair_allowed(m, e0, shared));  // a shared vertex
  EXPECT_FALSE(edge_pair_allowed(m, e0, ring));    // neighbours (6 and 7 share triangles with 0)
  for (int p = 36; p < 72; ++p) m.inv_mass[static_cast<size_t>(p)] = 0.0;
  for (int p = 0; p < 2; ++p) m.inv_mass[static_cast<size_t>(p)] = 0.0;
  EXPECT_FALSE(edge_pair_allowed(m, e0, other));  // all four pinned
}

TEST(SurfaceContact, EdgeFinderMatchesBruteForce) {
  Random rng(17);
  for (int trial = 0; trial < 5; ++trial) {
    Model m = two_cloths();
    m.surface_contact = true;
    m.self_contact = trial % 2 == 0;
    Points x = m.rest_positions;
    for (Eigen::Index i = 0; i < x.rows(); ++i) x.row(i) += 0.15 * rng.vec(-1, 1).transpose();
    if (trial == 4) x(5, 1) = std::nan("");
    const auto edges = surface_edges(m);
    for (double margin : {0.0, 0.03}) {
      std::vector<std::array<int, 4>> brute;
      for (size_t i = 0; i < edges.size(); ++i)
        for (size_t j = i + 1; j < edges.size(); ++j) {
          const auto &e = edges[i], &f = edges[j];
          const std::array<int, 4> ps{e[0], e[1], f[0], f[1]};
          bool finite = true;
          for (int p : ps) finite = finite && x.row(p).allFinite();
          if (!finite || !edge_pair_allowed(m, e, f)) continue;
          const SegmentSegment ss = segment_segment(x.row(e[0]).transpose(), x.row(e[1]).transpose(),
                                                    x.row(f[0]).transpose(), x.row(f[1]).transpose());
          if (ss.distance - edge_contact_thickness(m, ps) < margin) brute.push_back(ps);
        }
      const auto found = find_edge_contacts(m, x, margin);
      EXPECT_EQ(found, brute) << "trial " << trial << ", margin " << margin;
      EXPECT_FALSE(found.empty()) << "trial " << trial;
      SurfaceContactCache cache;
      EXPECT_EQ(find_edge_contacts(m, x, margin, &cache), brute);
    }
  }
}

TEST(SurfaceContact, CachedBroadPhaseFindsTheSameContacts) {
  // Two cloths moved over 30 calls (a drift and a growing jitter, as substeps would move them):
  // with a cache (refit, or rebuilt by its rule) the finder returns exactly what a BVH built anew
  // returns; both refits and rebuilds happen; a non-finite position falls back and then rebuilds;
  // another model's triangles are not served from the cache.
  Random rng(3);
  Model m = two_cloths();
  m.surface_contact = true;
  m.self_contact = true;
  SurfaceContactCache cache;
  Points x = m.rest_positions;
  long compared = 0;
  for (int call = 0; call < 30; ++call) {
    for (Eigen::Index i = 0; i < x.rows(); ++i)
      x.row(i) += (0.005 * call) * rng.vec(-1, 1).transpose() + Vec3(0.0, -0.002, 0.0).transpose();
    Points y = x;
    if (call == 20) y(3, 0) = std::nan("");
    const auto fresh = find_surface_contacts(m, y, 0.02);
    EXPECT_EQ(find_surface_contacts(m, y, 0.02, &cache), fresh) << "call " << call;
    const auto fresh_edges = find_edge_contacts(m, y, 0.02);
    EXPECT_EQ(find_edge_contacts(m, y, 0.02, &cache), fresh_edges) << "call " << call;
    compared += static_cast<long>(fresh.size() + fresh_edges.size());
  }
  EXPECT_GT(compared, 0);
  EXPECT_GT(cache.refits(), 0);
  // Two trees (triangles, edges): each built first, after the non-finite call, and by the area
  // rule at least once.
  std::printf("builds %ld, refits %ld\n", cache.builds(), cache.refits());
  EXPECT_GE(cache.builds(), 6);
  Model other = m;
  other.triangles.pop_back();
  const long builds = cache.builds();
  EXPECT_EQ(find_surface_contacts(other, x, 0.02, &cache), find_surface_contacts(other, x, 0.02));
  EXPECT_EQ(cache.builds(), builds + 1);
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
  // Vertex-triangle contacts, then edge-edge ones (the layers' parallel edges, 0.05 m apart).
  size_t edges = 0;
  for (size_t k = off.size(); k < on.size(); ++k) {
    if (on[k].kind == ContactKind::Edge) ++edges;
    else EXPECT_EQ(edges, 0u) << "a vertex-triangle contact after an edge-edge one";
    EXPECT_TRUE(on[k].kind == ContactKind::Triangle || on[k].kind == ContactKind::Edge);
    const ConstraintEval e = eval_contact(m, on[k], m.rest_positions, 0.0);
    EXPECT_LT(e.C, 0.05);
  }
  EXPECT_GT(edges, 0u);
  EXPECT_EQ(on[off.size()].kind, ContactKind::Triangle);
  std::array<int, 4> ps{};
  EXPECT_EQ(contact_particles(m, on[off.size()], ps), 4);
  EXPECT_EQ(ps[0], on[off.size()].a);
  m.edge_contact = false;  // vertex-triangle alone
  const std::vector<Contact> alone = find_contacts(m, m.rest_positions, 0.0, 0.05);
  EXPECT_EQ(alone.size(), on.size() - edges);
}

}  // namespace
}  // namespace pbdbench
