// Vertex–triangle contact (core/surface_contact.hpp: scene.surface_contact between bodies,
// scene.self_contact within a cloth) in the PBD families, pbd and xpbd, on the catalog scenes
// and on scenes built to fail without it; ref-be refuses it (test_ref_contact.cpp).
//
// The rules, written before the runs (two setups were changed after a first run, not the
// rules' tolerances: the folded cloth lost its bending constraints, which turned the upper half
// over the fold and under the lower one, a motion around the edge that the crossing count
// cannot tell from a crossing; the stack's friction between the cubes was set to 0.5, without
// which they slid off each other, which the stacking check, first written on the centres'
// heights, caught; that check now asks that each cube be wholly above the one below):
// - The draped cloth (catalog cloth_over_block, 1 s): at every step every cloth vertex is outside
//   the block's surface, its signed distance to the block's boundary triangles >= 0 (the contact
//   holds it at the thickness 3.7 cm; the tolerance is that whole thickness), and at the end the
//   cloth lies on the block (its centre above the block's top) and hangs over its sides (its
//   lowest vertex more than 0.1 m below the block's top).
// - A cloth dropped on a sparse block (vertices 15 cm apart, radius 5 mm, so that particle
//   contact alone cannot stop it) stays above the block's top face with the contact, every gap
//   above minus half the thickness (1 cm); without it (the control) it falls through. In every
//   projection order (pbd's Jacobi sweeps included: see the test), no cloth particle is below
//   the top face at any step.
// - A folded cloth (the lower half a trampoline pinned at its border, the upper half 2 cm above
//   it, released): with self-contact no vertex of the upper half crosses the lower half (the
//   count of crossings, by the sign of its height over the lower layer, is 0); without it (the
//   control) most of them cross.
// - Edge through edge (what edge-edge contact is for): a triangle falling edge first
//   across a pinned triangle's top edge, their edges crossing at right angles, no vertex ever
//   within 0.3 m of the other's triangle. With edge-edge contact, between bodies and (the two
//   triangles one cloth body) with self-contact, the falling edge stays above the pinned one at
//   every step (its midpoint at least the thickness 1 cm above, less half of it, 5 mm; every
//   edge-edge gap above -5 mm); with vertex-triangle contact alone (the control,
//   Model::edge_contact off) it passes through (its midpoint 5 cm below the edge at some step).
// - A cloth folding onto itself over a thin pole (catalog cloth_on_pole, 1.5 s; rule written
//   before its first run): with self-contact (as catalogued) no cloth edge passes through a cloth
//   triangle at any step (the count of such crossings, edges through triangles that share no
//   vertex with them, is 0); without it (the control) the halves swinging under the pole pass
//   through each other (more than 10 crossings at some step).
// - The stack of soft cubes (catalog soft_cube_stack, 1.5 s), as catalogued and with
//   vertex-triangle contact alone (particle contact switched off): no vertex of a cube enters
//   another cube (signed distance to its surface >= 0) at any step, and at the end each cube is
//   wholly above the one below; with neither contact (the control) they interpenetrate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "core/bvh.hpp"
#include "core/contacts.hpp"
#include "core/generators.hpp"
#include "core/mesh_collider.hpp"
#include "core/surface_contact.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {
namespace {

const char* const kSolvers[] = {"pbd", "xpbd"};

// The closed surface of the particles [begin, end) (its triangles, renumbered) at positions x: a
// mesh collider, for its signed distance.
MeshCollider body_surface(const Model& m, const Points& x, int begin, int end) {
  std::vector<std::array<int, 3>> tris;
  for (const auto& t : m.triangles)
    if (t[0] >= begin && t[0] < end) tris.push_back({t[0] - begin, t[1] - begin, t[2] - begin});
  return make_mesh_collider(x.middleRows(begin, end - begin), std::move(tris));
}

// The smallest signed distance of the particles [begin, end) to the surface, m.
double min_signed_distance(const MeshCollider& surface, const Points& x, int begin, int end) {
  double d = 1e300;
  for (int p = begin; p < end; ++p) d = std::min(d, mesh_distance(surface, x.row(p).transpose()).distance);
  return d;
}

// The smallest vertex-triangle gap over the pairs the contact considers, m (1e300 for none).
double min_surface_gap(const Model& m, const Points& x) {
  double d = 1e300;
  for (const auto& [p, t] : find_surface_contacts(m, x, 1.0)) {
    const auto& tri = m.triangles[static_cast<size_t>(t)];
    const PointTriangle pt = point_triangle(x.row(p).transpose(), x.row(tri[0]).transpose(),
                                            x.row(tri[1]).transpose(), x.row(tri[2]).transpose());
    d = std::min(d, pt.distance - surface_contact_thickness(m, p, t));
  }
  return d;
}

TEST(SurfaceContact, DrapedClothStaysOutsideTheBlock) {
  for (const char* name : kSolvers) {
    const config::Config cfg = config::load("cloth_over_block", {{"solver.name", name}});
    const Scene sc = config::build_scene(cfg);
    const Model& m = sc.model;
    ASSERT_TRUE(m.surface_contact);
    const int cloth = 24 * 24, n = m.particle_count();
    ASSERT_EQ(m.particle_body[cloth - 1], 0);
    ASSERT_EQ(m.particle_body[cloth], 1);
    auto solver = make_solver(config::solver_options(cfg), m);
    const double dt = config::run_options(cfg).dt;
    State s = sc.initial;
    double worst = 1e300;
    for (int k = 0; k < 60; ++k) {  // 1 s
      solver->step(m, s, dt);
      const MeshCollider block = body_surface(m, s.x, cloth, n);
      worst = std::min(worst, min_signed_distance(block, s.x, 0, cloth));
    }
    double top = -1e300, centre = 1e300, lowest = 1e300;
    for (int p = cloth; p < n; ++p) top = std::max(top, s.x(p, 1));
    for (int p = 0; p < cloth; ++p) {
      lowest = std::min(lowest, s.x(p, 1));
      if (std::abs(s.x(p, 0)) < 0.05 && std::abs(s.x(p, 2)) < 0.05) centre = std::min(centre, s.x(p, 1));
    }
    std::printf("%s: smallest signed distance of a cloth vertex to the block %.4f m; block top "
                "%.4f m, cloth centre %.4f m, lowest cloth vertex %.4f m\n",
                name, worst, top, centre, lowest);
    EXPECT_GE(worst, 0.0) << name;
    EXPECT_GT(centre, top) << name;
    EXPECT_LT(lowest, top - 0.1) << name;  // it hangs over the sides
  }
}

// A soft tet block (0.3 m cube, 2 x 2 x 2 cells: vertices 0.15 m apart, radius 5 mm) on the
// ground, and a 10 x 10 cloth (0.5 m, particles 5.6 cm apart, radius 5 mm) 2 cm above it.
Model cloth_on_sparse_block(bool surface) {
  Model m;
  TetBlockSpec b;
  b.cells = {2, 2, 2};
  b.size = Vec3(0.3, 0.3, 0.3);
  b.origin = Vec3(-0.15, 0.0055, -0.15);
  b.density = 200.0;
  b.radius = 0.005;
  b.edge.compliance = 1e-5;
  b.volume.compliance = 1e-7;
  add_tet_block(m, b);
  ClothSpec c;
  c.nx = c.ny = 10;
  c.width = c.height = 0.5;
  c.origin = Vec3(-0.25, 0.3055 + 0.02, -0.25);
  c.mass = 0.1;
  c.radius = 0.005;
  c.stretch.compliance = 1e-6;
  c.shear_params.compliance = 1e-5;
  c.bending_params.compliance = 10.0;
  add_cloth(m, c);
  m.planes.push_back(PlaneCollider{});
  m.particle_body.assign(27, 0);
  m.particle_body.resize(127, 1);
  m.surface_contact = surface;
  return m;
}

SolverOptions options_for(const std::string& name) {
  SolverOptions o;
  o.name = name;
  o.iterations = 10;
  o.substeps = 4;
  return o;
}

bool layer_height(const Points& x, const std::vector<std::array<int, 3>>& tris, double px,
                  double pz, double& y);

TEST(SurfaceContact, SparseBlockHoldsTheClothInEveryProjectionOrder) {
  // The projection orders reach the contact through different code (Gauss-Seidel in sequence,
  // by colour, Jacobi with its correction buffers; float; threads): each keeps every cloth
  // particle above the block's top face (its height over the face's triangles beneath it, as
  // they are at that step) at every step, every gap above minus half the thickness (1 cm), under
  // pbd and xpbd; and with vertex-triangle contact alone (Model::edge_contact off).
  // pbd with Jacobi sweeps was once recorded here as letting the cloth through the face: it does
  // not. The check then was the lowest centre particle against the block's highest vertex, and
  // under pbd's averaged Jacobi sweeps the block is softer: its top face sags, its centre vertex
  // 2.2 cm below its corners (printed below), and the cloth lies on it, below the corners but
  // above the face. The sag is Jacobi's slow convergence of the block's own constraints (each
  // correction divided by the particle's constraint count), not the contact's.
  const ProjectionOrder orders[] = {ProjectionOrder::Sequential, ProjectionOrder::Reversed,
                                    ProjectionOrder::Shuffled, ProjectionOrder::Colored,
                                    ProjectionOrder::Jacobi, ProjectionOrder::GroupedShuffled};
  for (bool edges : {true, false}) {
    Model m = cloth_on_sparse_block(true);
    m.edge_contact = edges;
    std::vector<std::array<int, 3>> top;  // the block's triangles on its top face
    for (const auto& t : m.triangles)
      if (t[0] < 27 && m.rest_positions(t[0], 1) > 0.3 && m.rest_positions(t[1], 1) > 0.3 &&
          m.rest_positions(t[2], 1) > 0.3)
        top.push_back(t);
    ASSERT_EQ(top.size(), 8u);
    for (const char* name : kSolvers)
      for (int run = 0; run < 9; ++run) {
        // The six orders in double, then sequential in float, colored with 2 threads, and
        // Jacobi with 200 sweeps.
        const ProjectionOrder order = run < 6 ? orders[run] : run == 6 ? orders[0] : run == 7 ? orders[3] : orders[4];
        SolverOptions o = options_for(name);
        o.order = order;
        if (run == 6) o.precision = Precision::Float;
        if (run == 7) o.threads = 2;
        if (order == ProjectionOrder::Jacobi) o.iterations = run == 8 ? 200 : 40;  // slower
        auto solver = make_solver(o, m);
        State s = rest_state(m);
        double worst = 1e300;
        int most_below = 0;
        for (int k = 0; k < 40; ++k) {
          solver->step(m, s, 1.0 / 60.0);
          worst = std::min(worst, min_surface_gap(m, s.x));
          int below = 0;
          for (int p = 27; p < m.particle_count(); ++p) {
            double y = 0.0;
            if (layer_height(s.x, top, s.x(p, 0), s.x(p, 2), y) && s.x(p, 1) < y) ++below;
          }
          most_below = std::max(most_below, below);
        }
        double corner = -1e300, sag = 1e300;  // the top face's highest and lowest vertex
        for (int p = 0; p < 27; ++p)
          if (m.rest_positions(p, 1) > 0.3) {
            corner = std::max(corner, s.x(p, 1));
            sag = std::min(sag, s.x(p, 1));
          }
        std::printf("%s, edge-edge %s, run %d (order %d): at most %d cloth particles below the "
                    "top face; its vertices from %.4f to %.4f m; smallest gap %.3e m\n",
                    name, edges ? "on" : "off", run, static_cast<int>(order), most_below, sag,
                    corner, worst);
        EXPECT_EQ(most_below, 0) << name << ", run " << run;
        EXPECT_GT(worst, -0.005) << name << ", run " << run;
      }
  }
}

TEST(SurfaceContact, SparseBlockStopsTheClothOnlyWithVertexTriangleContact) {
  for (const char* name : kSolvers) {
    for (bool surface : {true, false}) {
      const Model m = cloth_on_sparse_block(surface);
      auto solver = make_solver(options_for(name), m);
      State s = rest_state(m);
      const int block = 27;  // the block's 3 x 3 x 3 vertices come first
      double worst = 1e300;
      for (int k = 0; k < 40; ++k) {
        solver->step(m, s, 1.0 / 60.0);
        if (surface) worst = std::min(worst, min_surface_gap(m, s.x));
      }
      double lowest_centre = 1e300;
      for (int p = block; p < m.particle_count(); ++p)
        if (std::abs(s.x(p, 0)) < 0.1 && std::abs(s.x(p, 2)) < 0.1)
          lowest_centre = std::min(lowest_centre, s.x(p, 1));
      std::printf("%s, surface contact %s: lowest centre particle %.4f m (block top 0.3055 m), "
                  "smallest gap %.3e m\n",
                  name, surface ? "on" : "off", lowest_centre, worst);
      if (surface) {
        EXPECT_GT(lowest_centre, 0.3) << name;
        EXPECT_GT(worst, -0.005) << name;  // half the thickness of 1 cm
        // Contacts both ways at the end: cloth particles on block triangles, block vertices
        // against cloth triangles (the block's top corners and edges under the draping cloth).
        int cloth_on_block = 0, block_on_cloth = 0;
        for (const auto& [p, t] : find_surface_contacts(m, s.x, 2e-3)) {
          const bool block_triangle = m.triangles[static_cast<size_t>(t)][0] < block;
          if (p >= block && block_triangle) ++cloth_on_block;
          if (p < block && !block_triangle) ++block_on_cloth;
        }
        EXPECT_GT(cloth_on_block, 0) << name;
        EXPECT_GT(block_on_cloth, 0) << name;
      } else {
        EXPECT_LT(lowest_centre, 0.2) << name;  // the control: through the block
      }
    }
  }
}

// The height of the surface of triangles `tris` (of positions x) above the point (px, pz), by
// the triangle whose projection on the xz plane holds it; false when none does.
bool layer_height(const Points& x, const std::vector<std::array<int, 3>>& tris, double px,
                  double pz, double& y) {
  for (const auto& t : tris) {
    const double x0 = x(t[0], 0), z0 = x(t[0], 2);
    const double ax = x(t[1], 0) - x0, az = x(t[1], 2) - z0;
    const double bx = x(t[2], 0) - x0, bz = x(t[2], 2) - z0;
    const double det = ax * bz - az * bx;
    if (std::abs(det) < 1e-14) continue;
    const double u = ((px - x0) * bz - (pz - z0) * bx) / det;
    const double v = (ax * (pz - z0) - az * (px - x0)) / det;
    if (u < 0.0 || v < 0.0 || u + v > 1.0) continue;
    y = x(t[0], 1) + u * (x(t[1], 1) - x(t[0], 1)) + v * (x(t[2], 1) - x(t[0], 1));
    return true;
  }
  return false;
}

TEST(SurfaceContact, FoldedClothDoesNotPassThroughItselfWithSelfContact) {
  // An 8 x 16 cloth (0.2 x 0.4 m; spacing 2.9 cm by 2.7 cm; radius 5 mm: layers touch at 1 cm),
  // folded in two between rows 7 and 8: rows j >= 8 turned over onto rows j < 8 (z -> -z) and
  // lifted 2 cm. The lower half is a trampoline pinned at its border (row 0, columns 0 and 7). No
  // bending constraints: the upper half falls flat onto the lower one.
  constexpr int nx = 8, ny = 16, half = ny / 2;
  for (const char* name : kSolvers) {
    for (bool self : {true, false}) {
      Model m;
      ClothSpec c;
      c.nx = nx;
      c.ny = ny;
      c.width = 0.2;
      c.height = 0.4;
      c.origin = Vec3(-0.1, 0.5, -0.2);
      c.mass = 0.05;
      c.radius = 0.005;
      c.stretch.compliance = 1e-6;
      c.shear_params.compliance = 1e-5;
      c.bending = false;  // a bending constraint would unfold it (the upper half turning over)
      add_cloth(m, c);
      for (int j = 0; j < half; ++j)
        for (int i = 0; i < nx; ++i)
          if (j == 0 || i == 0 || i == nx - 1) m.inv_mass[static_cast<size_t>(j * nx + i)] = 0.0;
      m.self_contact = self;
      State s = rest_state(m);
      for (int j = half; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const int p = j * nx + i;
          s.x(p, 2) = -s.x(p, 2);
          s.x(p, 1) += 0.02;
        }
      std::vector<std::array<int, 3>> lower;  // the lower half's triangles (rows 0 to 7)
      for (const auto& t : m.triangles)
        if (std::max({t[0], t[1], t[2]}) < half * nx) lower.push_back(t);
      auto solver = make_solver(options_for(name), m);
      // The upper half's vertices away from the fold (rows 10 to 15): crossed when below the
      // lower layer beneath them.
      int most_crossed = 0;
      for (int k = 0; k < 40; ++k) {
        solver->step(m, s, 1.0 / 60.0);
        int crossed = 0;
        for (int j = 10; j < ny; ++j)
          for (int i = 0; i < nx; ++i) {
            const int p = j * nx + i;
            double y = 0.0;
            if (layer_height(s.x, lower, s.x(p, 0), s.x(p, 2), y) && s.x(p, 1) < y) ++crossed;
          }
        most_crossed = std::max(most_crossed, crossed);
      }
      const double gap = self ? min_surface_gap(m, s.x) : 0.0;
      std::printf("%s, self-contact %s: at most %d of 48 upper vertices below the lower layer; "
                  "smallest gap at the end %.3e m\n",
                  name, self ? "on" : "off", most_crossed, gap);
      if (self) {
        EXPECT_EQ(most_crossed, 0) << name;
        EXPECT_GT(gap, -0.005) << name;  // half the thickness of 1 cm
      } else {
        EXPECT_GT(most_crossed, 24) << name;  // the control: most of them pass through
      }
    }
  }
}

// Triangle A (particles 0-2) pinned in the plane z = 0, its top edge along x at height 0.3;
// triangle B (3-5) in the plane x = 0, its bottom edge along z 2 cm above A's, its apex 0.5 m
// higher, held by three distance constraints; radius 5 mm. Bodies 0 and 1, or one body.
Model crossed_edges(bool two_bodies) {
  Model m;
  for (const Vec3& p : {Vec3(-0.5, 0.3, 0.0), Vec3(0.5, 0.3, 0.0), Vec3(0.5, -0.3, 0.0)})
    add_particle(m, p, 1.0, 0.005);  // pinned below
  for (const Vec3& p : {Vec3(0.0, 0.32, -0.5), Vec3(0.0, 0.32, 0.5), Vec3(0.0, 0.82, 0.0)})
    add_particle(m, p, 0.1, 0.005);
  for (int p = 0; p < 3; ++p) m.inv_mass[static_cast<size_t>(p)] = 0.0;
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  const std::uint16_t group = m.group_index("stretch");
  for (const auto& [a, b] : {std::pair{3, 4}, std::pair{4, 5}, std::pair{3, 5}}) {
    Constraint c;
    c.kind = ConstraintKind::Distance;
    c.particles = {a, b, -1, -1};
    c.rest = (m.rest_positions.row(a) - m.rest_positions.row(b)).norm();
    c.compliance = 1e-8;
    c.group = group;
    m.constraints.push_back(c);
  }
  if (two_bodies) {
    m.particle_body = {0, 0, 0, 1, 1, 1};
    m.surface_contact = true;
  } else {
    m.self_contact = true;
  }
  return m;
}

TEST(SurfaceContact, EdgeStopsAnEdgeOnlyWithEdgeEdgeContact) {
  for (const char* name : kSolvers)
    for (bool two_bodies : {true, false})
      for (bool edges : {true, false}) {
        Model m = crossed_edges(two_bodies);
        m.edge_contact = edges;
        auto solver = make_solver(options_for(name), m);
        State s = rest_state(m);
        double lowest = 1e300, worst = 1e300;
        long edge_contacts = 0, triangle_contacts = 0;
        for (int k = 0; k < 18; ++k) {  // 0.3 s: 0.44 m of free fall
          solver->step(m, s, 1.0 / 60.0);
          lowest = std::min(lowest, 0.5 * (s.x(3, 1) + s.x(4, 1)));
          for (const Contact& c : find_contacts(m, s.x, s.time, 0.05)) {
            const double C = eval_contact(m, c, s.x, s.time).C;
            if (c.kind == ContactKind::Edge) {
              ++edge_contacts;
              worst = std::min(worst, C);
            }
            if (c.kind == ContactKind::Triangle) ++triangle_contacts;
          }
        }
        std::printf("%s, %s, edge-edge %s: lowest midpoint of the falling edge %.4f m (the "
                    "pinned edge at 0.3 m); %ld edge, %ld vertex-triangle contacts at margin 5 cm, "
                    "smallest edge gap %.3e m\n",
                    name, two_bodies ? "two bodies" : "self-contact", edges ? "on" : "off", lowest,
                    edge_contacts, triangle_contacts, edge_contacts ? worst : 0.0);
        EXPECT_EQ(triangle_contacts, 0) << name;  // no vertex comes near a triangle
        if (edges) {
          EXPECT_GT(edge_contacts, 0) << name << two_bodies;
          EXPECT_GT(lowest, 0.3 + 0.01 - 0.005) << name << two_bodies;
          EXPECT_GT(worst, -0.005) << name << two_bodies;
        } else {
          EXPECT_LT(lowest, 0.3 - 0.05) << name << two_bodies;  // the control: through
        }
      }
}

// Whether segment (p, q) passes through triangle (a, b, c) (Moller and Trumbore 1997).
bool segment_crosses_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 d = q - p, e1 = b - a, e2 = c - a;
  const Vec3 h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-300) return false;
  const double f = 1.0 / det;
  const Vec3 s = p - a;
  const double u = f * s.dot(h);
  if (u < 0.0 || u > 1.0) return false;
  const Vec3 qv = s.cross(e1);
  const double v = f * d.dot(qv);
  if (v < 0.0 || u + v > 1.0) return false;
  const double t = f * e2.dot(qv);
  return t >= 0.0 && t <= 1.0;
}

// The number of (edge, triangle) pairs of the model's surface, sharing no vertex, where the edge
// passes through the triangle: the surface's self-intersections.
int surface_crossings(const Model& m, const Points& x) {
  const TriangleBvh bvh(x, m.triangles);
  int crossings = 0;
  for (const auto& e : surface_edges(m)) {
    const Vec3 p = x.row(e[0]).transpose(), q = x.row(e[1]).transpose();
    TriangleBvh::Box box;
    box.grow(p);
    box.grow(q);
    bvh.overlapping(box, [&](int t) {
      const auto& tri = m.triangles[static_cast<size_t>(t)];
      for (int v : tri)
        if (v == e[0] || v == e[1]) return;
      if (segment_crosses_triangle(p, q, x.row(tri[0]).transpose(), x.row(tri[1]).transpose(),
                                   x.row(tri[2]).transpose()))
        ++crossings;
    });
  }
  return crossings;
}

TEST(SurfaceContact, ClothOnPoleDoesNotCrossItselfWithSelfContact) {
  {  // The counter on a closed form: two crossed triangles, one edge of each through the other.
    Model m;
    for (const Vec3& p : {Vec3(-1, 0, -1), Vec3(1, 0, -1), Vec3(0, 0, 1), Vec3(0, -1, 0),
                          Vec3(0, 1, 0), Vec3(0, 1, 0.5)})
      add_particle(m, p, 1.0, 0.01);
    m.triangles = {{0, 1, 2}, {3, 4, 5}};
    // Triangle 3-4-5 pierces 0-1-2: its edges 3-4 and 3-5 pass through it.
    EXPECT_EQ(surface_crossings(m, m.rest_positions), 2);
    m.rest_positions(3, 1) = 0.5;  // lifted clear
    EXPECT_EQ(surface_crossings(m, m.rest_positions), 0);
  }
  for (const char* name : kSolvers)
    for (bool self : {true, false}) {
      const config::Config cfg = config::load("cloth_on_pole", {{"solver.name", name}});
      Scene sc = config::build_scene(cfg);
      Model& m = sc.model;
      ASSERT_TRUE(m.self_contact);
      m.self_contact = self;
      auto solver = make_solver(config::solver_options(cfg), m);
      const double dt = config::run_options(cfg).dt;
      State s = sc.initial;
      int most = 0, steps_crossed = 0;
      for (int k = 0; k < 90; ++k) {  // 1.5 s
        solver->step(m, s, dt);
        const int crossings = surface_crossings(m, s.x);
        most = std::max(most, crossings);
        steps_crossed += crossings > 0;
      }
      double lowest = s.x.col(1).minCoeff(), highest = s.x.col(1).maxCoeff();
      std::printf("%s, self-contact %s: at most %d crossings (cloth edges through cloth "
                  "triangles) at a step, %d steps of 90 with any; cloth from %.3f to %.3f m\n",
                  name, self ? "on" : "off", most, steps_crossed, lowest, highest);
      // Under pbd with self-contact it hangs on the pole; under xpbd (either way) and pbd
      // without it, it slips off within 1.5 s (recorded by the print, not yet explained: the
      // pole is a mesh collider, met by the cloth's particles only, not its edges).
      if (std::string(name) == "pbd" && self) {
        EXPECT_GT(highest, 1.0) << name;
      }
      if (self) {
        EXPECT_EQ(most, 0) << name;
      } else {
        EXPECT_GT(most, 10) << name;  // the control: the halves pass through each other
      }
    }
}

TEST(SurfaceContact, StackOfSoftCubesDoesNotInterpenetrate) {
  // soft_cube_stack: cubes of 64 vertices, 0-63 the scene's own, 64-127 and 128-191 the
  // [[body]] entries; 1.5 s. As catalogued (particle and vertex-triangle contact, the latter with
  // friction 0.5), with vertex-triangle contact alone (particle contact off), and the control
  // with neither.
  const char* const kVariants[] = {"as catalogued", "vertex-triangle contact alone", "no contact"};
  for (const char* name : kSolvers) {
    for (int variant = 0; variant < 3; ++variant) {
      const config::Config cfg = config::load("soft_cube_stack", {{"solver.name", name}});
      Scene sc = config::build_scene(cfg);
      Model& m = sc.model;
      ASSERT_TRUE(m.surface_contact && m.particle_contact);
      ASSERT_EQ(m.surface_friction, 0.5);
      if (variant > 0) m.particle_contact = false;
      if (variant == 2) m.surface_contact = false;
      auto solver = make_solver(config::solver_options(cfg), m);
      const double dt = config::run_options(cfg).dt;
      State s = sc.initial;
      double worst = 1e300;
      for (int k = 0; k < 90; ++k) {
        solver->step(m, s, dt);
        for (int a = 0; a < 3; ++a) {
          const MeshCollider cube = body_surface(m, s.x, 64 * a, 64 * (a + 1));
          for (int b = 0; b < 3; ++b)
            if (b != a) worst = std::min(worst, min_signed_distance(cube, s.x, 64 * b, 64 * (b + 1)));
        }
      }
      double low[3], high[3];
      for (int a = 0; a < 3; ++a) {
        low[a] = s.x.middleRows(64 * a, 64).col(1).minCoeff();
        high[a] = s.x.middleRows(64 * a, 64).col(1).maxCoeff();
      }
      std::printf("%s, %s: smallest signed distance of a vertex to another cube %.4f m; cubes "
                  "from %.3f to %.3f, %.3f to %.3f, %.3f to %.3f m\n",
                  name, kVariants[variant], worst, low[0], high[0], low[1], high[1], low[2], high[2]);
      if (variant < 2) {
        EXPECT_GE(worst, 0.0) << name << ", " << kVariants[variant];
        // Still a stack: each cube wholly above the one below.
        EXPECT_GT(low[1], high[0]) << name << ", " << kVariants[variant];
        EXPECT_GT(low[2], high[1]) << name << ", " << kVariants[variant];
      } else {
        EXPECT_LT(worst, -0.05) << name;  // the control: they sink into each other
      }
    }
  }
}

}  // namespace
}  // namespace pbdbench
