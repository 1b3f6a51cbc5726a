// Import of meshes from standard formats. Every reader throws MeshError naming the file, the line
// and what is wrong (a missing file, a bad number, an index out of range, a degenerate element).
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/generators.hpp"
#include "core/model.hpp"

namespace pbdbench {

class MeshError : public std::runtime_error {
 public:
  MeshError(const std::string& file, int line, const std::string& what);
  const std::string& file() const { return file_; }
  int line() const { return line_; }  // 0 when the problem is not on one line

 private:
  std::string file_;
  int line_;
};

struct SurfaceMesh {
  Points vertices;                            // (n x 3)
  std::vector<std::array<int, 3>> triangles;  // 0-based, polygons fan-triangulated
  std::vector<int> triangle_lines;            // the file's line of each triangle's face (OBJ)
};

struct TetMesh {
  Points vertices;                       // (n x 3)
  std::vector<std::array<int, 4>> tets;  // 0-based, as stored in the file
};

// Wavefront OBJ: `v x y z` and `f a b c ...` lines (a may be a, a/t, a/t/n or a//n; negative
// indices count from the end). Other lines are ignored.
SurfaceMesh read_obj(const std::string& path);

// TetGen: path is the .node file (or the base name); the .ele file beside it is read too.
TetMesh read_tetgen(const std::string& path);

// Gmsh .msh, ASCII format 2.2 or 4.1: nodes and 4-node tetrahedra (element type 4).
TetMesh read_gmsh(const std::string& path);

// Reads .node/.ele or .msh by the file's extension.
TetMesh read_tet_mesh(const std::string& path);

// Adds a surface mesh as a cloth-like body: particles (mass spread evenly, total `mass`), the
// triangles, "stretch" distance constraints on unique edges, and dihedral "bending" constraints
// on interior edges when bending. surface_closed is set when every edge has two triangles and the
// winding is consistent (and the model's earlier surfaces, if any, were closed); a closed surface
// wound inward (negative enclosed volume) is turned outward. Throws MeshError (line 0) on a
// degenerate triangle (area <= 1e-12 diag^2, diag the bounding-box diagonal), an index out of
// range or duplicate vertices (identical coordinates).
struct SurfaceBodySpec {
  double mass = 1.0;    // kg, total
  double radius = 0.01; // m
  bool bending = true;
  ConstraintParams stretch, bending_params;
};
ParticleRange add_surface_mesh(Model& model, const SurfaceMesh& mesh, const SurfaceBodySpec& spec,
                               const std::string& file);

// Adds a tet mesh as a soft body: particles (mass from density * |volume| / 4 per tet vertex),
// the tets (a negative one has two vertices swapped when reorient; else it is refused with a
// MeshError: inconsistent orientation is staged on purpose with the [defects] key flip_tets),
// "edge" and "volume" constraints, and the boundary surface (outward).
// Throws MeshError (line 0) naming the element when a tet is degenerate (|volume| below 1e-12
// times the cube of the mesh's bounding-box diagonal), an index is out of range, two vertices
// have identical coordinates, or a vertex belongs to no tet (it would have no mass).
struct TetBodySpec {
  double density = 1000.0;  // kg/m^3
  double radius = 0.01;     // m
  bool reorient = true;
  bool edges = true;
  bool volumes = true;
  ConstraintParams edge, volume;
};
ParticleRange add_tet_mesh(Model& model, const TetMesh& mesh, const TetBodySpec& spec,
                           const std::string& file);

}  // namespace pbdbench
