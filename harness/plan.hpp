// The planned run, estimated before it starts: steps, rows, the run file's size, the memory and
// the time it will take, and whether this machine can take it.
//
// The time is a cost model fitted to the catalog scenes (plan.cpp: per particle, substep,
// constraint projection by kind, collider and contact; per particle and constraint for the
// reference and global solvers), within a factor of 2 of what those scenes measure
// (tests/harness/test_plan.cpp); the memory counts the largest data structures of the model.
// They exist to refuse up front what would exhaust the memory or the disk, or run for days,
// instead of finding out hours later (--force runs it anyway), and to say how long a long run
// will take.
#pragma once

#include <filesystem>
#include <string>

#include "config/config.hpp"
#include "core/model.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

struct RunPlan {
  long steps = 0;
  long frames = 0;
  double file_bytes = 0.0;    // the run file at the end (frames uncompressed: an upper bound)
  double memory_bytes = 0.0;  // resident memory of the run: the largest of the steps' and the export's
  double seconds = 0.0;       // wall time
  long contact_pairs = 0;     // particle pairs overlapping (within the contact margin) at the start
  // Memory and disk, by part (plan.cpp counts them; docs/usage.md, "The plan"):
  long surface_pairs = 0;     // vertex-triangle and edge-edge pairs within the contact margin at the start
  double contact_bytes = 0.0; // the contacts: those at the start and an allowance per surface particle
  double mesh_bytes = 0.0;    // the mesh colliders: triangles, normals, BVHs (built before the plan)
  double export_bytes = 0.0;         // the ParaView export's data file (RUN.viz.h5); 0 without one
  double export_memory_bytes = 0.0;  // the export's resident memory; 0 without one
  std::string contact_limit;  // a contact search passes its limit at the start
                              // (core/surface_contact.hpp contact_pair_limit): its message
};

// `exported`: the run is followed by its ParaView export (`pbdbench run` without --no-xdmf),
// whose memory and file the plan then counts.
RunPlan plan_run(const Model& model, const SolverOptions& solver, const config::RunOptions& run,
                 bool exported = false);

// The estimated time of one step (s): the solver's step, and the step's metrics and row.
double step_seconds(const Model& model, const SolverOptions& solver);

// "" when the plan fits this machine (memory available, free space at `out`'s folder for the run
// file, its working copy and the export, at most a day of wall time, contacts at the start within
// their searches' limits), else why not, with the numbers.
std::string plan_problems(const RunPlan& plan, const std::filesystem::path& out);

// "12,000 steps, about 3 min, 1.2 GB of memory, a 40 MB file".
std::string describe_plan(const RunPlan& plan);

}  // namespace pbdbench
