// ParaView output: an XDMF (version 2) description of a run file, for ParaView or any reader of
// the format (VTK's XDMF reader, meshio).
//
//   RUN.xdmf      a temporal collection, one step per frame of the run file, each a spatial
//                 collection of grids: "tets", "triangles", "edges" (the model's topology; edges
//                 are the model's edges and the pairs of its distance constraints, so chains and
//                 springs show), and "colliders" (planes as finite quads around the body, spheres
//                 and bowls as meshes, moving with their motion).
//                 Point data: velocity (m/s), displacement from the rest position (m), inv_mass
//                 (1/kg), pinned (1 where inv_mass = 0).
//                 Cell data, per frame: strain of each edge (|x_i - x_j| / rest - 1), area change
//                 of each triangle and volume change of each tet (A / A0 - 1, V / V0 - 1), and
//                 constraint_error: the largest error (metrics::constraint_error) of the
//                 constraints on the cell's particles (distance on an edge, volume and FEM on a
//                 tet or a triangle; NaN where none).
//   RUN.viz.h5    the fields computed here. Positions and velocities are not copied: the XDMF
//                 reads them from the run file (/frames/positions, /frames/velocities) by
//                 hyperslab.
#pragma once

#include <filesystem>

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
// runfile/output_guard.hpp) to replace a file that is not an earlier export; throws
// std::runtime_error naming the file when the run file cannot be read.
XdmfSummary write_xdmf(const std::filesystem::path& run_file, const Model& model,
                       const std::filesystem::path& xdmf);

// The default place of a run file's XDMF: RUN.h5 -> RUN.xdmf.
std::filesystem::path default_xdmf_path(const std::filesystem::path& run_file);

// Whether `path` is the data file of an export (RUN.viz.h5, which `pbdbench run` writes beside
// the run file): commands that take many run files (`summary results/mine/*.h5`) pass over it.
bool is_xdmf_data(const std::filesystem::path& path);

}  // namespace pbdbench
