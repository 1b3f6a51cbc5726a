// ParaView output: an XDMF (version 3) description of a run file, read by ParaView's XDMF readers
// (the legacy "XDMF Reader" and "Xdmf3ReaderS") and by meshio (meshio.xdmf.TimeSeriesReader).
//
//   RUN.xdmf      two temporal collections, one uniform grid per frame of the run file:
//                 "colliders" (when the scene has any: planes as finite quads around the body,
//                 spheres and bowls as meshes, moving with their motion) and "body", last (meshio
//                 reads the last collection): the model's tets, triangles and edges in one mixed
//                 topology, in that order (edges are the model's edges and the pairs of its
//                 distance constraints, so chains and springs show).
//                 Point data: velocity (m/s), displacement from the rest position (m), inv_mass
//                 (1/kg), pinned (1 where inv_mass = 0).
//                 Cell data, per frame, defined on every cell: change, the relative change of the
//                 cell's measure (a tet's volume, a triangle's area, an edge's length: V / V0 - 1,
//                 A / A0 - 1, l / l0 - 1), and constraint_error, the largest error
//                 (metrics::constraint_error) of the constraints whose particles all belong to the
//                 cell (a cloth triangle: the distance constraints of its edges), else of those
//                 that share a particle with it, 0 where none does; NaN only where a constraint's
//                 error is NaN.
//   RUN.viz.h5    the data the XDMF reads, each a whole dataset (no hyperslab: meshio reads none):
//                 edges, triangles, tets, mixed (the mixed topology), inv_mass, pinned,
//                 collider_triangles, and per frame /frames/NNNNNN/ positions, displacement,
//                 velocity, change, constraint_error, collider_points (frame 0's only when the
//                 colliders do not move), deflated (level 1, shuffled).
#pragma once

#include <filesystem>
#include <string>

#include "core/model.hpp"

namespace pbdbench {

struct XdmfSummary {
  long frames = 0;
  long tets = 0, triangles = 0, edges = 0;
  long collider_points = 0;
  std::filesystem::path xdmf, data;
};

// Writes `xdmf` and the data file beside it (its stem + ".viz.h5") for the run file `run_file`
// made from `model` (config::build_scene on the run's stored configuration). Refuses (OutputRefused,
// runfile/output_guard.hpp, naming `argument`: "--out" for `export --out`) to replace a file that
// is not an earlier export, or the run file itself, or to write through a link planted at a
// temporary ("<file>.tmp"); throws
// std::runtime_error naming the file when the run file cannot be read.
XdmfSummary write_xdmf(const std::filesystem::path& run_file, const Model& model,
                       const std::filesystem::path& xdmf, const std::string& argument = "the export");

// The default place of a run file's XDMF: RUN.h5 -> RUN.xdmf.
std::filesystem::path default_xdmf_path(const std::filesystem::path& run_file);

// Whether `path` is the data file of an export (RUN.viz.h5, which `pbdbench run` writes beside
// the run file): commands that take many run files (`summary results/mine/*.h5`) pass over it.
bool is_xdmf_data(const std::filesystem::path& path);

}  // namespace pbdbench
