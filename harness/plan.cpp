#include "harness/plan.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>

#include <fmt/format.h>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_kind.hpp"
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
constexpr double kContactBytes = 256;
constexpr double kReferenceBytes = 16384;     // per constraint or particle: sparse factors
constexpr double kBaseBytes = 96.0 * 1024 * 1024;  // the program, HDF5's caches, buffered rows
constexpr double kMaxSeconds = 24 * 3600.0;

bool is_reference(const std::string& solver) {
  const SolverEntry* entry = find_solver(solver);
  return entry != nullptr &&
         (entry->family == SolverFamily::Reference || entry->family == SolverFamily::Global);
}

// Particle pairs closer than the sum of their radii at the start, counted with a grid (no list).
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
              if (pairs > 64L * n) return pairs;  // collapsed: counting further only costs time
            }
        }
  return pairs;
}

double available_memory() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kb = 0.0;
  std::string unit;
  while (in >> key >> kb >> unit)
    if (key == "MemAvailable:") return kb * 1024.0;
  return 0.0;  // unknown
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

RunPlan plan_run(const Model& model, const SolverOptions& solver, const config::RunOptions& run) {
  RunPlan plan;
  plan.steps = run.steps();
  plan.frames = plan.steps / run.every_frame() + 2;
  plan.contact_pairs = overlapping_pairs(model);
  const double n = model.particle_count();
  const double m = static_cast<double>(model.constraints.size());
  const double contacts = static_cast<double>(plan.contact_pairs) + n * static_cast<double>(model.planes.size() + model.spheres.size() + model.meshes.size());
  const double steps = static_cast<double>(plan.steps);
  size_t columns = 0;
  for (const SeriesSpec& s : series_table()) columns += static_cast<size_t>(s.width);
  columns += 2 * model.group_names.size();
  plan.file_bytes = (steps + 1) * static_cast<double>(columns) * 8.0 + static_cast<double>(plan.frames) * n * 48.0;  // positions and velocities
  plan.seconds = steps * step_seconds(model, solver);
  if (is_reference(solver.name)) {
    plan.memory_bytes = kBaseBytes + (m + n) * kReferenceBytes + contacts * kContactBytes;
  } else {
    plan.memory_bytes = kBaseBytes + n * kParticleBytes + m * kConstraintBytes + contacts * kContactBytes;
  }
  return plan;
}

std::string plan_problems(const RunPlan& plan, const std::filesystem::path& out) {
  std::vector<std::string> problems;
  const double memory = available_memory();
  if (memory > 0.0 && plan.memory_bytes > memory)
    problems.push_back(fmt::format("about {} of memory, and {} is available", bytes(plan.memory_bytes), bytes(memory)));
  const std::filesystem::path dir = out.has_parent_path() ? out.parent_path() : std::filesystem::path(".");
  struct statvfs fs {};
  if (::statvfs(dir.c_str(), &fs) == 0) {
    const double free = static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize);
    // The run file and its working copy (runfile/shadow_file.hpp).
    if (2.0 * plan.file_bytes > free)
      problems.push_back(fmt::format("a run file of up to {} (twice that while it runs), and {} is free in {}",
                                     bytes(plan.file_bytes), bytes(free), dir.string()));
  }
  if (plan.seconds > kMaxSeconds)
    problems.push_back(fmt::format("about {} of wall time, more than a day", duration(plan.seconds)));
  std::string text;
  for (size_t i = 0; i < problems.size(); ++i) text += (i ? "; " : "") + problems[i];
  return text;
}

std::string describe_plan(const RunPlan& plan) {
  return fmt::format("{} steps, about {} and {} of memory, a run file of up to {}", plan.steps,
                     duration(plan.seconds), bytes(plan.memory_bytes), bytes(plan.file_bytes));
}

}  // namespace pbdbench
