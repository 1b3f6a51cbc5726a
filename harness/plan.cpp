#include "harness/plan.hpp"

#include <sys/resource.h>
#include <sys/statvfs.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>

#include <fmt/format.h>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_kind.hpp"
#include "core/surface_contact.hpp"
#include "runfile/series.hpp"

namespace pbdbench {

namespace {

// The time of a step: a cost model per particle, substep, constraint projection by kind and
// contact, its costs fitted to short runs of every catalog scene (their own solvers, and ref-be)
// on a 2-core AMD EPYC, Release build, in the CPU time of the whole process per step over 200
// steps: `test_harness --gtest_also_run_disabled_tests --gtest_filter=Plan.DISABLED_CatalogTable`
// prints the estimate beside the measurement, and
// Plan.TheTimeEstimateIsWithinAFactorOfTwoOnCatalogScenes holds a few scenes to a factor of 2.
constexpr double kStepSeconds = 6e-5;               // one step's row: metrics, the writer, checks
constexpr double kParticleSeconds = 5e-7;           // one particle, one step: its metrics and frame
constexpr double kSubstepSeconds = 2e-6;            // one substep of the PBD family
constexpr double kSubstepParticleSeconds = 5e-8;    // one particle, one substep: prediction, velocity
// One projection of a constraint, by kind (core/constraint_kind.hpp).
constexpr double kProjectionSeconds[kConstraintKindCount] = {
    1.3e-8,  // Distance
    2.0e-8,  // Volume
    1.3e-8,  // Bending
    5.0e-8,  // FemDeviatoric
    5.0e-8,  // FemHydrostatic
    2.6e-7,  // FemStrainTriangle (a 3-vector: its 3 x 3 system)
    5.0e-7,  // FemStrainTet (a 6-vector; in no catalog scene: about twice the triangle's, assumed)
};
// One particle, one substep, against each collider (plane or sphere; triangle mesh), and the
// contacts between particles and between surfaces (their detection dominates).
constexpr double kAnalyticColliderSeconds = 1e-7;
constexpr double kMeshColliderSeconds = 1.1e-6;
constexpr double kParticleContactSeconds = 1e-6;
constexpr double kSurfaceContactSeconds = 9e-6;     // between bodies (scene.surface_contact)
constexpr double kSelfContactSeconds = 5e-6;        // a cloth against itself (scene.self_contact)
// The reference and global solvers: one step of Newton iterations on the sparse system, per
// particle and per non-FEM constraint, per FEM constraint (an element's energy and Hessian), and
// per particle when particles or surfaces touch (the contact potential).
constexpr double kReferenceSeconds = 1e-5;
constexpr double kReferenceFemSeconds = 6e-5;
constexpr double kReferenceContactSeconds = 2e-4;
constexpr double kParticleBytes = 2048;       // state, work arrays, metrics, the step logger's
                                              // copies (harness/step_logger.hpp), per particle
constexpr double kConstraintBytes = 512;      // constraint, ordering, multipliers
// The memory of a run (docs/usage.md, "The plan"), as resident memory: the program, its data by
// particle, constraint and contact, the mesh colliders, and the ParaView export that follows a
// run. Measured with /usr/bin/time -v (its maximum resident set) on catalog scenes:
// PlanMemory.* (tests/harness/test_plan_memory.cpp) holds a few, and a mesh collider, to a
// factor of 2.
constexpr double kContactBytes = 256;         // a contact, the solver's copy, the metrics' search
// Contacts between surfaces expected per surface particle over a run (vertex-triangle and
// edge-edge: a cloth lying on a body touches a few triangles and edges with each particle),
// beyond those of the start; their searches stop at contact_pair_limit (core/surface_contact.hpp).
constexpr double kSurfaceContactsPerParticle = 8;
constexpr double kMeshTriangleBytes = 400;    // a collider triangle: its vertices, normals, BVH
                                              // nodes, and the OBJ's parse
constexpr double kReferenceBytes = 16384;     // per constraint or particle: sparse factors
// The program, its libraries, HDF5's caches and buffered rows: 28 to 34 MB measured for the
// small catalog scenes (`/usr/bin/time -v pbdbench run SCENE --set time.duration=0.25`), 21 to
// 27 MB in the test's child processes.
constexpr double kBaseBytes = 24.0 * 1024 * 1024;
// The export (runfile/xdmf.cpp) reads the run file's frames one at a time
// (runfile/frame_reader.hpp): it holds one frame's positions, velocities and output buffer (72
// bytes a particle), its two fields (16 bytes a cell) and its cell tables (kExportCellBytes a
// cell), whatever the run's length. (Holding every frame, the 64 x 64 cloth's export grew by 0.57
// MB a frame, 48 x 4096 + 16 x 23,940 bytes: 399 MB with 603 frames, 2.1 GB with 3,603.) Its data
// file holds per frame positions, displacement and velocity (72 bytes a particle), the two fields
// (16 bytes a cell) and kExportFrameBytes of HDF5 objects, uncompressed (gzip makes it 0.6 to 0.9
// of that).
constexpr double kExportCellBytes = 256;
constexpr double kExportFrameBytes = 8192;
constexpr double kMaxSeconds = 24 * 3600.0;

bool is_reference(const std::string& solver) {
  const SolverEntry* entry = find_solver(solver);
  return entry != nullptr &&
         (entry->family == SolverFamily::Reference || entry->family == SolverFamily::Global);
}

// Particle pairs closer than the sum of their radii at the start, counted with a grid (no list),
// up to the particle search's limit (beyond it the run would stop at its first step).
long overlapping_pairs(const Model& model) {
  const int n = model.particle_count();
  double rmax = 0.0;
  for (double r : model.radius) rmax = std::max(rmax, r);
  if (n < 2 || !(rmax > 0.0)) return 0;
  const double cell = 2.0 * rmax;
  std::map<std::tuple<long, long, long>, std::vector<int>> cells;
  auto index = [&](double v) { return static_cast<long>(std::floor(v / cell)); };
  for (int p = 0; p < n; ++p) {
    const auto x = model.rest_positions.row(p);
    if (!x.allFinite()) continue;
    cells[{index(x(0)), index(x(1)), index(x(2))}].push_back(p);
  }
  long pairs = 0;
  for (const auto& [key, members] : cells)
    for (long di = -1; di <= 1; ++di)
      for (long dj = -1; dj <= 1; ++dj)
        for (long dk = -1; dk <= 1; ++dk) {
          auto it = cells.find({std::get<0>(key) + di, std::get<1>(key) + dj, std::get<2>(key) + dk});
          if (it == cells.end()) continue;
          for (int a : members)
            for (int b : it->second) {
              if (b <= a) continue;
              const double d = (model.rest_positions.row(a) - model.rest_positions.row(b)).norm();
              if (d < model.radius[static_cast<size_t>(a)] + model.radius[static_cast<size_t>(b)]) ++pairs;
              if (pairs > static_cast<long>(contact_pair_limit(static_cast<size_t>(n)))) return pairs;
            }
        }
  return pairs;
}

// The surface particles (vertices of Model::triangles): those that touch other surfaces.
double surface_particles(const Model& model) {
  std::vector<char> on(static_cast<size_t>(model.particle_count()), 0);
  for (const auto& t : model.triangles)
    for (int v : t) on[static_cast<size_t>(v)] = 1;
  return static_cast<double>(std::count(on.begin(), on.end(), 1));
}

// The vertex-triangle and edge-edge pairs within the contact margin at the rest positions, by
// the solvers' own searches; a search past its limit leaves its message in plan.contact_limit.
void count_surface_contacts(const Model& model, double margin, RunPlan& plan) {
  if (!vertex_triangle_contact(model)) return;
  try {
    plan.surface_pairs = static_cast<long>(find_surface_contacts(model, model.rest_positions, margin).size());
    plan.surface_pairs += static_cast<long>(find_edge_contacts(model, model.rest_positions, margin).size());
  } catch (const ContactPairLimit& e) {
    plan.contact_limit = e.what();
  }
}

// The cells of the export (runfile/xdmf.cpp): tets, triangles, and edges (the model's and its
// distance constraints' pairs, once each: the larger of the two counts, which a cloth's and a
// tet body's share).
double export_cells(const Model& model) {
  double distance = 0.0;
  for (const Constraint& c : model.constraints) distance += c.kind == ConstraintKind::Distance ? 1.0 : 0.0;
  return static_cast<double>(model.tets.size() + model.triangles.size()) +
         std::max(static_cast<double>(model.edges.size()), distance);
}

// The memory this process may take: the machine's available memory (/proc/meminfo), and below
// it the process's address-space limit (`ulimit -v`, prlimit --as: a resident set is at most its
// address space) and its control group's limit (cgroup v2 memory.max less memory.current: a
// container's or a Slurm job's). 0 when none is known.
double available_memory() {
  double available = 0.0;
  {
    std::ifstream in("/proc/meminfo");
    std::string key, unit;
    double kb = 0.0;
    while (in >> key >> kb >> unit)
      if (key == "MemAvailable:") {
        available = kb * 1024.0;
        break;
      }
  }
  auto lower = [&](double limit) {
    if (limit > 0.0 && (available <= 0.0 || limit < available)) available = limit;
  };
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) lower(static_cast<double>(as.rlim_cur));
  std::string cgroup = "/";
  {
    std::ifstream self("/proc/self/cgroup");
    for (std::string line; std::getline(self, line);)
      if (line.rfind("0::", 0) == 0) cgroup = line.substr(3);
  }
  const std::string dir = "/sys/fs/cgroup" + cgroup + (cgroup.empty() || cgroup.back() != '/' ? "/" : "");
  std::ifstream max_file(dir + "memory.max"), current_file(dir + "memory.current");
  std::string max_text;
  double current = 0.0;
  if (max_file >> max_text && max_text != "max" && current_file >> current) {
    char* end = nullptr;
    const double max = std::strtod(max_text.c_str(), &end);
    if (end != max_text.c_str() && max > current) lower(max - current);
  }
  return available;
}

std::string bytes(double b) {
  if (b >= 1e9) return fmt::format("{:.3g} GB", b / 1e9);
  if (b >= 1e6) return fmt::format("{:.3g} MB", b / 1e6);
  return fmt::format("{:.3g} kB", b / 1e3);
}

std::string duration(double s) {
  if (s >= 86400) return fmt::format("{:.3g} days", s / 86400);
  if (s >= 3600) return fmt::format("{:.3g} h", s / 3600);
  if (s >= 60) return fmt::format("{:.3g} min", s / 60);
  return fmt::format("{:.2g} s", s);
}

}  // namespace

double step_seconds(const Model& model, const SolverOptions& solver) {
  const double n = model.particle_count();
  const bool touching = model.particle_contact || model.surface_contact || model.self_contact;
  std::array<double, kConstraintKindCount> kinds{};
  for (const Constraint& c : model.constraints) kinds[static_cast<size_t>(c.kind)] += 1.0;
  const double seconds = kStepSeconds + n * kParticleSeconds;
  if (is_reference(solver.name)) {
    double fem = 0.0;
    for (int k = 0; k < kConstraintKindCount; ++k)
      if (is_fem_kind(static_cast<ConstraintKind>(k))) fem += kinds[static_cast<size_t>(k)];
    const double others = static_cast<double>(model.constraints.size()) - fem;
    return seconds + (n + others) * kReferenceSeconds + fem * kReferenceFemSeconds +
           (touching ? n * kReferenceContactSeconds : 0.0);
  }
  const SolverEntry* entry = find_solver(solver.name);
  const double substeps = std::max(1, solver.substeps);
  // force-symplectic takes substeps and no iterations.
  const bool iterates = entry == nullptr || entry->family != SolverFamily::Force;
  const double sweeps = substeps * (iterates ? std::max(1, solver.iterations) : 1);
  double projection = 0.0;
  for (int k = 0; k < kConstraintKindCount; ++k) projection += kinds[static_cast<size_t>(k)] * kProjectionSeconds[k];
  const double colliders = static_cast<double>(model.planes.size() + model.spheres.size()) * kAnalyticColliderSeconds +
                           static_cast<double>(model.meshes.size()) * kMeshColliderSeconds;
  const double per_particle = kSubstepParticleSeconds + colliders +
                              (model.particle_contact ? kParticleContactSeconds : 0.0) +
                              (model.surface_contact ? kSurfaceContactSeconds : 0.0) +
                              (model.self_contact ? kSelfContactSeconds : 0.0);
  return seconds + substeps * (kSubstepSeconds + n * per_particle) + sweeps * projection;
}

RunPlan plan_run(const Model& model, const SolverOptions& solver, const config::RunOptions& run,
                 bool exported) {
  RunPlan plan;
  plan.steps = run.steps();
  plan.frames = plan.steps / run.every_frame() + 2;
  plan.contact_pairs = overlapping_pairs(model);
  const double n = model.particle_count();
  const double m = static_cast<double>(model.constraints.size());
  count_surface_contacts(model, solver.contact_margin, plan);
  const double contacts = static_cast<double>(plan.contact_pairs) + static_cast<double>(plan.surface_pairs) +
                          n * static_cast<double>(model.planes.size() + model.spheres.size() + model.meshes.size()) +
                          (vertex_triangle_contact(model) ? kSurfaceContactsPerParticle * surface_particles(model) : 0.0);
  plan.contact_bytes = contacts * kContactBytes;
  for (const MeshCollider& mesh : model.meshes) plan.mesh_bytes += static_cast<double>(mesh.triangles.size()) * kMeshTriangleBytes;
  const double steps = static_cast<double>(plan.steps);
  size_t columns = 0;
  for (const SeriesSpec& s : series_table()) columns += static_cast<size_t>(s.width);
  columns += 2 * model.group_names.size();
  plan.file_bytes = (steps + 1) * static_cast<double>(columns) * 8.0 + static_cast<double>(plan.frames) * n * 48.0;  // positions and velocities
  plan.seconds = steps * step_seconds(model, solver);
  if (is_reference(solver.name)) {
    plan.memory_bytes = kBaseBytes + (m + n) * kReferenceBytes + plan.contact_bytes + plan.mesh_bytes;
  } else {
    plan.memory_bytes = kBaseBytes + n * kParticleBytes + m * kConstraintBytes + plan.contact_bytes + plan.mesh_bytes;
  }
  if (exported) {
    const double cells = export_cells(model), frames = static_cast<double>(plan.frames);
    plan.export_bytes = frames * (72.0 * n + 16.0 * cells + kExportFrameBytes);
    plan.export_memory_bytes = kBaseBytes + n * kParticleBytes + m * kConstraintBytes + plan.mesh_bytes +
                               cells * kExportCellBytes + 72.0 * n + 16.0 * cells;
    plan.memory_bytes = std::max(plan.memory_bytes, plan.export_memory_bytes);
  }
  return plan;
}

std::string plan_problems(const RunPlan& plan, const std::filesystem::path& out) {
  std::vector<std::string> problems;
  if (!plan.contact_limit.empty()) problems.push_back("at the start, " + plan.contact_limit);
  const double memory = available_memory();
  if (memory > 0.0 && plan.memory_bytes > memory)
    problems.push_back(fmt::format("about {} of memory{}, and {} is available", bytes(plan.memory_bytes),
                                   plan.export_memory_bytes >= plan.memory_bytes && plan.export_memory_bytes > 0.0
                                       ? " (the ParaView export's; --no-xdmf runs without it)"
                                       : "",
                                   bytes(memory)));
  const std::filesystem::path dir = out.has_parent_path() ? out.parent_path() : std::filesystem::path(".");
  struct statvfs fs {};
  if (::statvfs(dir.c_str(), &fs) == 0) {
    const double free = static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize);
    // The run file and its working copy (runfile/shadow_file.hpp), and the export beside them.
    if (2.0 * plan.file_bytes + plan.export_bytes > free)
      problems.push_back(fmt::format("a run file of up to {} (twice that while it runs){}, and {} is free in {}",
                                     bytes(plan.file_bytes),
                                     plan.export_bytes > 0.0
                                         ? fmt::format(" and a ParaView export of {} (--no-xdmf runs without it)",
                                                       bytes(plan.export_bytes))
                                         : "",
                                     bytes(free), dir.string()));
  }
  if (plan.seconds > kMaxSeconds)
    problems.push_back(fmt::format("about {} of wall time, more than a day", duration(plan.seconds)));
  std::string text;
  for (size_t i = 0; i < problems.size(); ++i) text += (i ? "; " : "") + problems[i];
  return text;
}

std::string describe_plan(const RunPlan& plan) {
  return fmt::format("{} steps, about {} and {} of memory, a run file of up to {}{}", plan.steps,
                     duration(plan.seconds), bytes(plan.memory_bytes), bytes(plan.file_bytes),
                     plan.export_bytes > 0.0 ? fmt::format(" and a ParaView export of {}", bytes(plan.export_bytes)) : "");
}

}  // namespace pbdbench
