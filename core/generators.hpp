// Scene generators: each appends particles, topology and constraints to a Model and returns the
// range of particles it added, so a scene can combine several parts. Pure functions of their
// specs; no randomness except where a spec carries a seed.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "core/model.hpp"

namespace pbdbench {

struct ParticleRange {
  int begin = 0;  // first particle added
  int end = 0;    // one past the last
  int size() const { return end - begin; }
};

// Material parameters of one constraint group (copied into each Constraint).
struct ConstraintParams {
  double compliance = 0.0;  // alpha (units of C^2/J; m/N for distance), >= 0
  double stiffness = 1.0;   // PBD k in [0, 1]
  double damping = 0.0;     // XPBD beta >= 0, s / (units of alpha): N s/m for distance
};

// One free particle.
int add_particle(Model& model, const Vec3& position, double mass, double radius);

// A chain of `links` distance constraints (group "link") joining links+1 particles laid out from
// `top` along the unit vector `direction`, each link `link_length` long. Every particle has
// `mass` except the last, which has `end_mass` when end_mass > 0. With pin_top the first particle
// is pinned (inv_mass 0 and a static Attachment). A pendulum is a chain of one link.
struct ChainSpec {
  int links = 19;
  double link_length = 0.1;               // m
  Vec3 top = Vec3::Zero();                // m
  Vec3 direction = Vec3(0.0, -1.0, 0.0);  // unit
  double mass = 1.0;                      // kg per particle
  double end_mass = 0.0;                  // kg, 0 = same as mass
  double radius = 0.01;                   // m
  bool pin_top = true;
  ConstraintParams link;
};
ParticleRange add_chain(Model& model, const ChainSpec& spec);

// A rectangular cloth of nx * ny particles (particle (i, j) has index begin + j * nx + i) spanning
// width along the first axis of `plane` and height along the second, from `origin`:
//   plane "xz": x = origin + (i w/(nx-1), 0, j h/(ny-1))  (horizontal for gravity along -y)
//   plane "xy": x = origin + (i w/(nx-1), -j h/(ny-1), 0) (hanging, row j = 0 on top)
// Constraints: "stretch" (grid edges), "shear" (both diagonals of each cell) when shear,
// "bending": dihedral (one per interior triangle edge) or distance between particles two apart
// along each grid line, when bending. Triangles: two per cell, all wound the same way.
// Total mass `mass` spread evenly over the particles.
enum class BendingModel : std::uint8_t { Dihedral, Distance };
struct ClothSpec {
  int nx = 64, ny = 64;
  double width = 1.0, height = 1.0;  // m
  Vec3 origin = Vec3::Zero();        // m
  std::string plane = "xz";          // "xz" or "xy"
  double mass = 1.0;                 // kg, total
  double radius = 0.005;             // m per particle
  bool shear = true;
  bool bending = true;
  BendingModel bending_model = BendingModel::Dihedral;
  ConstraintParams stretch, shear_params, bending_params;
};
ParticleRange add_cloth(Model& model, const ClothSpec& spec);

// A box of cells[0] x cells[1] x cells[2] hexahedral cells, each split into tetrahedra (6, sharing
// the cell's main diagonal, or 5 with alternating orientation so neighbouring cells conform), all
// positively oriented. Spans `size` from `origin`. Mass from density times each tet's volume,
// lumped equally to its four vertices. Constraints: "edge" (distance on every unique tet edge)
// when edges, "volume" (one per tet) when volumes. Surface triangles: the boundary faces, wound
// outward; surface_closed = true, or, when the model already had triangles, kept true only if
// it was true (the union of closed surfaces is closed, anything with an open sheet is not).
struct TetBlockSpec {
  std::array<int, 3> cells{8, 2, 2};
  Vec3 size = Vec3(1.0, 0.25, 0.25);  // m
  Vec3 origin = Vec3::Zero();         // m, the minimum corner
  double density = 1000.0;            // kg/m^3
  double radius = 0.01;               // m per particle
  int tets_per_cell = 6;              // 5 or 6
  bool edges = true;
  bool volumes = true;
  ConstraintParams edge, volume;
};
ParticleRange add_tet_block(Model& model, const TetBlockSpec& spec);

// A rectangle of cells[0] x cells[1] cells in the xy plane (a 2D body: the plane-strain FEM
// elements of core/fem.hpp move in it), spanning size[0] along x and size[1] along y from
// `origin` (its minimum corner). Vertex (i, j) is begin + i + (cells[0] + 1) j; each cell is
// split into two triangles along a diagonal that alternates from cell to cell (i + j even: from
// (i, j) to (i+1, j+1); odd: from (i+1, j) to (i, j+1)), so that the mesh has no preferred
// direction; all triangles wound counter-clockwise seen from +z. Mass from density times
// thickness times each triangle's area, lumped equally to its three vertices. The triangles are
// the model's triangles, their unique edges its edges; constraints: "edge" (distance on every
// edge) when edges. The FEM elements are added apart (fem::add_fem_triangles).
struct TriBlockSpec {
  std::array<int, 2> cells{20, 4};
  std::array<double, 2> size{1.0, 0.2};  // m
  Vec3 origin = Vec3::Zero();            // m, the minimum corner
  double density = 1000.0;               // kg/m^3
  double thickness = 1.0;                // m, the extent out of the plane the mass stands for
  double radius = 0.01;                  // m per particle
  bool edges = false;
  ConstraintParams edge;
};
ParticleRange add_tri_block(Model& model, const TriBlockSpec& spec);

// Grid layout: count[0] x count[1] x count[2] spheres of `radius` on a cubic lattice of spacing
// 2 radius (1 + gap) from `origin` (the centre of the first sphere); the jitter must stay below
// radius gap, so that no two spheres start overlapping.
// Ring layout: count[0] spheres (count[1] = count[2] = 1) with centres on a circle of
// `ring_radius` around `origin`, in the plane normal to `up`: sphere k at angle 2 pi k / count[0]
// from e1, origin + ring_radius (cos a e1 + sin a e2), with e1 the unit projection of +x on that
// plane (of +z when up is along x) and e2 = up x e1. Neighbours may overlap: the layout exists to
// start in penetration (centre distance 2 ring_radius sin(pi / count[0])).
// Either way each centre is then displaced by a uniform random jitter in [-jitter, jitter] m per
// axis drawn from `seed` (deterministic). Each sphere has `mass`.
enum class SpheresLayout : std::uint8_t { Grid, Ring };
struct PackedSpheresSpec {
  std::array<int, 3> count{5, 5, 5};
  double radius = 0.05;        // m
  double gap = 0.05;           // fraction of the diameter left between neighbours (grid)
  Vec3 origin = Vec3::Zero();  // m, centre of the first sphere (grid) or of the ring
  double mass = 0.1;           // kg each
  double jitter = 0.0;         // m
  std::uint64_t seed = 1;
  SpheresLayout layout = SpheresLayout::Grid;
  double ring_radius = 0.1;    // m, > 0 (ring)
  Vec3 up = Vec3::UnitY();     // the ring's axis (ring; non-zero, normalised)
};
ParticleRange add_packed_spheres(Model& model, const PackedSpheresSpec& spec);

}  // namespace pbdbench
