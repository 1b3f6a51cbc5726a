// Tests of core/generators: counts, geometry, rest constraint values, masses, tet orientation and
// conformity, closed surfaces, determinism of the packed spheres, spec validation.
#include "core/generators.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <set>

#include "core/constraint_functions.hpp"
#include "core/state.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers.

int count_group(const Model& m, const std::string& group) {
  int n = 0;
  for (const Constraint& c : m.constraints) n += m.group_names[c.group] == group;
  return n;
}

// Every constraint has C = 0 at the rest positions: exactly for lengths and volumes measured on
// the same geometry (up to round-off relative to the rest value), and for bending.
void expect_satisfied_at_rest(const Model& m) {
  for (size_t i = 0; i < m.constraints.size(); ++i) {
    const Constraint& c = m.constraints[i];
    const double C = eval_constraint(c, m.rest_positions).C;
    EXPECT_TRUE(test::near(C, 0.0, {test::kRoundoff.rel * std::abs(c.rest), 0.0}))
        << "constraint " << i << " (" << to_string(c.kind) << ", group " << m.group_names[c.group] << "): C = " << C;
  }
}

double total_mass(const Model& m, ParticleRange r) {
  double sum = 0.0;
  for (int i = r.begin; i < r.end; ++i) sum += 1.0 / m.inv_mass[static_cast<size_t>(i)];
  return sum;
}

// Enclosed volume of the model's triangles, sum x0 . (x1 x2) / 6: positive when closed and wound
// outward.
double enclosed_volume(const Model& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) {
    const Vec3 a = m.rest_positions.row(t[0]), b = m.rest_positions.row(t[1]), c = m.rest_positions.row(t[2]);
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

// True when every directed edge of the triangles appears once and its reverse once: a closed,
// consistently wound surface.
bool closed_and_consistent(const std::vector<std::array<int, 3>>& triangles) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : triangles)
    for (int e = 0; e < 3; ++e) ++directed[{t[static_cast<size_t>(e)], t[static_cast<size_t>((e + 1) % 3)]}];
  for (const auto& [edge, count] : directed) {
    const auto twin = directed.find({edge.second, edge.first});
    if (count != 1 || twin == directed.end() || twin->second != 1) return false;
  }
  return true;
}

// Message of the std::invalid_argument thrown by f, or "" when none is thrown.
template <typename F>
std::string invalid_argument_message(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// ---------------------------------------------------------------------------------------------
// Cloth.

TEST(Generators, ClothConstraintCounts) {
  for (auto [nx, ny] : {std::pair{2, 2}, {3, 5}, {8, 6}, {17, 4}}) {
    for (BendingModel bending : {BendingModel::Dihedral, BendingModel::Distance}) {
      Model m;
      ClothSpec spec;
      spec.nx = nx;
      spec.ny = ny;
      spec.bending_model = bending;
      const ParticleRange r = add_cloth(m, spec);
      SCOPED_TRACE(testing::Message() << nx << " x " << ny << ", bending " << static_cast<int>(bending));
      EXPECT_EQ(r.begin, 0);
      EXPECT_EQ(r.size(), nx * ny);
      EXPECT_EQ(m.particle_count(), nx * ny);
      EXPECT_EQ(count_group(m, "stretch"), 2 * nx * ny - nx - ny);
      EXPECT_EQ(count_group(m, "shear"), 2 * (nx - 1) * (ny - 1));
      // Dihedral: one per interior edge (horizontal, vertical and cell diagonals); distance: one
      // per pair two apart along a grid line.
      const int dihedral = (nx - 1) * (ny - 2) + (nx - 2) * (ny - 1) + (nx - 1) * (ny - 1);
      const int distance = (nx - 2) * ny + nx * (ny - 2);
      EXPECT_EQ(count_group(m, "bending"), bending == BendingModel::Dihedral ? dihedral : distance);
      EXPECT_EQ(m.triangles.size(), static_cast<size_t>(2 * (nx - 1) * (ny - 1)));
      EXPECT_EQ(m.edges.size(), static_cast<size_t>(2 * nx * ny - nx - ny));
      EXPECT_FALSE(m.surface_closed);
      for (const Constraint& c : m.constraints) {
        if (m.group_names[c.group] == "bending") {
          EXPECT_EQ(c.kind, bending == BendingModel::Dihedral ? ConstraintKind::Bending : ConstraintKind::Distance);
        }
      }
    }
  }
  Model m;
  ClothSpec spec;
  spec.nx = 5;
  spec.ny = 4;
  spec.shear = false;
  spec.bending = false;
  add_cloth(m, spec);
  EXPECT_EQ(m.constraint_count(), 2 * 5 * 4 - 5 - 4);
  EXPECT_EQ(m.group_names, std::vector<std::string>{"stretch"});
}

TEST(Generators, ClothGeometryMassAndWinding) {
  for (const std::string plane : {"xz", "xy"}) {
    Model m;
    ClothSpec spec;
    spec.nx = 5;
    spec.ny = 3;
    spec.width = 2.0;
    spec.height = 0.5;
    spec.origin = Vec3(1, 2, 3);
    spec.plane = plane;
    spec.mass = 3.0;
    spec.radius = 0.02;
    const ParticleRange r = add_cloth(m, spec);
    SCOPED_TRACE(plane);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 5; ++i) {
        const Vec3 expected = plane == "xz" ? Vec3(1 + 0.5 * i, 2, 3 + 0.25 * j) : Vec3(1 + 0.5 * i, 2 - 0.25 * j, 3);
        EXPECT_TRUE(test::near(Vec3(m.rest_positions.row(r.begin + j * 5 + i)), expected, test::kRoundoff))
            << "particle (" << i << ", " << j << ")";
      }
    EXPECT_TRUE(test::near(total_mass(m, r), 3.0, test::kRoundoff));
    for (double w : m.inv_mass) EXPECT_TRUE(test::near(w, 15.0 / 3.0, test::kRoundoff));
    for (double rad : m.radius) EXPECT_EQ(rad, 0.02);
    EXPECT_TRUE(m.attachments.empty());  // the scene builder pins, not the generator
    // All triangles wound the same way: normal +y for "xz", +z for "xy".
    const Vec3 normal = plane == "xz" ? Vec3::UnitY() : Vec3::UnitZ();
    for (const auto& t : m.triangles) {
      const Vec3 a = m.rest_positions.row(t[0]), b = m.rest_positions.row(t[1]), c = m.rest_positions.row(t[2]);
      const Vec3 n = (b - a).cross(c - a);
      EXPECT_TRUE(test::near(n.normalized(), normal, test::kRoundoff));
      EXPECT_TRUE(test::near(n.norm() / 2, 0.5 * 0.25 / 2, test::kRoundoff));
    }
    // The edges are the stretch constraints' pairs.
    std::set<std::pair<int, int>> stretch, edges;
    for (const Constraint& c : m.constraints)
      if (m.group_names[c.group] == "stretch") stretch.insert(std::minmax(c.particles[0], c.particles[1]));
    for (const auto& e : m.edges) edges.insert(std::minmax(e[0], e[1]));
    EXPECT_EQ(stretch, edges);
  }
}

TEST(Generators, ClothConstraintsAreSatisfiedAtRest) {
  for (BendingModel bending : {BendingModel::Dihedral, BendingModel::Distance}) {
    Model m;
    ClothSpec spec;
    spec.nx = 7;
    spec.ny = 9;
    spec.width = 0.7;
    spec.height = 1.3;
    spec.bending_model = bending;
    spec.stretch.compliance = 1e-6;
    spec.shear_params.stiffness = 0.5;
    spec.bending_params.damping = 0.01;
    add_cloth(m, spec);
    expect_satisfied_at_rest(m);
    for (const Constraint& c : m.constraints) {
      const std::string& g = m.group_names[c.group];
      if (c.kind == ConstraintKind::Bending) {
        EXPECT_TRUE(test::near(c.rest, std::numbers::pi, test::kRoundoff));
      }
      // Parameters are copied from the group's spec.
      const ConstraintParams& p = g == "stretch" ? spec.stretch : g == "shear" ? spec.shear_params : spec.bending_params;
      EXPECT_EQ(c.compliance, p.compliance);
      EXPECT_EQ(c.stiffness, p.stiffness);
      EXPECT_EQ(c.damping, p.damping);
    }
  }
}

TEST(Generators, ClothDihedralWingsAreTheOppositeVertices) {
  Model m;
  ClothSpec spec;
  spec.nx = 4;
  spec.ny = 4;
  add_cloth(m, spec);
  for (const Constraint& c : m.constraints) {
    if (c.kind != ConstraintKind::Bending) continue;
    // x0, x1 share two triangles; x2 and x3 lie on opposite sides of the edge in the plane.
    const auto& p = c.particles;
    int shared = 0;
    for (const auto& t : m.triangles) {
      const std::set<int> tri(t.begin(), t.end());
      if (tri.count(p[0]) && tri.count(p[1]) && (tri.count(p[2]) || tri.count(p[3]))) ++shared;
    }
    EXPECT_EQ(shared, 2);
    // Bend the cloth a little about the edge: the constraint becomes valid and C != 0.
    Points x = m.rest_positions;
    x(p[3], 1) += 0.01;
    const ConstraintEval e = eval_constraint(c, x);
    EXPECT_TRUE(e.valid);
    EXPECT_LT(e.C, 0.0);  // a bend makes the angle smaller than pi
  }
}

TEST(Generators, PartsAppendToAnExistingModel) {
  Model m;
  ChainSpec chain;
  chain.links = 3;
  const ParticleRange a = add_chain(m, chain);
  ClothSpec cloth;
  cloth.nx = 3;
  cloth.ny = 3;
  const ParticleRange b = add_cloth(m, cloth);
  EXPECT_EQ(a.begin, 0);
  EXPECT_EQ(a.end, 4);
  EXPECT_EQ(b.begin, 4);
  EXPECT_EQ(b.end, 13);
  EXPECT_EQ(m.particle_count(), 13);
  EXPECT_EQ(m.inv_mass.size(), 13u);
  EXPECT_EQ(m.radius.size(), 13u);
  for (const Constraint& c : m.constraints) {
    const bool in_chain = m.group_names[c.group] == "link";
    for (int k = 0; k < arity(c.kind); ++k) {
      const int p = c.particles[static_cast<size_t>(k)];
      EXPECT_TRUE(in_chain ? (p >= a.begin && p < a.end) : (p >= b.begin && p < b.end));
    }
  }
  for (const auto& t : m.triangles)
    for (int p : t) EXPECT_GE(p, b.begin);
  expect_satisfied_at_rest(m);
}

// ---------------------------------------------------------------------------------------------
// Chain.

TEST(Generators, ChainGeometryPinAndMasses) {
  Model m;
  ChainSpec spec;
  spec.links = 19;
  spec.link_length = 0.01;
  spec.top = Vec3(0, 2, 0);
  spec.direction = Vec3(1, -1, 0).normalized();
  spec.mass = 1.0;
  spec.end_mass = 1e5;
  const ParticleRange r = add_chain(m, spec);
  ASSERT_EQ(r.size(), 20);
  EXPECT_EQ(m.constraint_count(), 19);
  EXPECT_EQ(m.edges.size(), 19u);
  EXPECT_EQ(m.group_names, std::vector<std::string>{"link"});
  for (int k = 0; k < 20; ++k)
    EXPECT_TRUE(test::near(Vec3(m.rest_positions.row(k)), spec.top + 0.01 * k * spec.direction, test::kRoundoff));
  for (int k = 0; k < 19; ++k) {
    const Constraint& c = m.constraints[static_cast<size_t>(k)];
    EXPECT_EQ(c.particles[0], k);
    EXPECT_EQ(c.particles[1], k + 1);
    EXPECT_TRUE(test::near(c.rest, 0.01, test::kRoundoff));
  }
  expect_satisfied_at_rest(m);
  // The top is pinned with a static attachment at its position; the end carries end_mass.
  EXPECT_EQ(m.inv_mass[0], 0.0);
  ASSERT_EQ(m.attachments.size(), 1u);
  EXPECT_EQ(m.attachments[0].particle, 0);
  EXPECT_EQ(m.attachments[0].motion, -1);
  EXPECT_EQ(m.attachments[0].anchor, Vec3(0, 2, 0));
  for (int k = 1; k < 19; ++k) EXPECT_EQ(m.inv_mass[static_cast<size_t>(k)], 1.0);
  EXPECT_TRUE(test::near(m.inv_mass[19], 1e-5, test::kRoundoff));
  // The rest state keeps the pinned particle where it is.
  EXPECT_EQ(Vec3(rest_state(m).x.row(0)), Vec3(0, 2, 0));

  // A pendulum: one link, not pinned, end mass 0 means "same as mass".
  Model p;
  ChainSpec pendulum;
  pendulum.links = 1;
  pendulum.link_length = 2.0;
  pendulum.pin_top = false;
  pendulum.mass = 0.5;
  add_chain(p, pendulum);
  EXPECT_EQ(p.particle_count(), 2);
  EXPECT_TRUE(p.attachments.empty());
  EXPECT_EQ(p.inv_mass, (std::vector<double>{2.0, 2.0}));
  EXPECT_TRUE(test::near(Vec3(p.rest_positions.row(1)), Vec3(0, -2, 0), test::kRoundoff));
}

// ---------------------------------------------------------------------------------------------
// Tet block.

struct BlockCase {
  std::array<int, 3> cells;
  int tets_per_cell;
};

TEST(Generators, TetBlockIsPositiveConformingAndClosed) {
  for (const BlockCase bc : {BlockCase{{1, 1, 1}, 6}, {{1, 1, 1}, 5}, {{3, 2, 2}, 6}, {{3, 2, 2}, 5},
                             {{4, 3, 5}, 5}, {{8, 2, 2}, 6}}) {
    const auto [cx, cy, cz] = bc.cells;
    SCOPED_TRACE(testing::Message() << cx << " x " << cy << " x " << cz << ", " << bc.tets_per_cell << " tets per cell");
    Model m;
    TetBlockSpec spec;
    spec.cells = bc.cells;
    spec.tets_per_cell = bc.tets_per_cell;
    spec.size = Vec3(1.0, 0.3, 0.7);
    spec.origin = Vec3(-0.5, 1.0, 0.25);
    spec.density = 500.0;
    const ParticleRange r = add_tet_block(m, spec);
    const double box_volume = 1.0 * 0.3 * 0.7;

    EXPECT_EQ(r.size(), (cx + 1) * (cy + 1) * (cz + 1));
    ASSERT_EQ(m.tets.size(), static_cast<size_t>(cx * cy * cz * bc.tets_per_cell));
    double volume = 0.0;
    for (const auto& t : m.tets) {
      const double v = tet_signed_volume(m.rest_positions.row(t[0]), m.rest_positions.row(t[1]),
                                         m.rest_positions.row(t[2]), m.rest_positions.row(t[3]));
      EXPECT_GT(v, 0.0);
      volume += v;
    }
    EXPECT_TRUE(test::near(volume, box_volume, test::kRoundoff));
    // Particles span the box.
    EXPECT_TRUE(test::near(Vec3(m.rest_positions.colwise().minCoeff()), spec.origin, test::kRoundoff));
    EXPECT_TRUE(test::near(Vec3(m.rest_positions.colwise().maxCoeff()), spec.origin + spec.size, test::kRoundoff));

    // Conforming: every tet face is shared by two tets except the boundary faces, and there are
    // exactly as many of those as the box's faces hold (two triangles per boundary square). A
    // non-conforming split would leave unmatched interior faces.
    std::map<std::array<int, 3>, int> faces;
    for (const auto& t : m.tets)
      for (int skip = 0; skip < 4; ++skip) {
        std::array<int, 3> f{};
        int k = 0;
        for (int v = 0; v < 4; ++v)
          if (v != skip) f[static_cast<size_t>(k++)] = t[static_cast<size_t>(v)];
        std::sort(f.begin(), f.end());
        ++faces[f];
      }
    const int boundary_squares = 2 * (cx * cy + cy * cz + cx * cz);
    int single = 0;
    for (const auto& [f, count] : faces) {
      EXPECT_LE(count, 2);
      single += count == 1;
    }
    EXPECT_EQ(single, 2 * boundary_squares);
    EXPECT_EQ(m.triangles.size(), static_cast<size_t>(2 * boundary_squares));
    EXPECT_TRUE(m.surface_closed);
    EXPECT_TRUE(closed_and_consistent(m.triangles));
    // Wound outward: the enclosed volume is the box's (and positive).
    EXPECT_TRUE(test::near(enclosed_volume(m), box_volume, test::kRoundoff));

    // Unique tet edges: the grid's axis edges, one diagonal per cell face, and (6 tets) the cell's
    // main diagonal.
    const int vx = cx + 1, vy = cy + 1, vz = cz + 1;
    const int axis = cx * vy * vz + vx * cy * vz + vx * vy * cz;
    const int face_diagonals = cx * cy * vz + cx * vy * cz + vx * cy * cz;
    const int expected_edges = axis + face_diagonals + (bc.tets_per_cell == 6 ? cx * cy * cz : 0);
    EXPECT_EQ(m.edges.size(), static_cast<size_t>(expected_edges));
    EXPECT_EQ(count_group(m, "edge"), expected_edges);
    EXPECT_EQ(count_group(m, "volume"), static_cast<int>(m.tets.size()));

    // Mass: density times volume, every particle with some.
    EXPECT_TRUE(test::near(total_mass(m, r), 500.0 * box_volume, test::kRoundoff));
    for (double w : m.inv_mass) EXPECT_GT(w, 0.0);
    expect_satisfied_at_rest(m);
  }
}

TEST(Generators, TetBlockOptionsAndSurfaceClosedMerging) {
  TetBlockSpec spec;
  spec.cells = {2, 1, 1};
  spec.edges = false;
  Model only_volumes;
  add_tet_block(only_volumes, spec);
  EXPECT_EQ(count_group(only_volumes, "edge"), 0);
  EXPECT_EQ(only_volumes.constraint_count(), 12);
  EXPECT_FALSE(only_volumes.edges.empty());  // the topology keeps its edges

  // Two closed blocks: still closed. A cloth and a block: not closed (the cloth has a border).
  Model two;
  add_tet_block(two, spec);
  spec.origin = Vec3(5, 0, 0);
  add_tet_block(two, spec);
  EXPECT_TRUE(two.surface_closed);
  EXPECT_TRUE(closed_and_consistent(two.triangles));
  Model mixed;
  ClothSpec cloth;
  cloth.nx = 3;
  cloth.ny = 3;
  add_cloth(mixed, cloth);
  add_tet_block(mixed, spec);
  EXPECT_FALSE(mixed.surface_closed);
  Model mixed2;
  add_tet_block(mixed2, spec);
  add_cloth(mixed2, cloth);
  EXPECT_FALSE(mixed2.surface_closed);
}

TEST(Generators, TriBlockGeometryMassWindingAndEdges) {
  TriBlockSpec spec;
  spec.cells = {4, 2};
  spec.size = {1.0, 0.5};
  spec.origin = Vec3(0.0, 1.0, 0.0);
  spec.density = 100.0;
  spec.thickness = 0.2;
  spec.edges = true;
  spec.edge = ConstraintParams{1e-6, 1.0, 0.0};
  Model m;
  const ParticleRange r = add_tri_block(m, spec);
  EXPECT_EQ(r.size(), 5 * 3);
  ASSERT_EQ(m.triangles.size(), 16u);
  // Vertex (i, j) at origin + (i w / cx, j h / cy, 0).
  EXPECT_TRUE(test::near(Vec3(m.rest_positions.row(r.begin + 4 + 5 * 2)), Vec3(1.0, 1.5, 0.0), test::kRoundoff));
  // Counter-clockwise seen from +z, none degenerate; the area sums to w h.
  double area = 0.0;
  for (const auto& t : m.triangles) {
    const Vec3 n = Vec3(m.rest_positions.row(t[1]) - m.rest_positions.row(t[0]))
                       .cross(Vec3(m.rest_positions.row(t[2]) - m.rest_positions.row(t[0])));
    EXPECT_GT(n.z(), 0.0);
    area += 0.5 * n.norm();
  }
  EXPECT_TRUE(test::near(area, 0.5, test::kRoundoff));
  // Mass: density x thickness x area.
  double mass = 0.0;
  for (double w : m.inv_mass) mass += 1.0 / w;
  EXPECT_TRUE(test::near(mass, 100.0 * 0.2 * 0.5, test::kRoundoff));
  // Unique edges: 4 x 3 horizontal + 5 x 2 vertical + 8 diagonals = 30, each a satisfied
  // distance constraint.
  EXPECT_EQ(m.edges.size(), 30u);
  EXPECT_EQ(count_group(m, "edge"), 30);
  for (const Constraint& c : m.constraints) EXPECT_LE(std::abs(eval_constraint(c, m.rest_positions).C), 1e-15);
  // The diagonals alternate: cell (0, 0) is split along (0,0)-(1,1), cell (1, 0) along (2,0)-(1,1).
  std::set<std::pair<int, int>> edges;
  for (const auto& e : m.edges) edges.insert({e[0], e[1]});
  EXPECT_TRUE(edges.count({0, 6}));
  EXPECT_TRUE(edges.count({2, 6}));
  EXPECT_FALSE(edges.count({1, 5}));
  TriBlockSpec bad;
  bad.cells = {0, 1};
  EXPECT_THROW(add_tri_block(m, bad), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Packed spheres.

TEST(Generators, PackedSpheresAreDeterministicAndDoNotOverlap) {
  PackedSpheresSpec spec;
  spec.count = {4, 3, 5};
  spec.radius = 0.05;
  spec.gap = 0.1;
  spec.jitter = 0.004;  // below radius * gap = 0.005
  spec.origin = Vec3(0, 1, 0);
  spec.seed = 7;
  Model a, b, c;
  const ParticleRange r = add_packed_spheres(a, spec);
  add_packed_spheres(b, spec);
  spec.seed = 8;
  add_packed_spheres(c, spec);
  ASSERT_EQ(r.size(), 60);
  // Bitwise equal for the same seed (a determinism test: == on purpose), different otherwise.
  EXPECT_TRUE(a.rest_positions == b.rest_positions);
  EXPECT_FALSE(a.rest_positions == c.rest_positions);
  EXPECT_TRUE(a.constraints.empty());
  const double spacing = 2 * 0.05 * 1.1;
  double min_distance = 1e300;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i) {
        const int p = i + 4 * (j + 3 * k);
        const Vec3 lattice = spec.origin + spacing * Vec3(i, j, k);
        const Vec3 d = Vec3(a.rest_positions.row(p)) - lattice;
        EXPECT_LE(d.cwiseAbs().maxCoeff(), spec.jitter) << "sphere " << p;
      }
  for (int p = 0; p < 60; ++p)
    for (int q = p + 1; q < 60; ++q) min_distance = std::min(min_distance, (a.rest_positions.row(p) - a.rest_positions.row(q)).norm());
  EXPECT_GT(min_distance, 2 * spec.radius);
  for (double w : a.inv_mass) EXPECT_TRUE(test::near(w, 10.0, test::kRoundoff));

  // The jitter is the documented mapping of the seeded 64-bit generator: first sphere, first axis.
  std::mt19937_64 rng(8);
  const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  EXPECT_EQ(c.rest_positions(0, 0), spec.origin.x() + spec.jitter * (2.0 * u - 1.0));

  // No jitter: exactly the lattice.
  spec.jitter = 0.0;
  Model d;
  add_packed_spheres(d, spec);
  EXPECT_TRUE(test::near(Vec3(d.rest_positions.row(59)), spec.origin + spacing * Vec3(3, 2, 4), test::kRoundoff));
}

TEST(Generators, RingSpheresLieOnTheirCircle) {
  // Three spheres on a circle of radius R normal to `up`: each R from the origin, in the plane,
  // 120 degrees apart (centre distance sqrt(3) R), the first along the projection of +x.
  PackedSpheresSpec spec;
  spec.layout = SpheresLayout::Ring;
  spec.count = {3, 1, 1};
  spec.radius = 0.05;
  spec.ring_radius = 1.6 * 0.05 / std::sqrt(3.0);
  spec.origin = Vec3(0.2, 0.5, -0.1);
  for (const Vec3& up : {Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(1, 2, 3)}) {
    spec.up = up;
    Model m;
    ASSERT_EQ(add_packed_spheres(m, spec).size(), 3);
    const Vec3 u = up.normalized();
    for (int k = 0; k < 3; ++k) {
      const Vec3 r = Vec3(m.rest_positions.row(k)) - spec.origin;
      EXPECT_TRUE(test::near(r.norm(), spec.ring_radius, test::kRoundoff)) << k;
      EXPECT_TRUE(test::near(r.dot(u), 0.0, test::kRoundoff)) << k;
      const Vec3 next = Vec3(m.rest_positions.row((k + 1) % 3)) - spec.origin;
      EXPECT_TRUE(test::near((r - next).norm(), 1.6 * spec.radius, test::kRoundoff)) << k;  // overlapping
    }
    if (u.x() < 0.9) {  // the first sphere towards +x
      const Vec3 r0 = Vec3(m.rest_positions.row(0)) - spec.origin;
      Vec3 e1 = Vec3::UnitX() - u.x() * u;
      EXPECT_TRUE(test::near(r0, spec.ring_radius * e1.normalized(), test::kRoundoff));
    }
  }
  // Jitter: at most `jitter` per axis off the circle's points, deterministic in the seed.
  spec.up = Vec3::UnitY();
  Model exact, a, b, c;
  add_packed_spheres(exact, spec);
  spec.jitter = 0.005;
  spec.seed = 3;
  add_packed_spheres(a, spec);
  add_packed_spheres(b, spec);
  spec.seed = 4;
  add_packed_spheres(c, spec);
  EXPECT_TRUE(a.rest_positions == b.rest_positions);  // determinism: == on purpose
  EXPECT_FALSE(a.rest_positions == c.rest_positions);
  EXPECT_LE((a.rest_positions - exact.rest_positions).cwiseAbs().maxCoeff(), 0.005);
  EXPECT_GT((a.rest_positions - exact.rest_positions).cwiseAbs().maxCoeff(), 0.0);
  // count[1], count[2] other than 1, a ring radius <= 0 or a zero axis are refused.
  Model m;
  spec.count = {3, 2, 1};
  EXPECT_THROW(add_packed_spheres(m, spec), std::invalid_argument);
  spec.count = {3, 1, 1};
  spec.ring_radius = 0.0;
  EXPECT_THROW(add_packed_spheres(m, spec), std::invalid_argument);
  spec.ring_radius = 0.1;
  spec.up = Vec3::Zero();
  EXPECT_THROW(add_packed_spheres(m, spec), std::invalid_argument);
  EXPECT_EQ(m.particle_count(), 0);
}

// ---------------------------------------------------------------------------------------------
// Spec validation.

TEST(Generators, InvalidSpecsNameTheFieldAndTheBound) {
  Model m;
  ClothSpec cloth;
  cloth.nx = 1;
  EXPECT_EQ(invalid_argument_message([&] { add_cloth(m, cloth); }), "ClothSpec.nx = 1 is below the minimum 2");
  cloth = {};
  cloth.plane = "yz";
  EXPECT_NE(invalid_argument_message([&] { add_cloth(m, cloth); }).find("ClothSpec.plane"), std::string::npos);
  cloth = {};
  cloth.width = -1;
  EXPECT_NE(invalid_argument_message([&] { add_cloth(m, cloth); }).find("ClothSpec.width = -1"), std::string::npos);
  cloth = {};
  cloth.stretch.stiffness = 1.5;
  EXPECT_EQ(invalid_argument_message([&] { add_cloth(m, cloth); }), "ClothSpec.stretch.stiffness = 1.5 is outside [0, 1]");
  cloth = {};
  cloth.bending_params.compliance = -1e-3;
  EXPECT_NE(invalid_argument_message([&] { add_cloth(m, cloth); }).find("ClothSpec.bending_params.compliance"),
            std::string::npos);

  ChainSpec chain;
  chain.links = 0;
  EXPECT_EQ(invalid_argument_message([&] { add_chain(m, chain); }), "ChainSpec.links = 0 is below the minimum 1");
  chain = {};
  chain.direction = Vec3(0, -2, 0);
  EXPECT_NE(invalid_argument_message([&] { add_chain(m, chain); }).find("ChainSpec.direction"), std::string::npos);
  chain = {};
  chain.mass = 0;
  EXPECT_NE(invalid_argument_message([&] { add_chain(m, chain); }).find("ChainSpec.mass = 0 must be finite and above 0"),
            std::string::npos);
  chain = {};
  chain.link.damping = -1;
  EXPECT_NE(invalid_argument_message([&] { add_chain(m, chain); }).find("ChainSpec.link.damping"), std::string::npos);

  TetBlockSpec block;
  block.cells = {2, 0, 2};
  EXPECT_EQ(invalid_argument_message([&] { add_tet_block(m, block); }), "TetBlockSpec.cells[1] = 0 is below the minimum 1");
  block = {};
  block.tets_per_cell = 4;
  EXPECT_NE(invalid_argument_message([&] { add_tet_block(m, block); }).find("TetBlockSpec.tets_per_cell = 4"),
            std::string::npos);
  block = {};
  block.density = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(invalid_argument_message([&] { add_tet_block(m, block); }).find("TetBlockSpec.density"), std::string::npos);

  PackedSpheresSpec spheres;
  spheres.radius = 0.05;
  spheres.gap = 0.1;
  spheres.jitter = 0.0051;  // above radius * gap = 0.005: neighbours could overlap
  EXPECT_NE(invalid_argument_message([&] { add_packed_spheres(m, spheres); }).find("PackedSpheresSpec.jitter"),
            std::string::npos);
  spheres = {};
  spheres.count = {0, 1, 1};
  EXPECT_NE(invalid_argument_message([&] { add_packed_spheres(m, spheres); }).find("PackedSpheresSpec.count[0]"),
            std::string::npos);

  EXPECT_NE(invalid_argument_message([&] { add_particle(m, Vec3::Zero(), -1.0, 0.1); }).find("mass"), std::string::npos);
  // Nothing was added by the failed calls.
  EXPECT_EQ(m.particle_count(), 0);
  EXPECT_TRUE(m.constraints.empty());
  EXPECT_EQ(add_particle(m, Vec3(1, 2, 3), 2.0, 0.1), 0);
  EXPECT_EQ(m.inv_mass, std::vector<double>{0.5});
}

}  // namespace
}  // namespace pbdbench
