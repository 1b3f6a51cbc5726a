#include "solvers/options.hpp"

#include "solvers/solver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <thread>

#include <sched.h>

namespace pbdbench {

namespace {

constexpr std::array<const char*, kProjectionOrderCount> kOrderNames = {
    "sequential", "reversed", "shuffled", "colored", "jacobi", "grouped_shuffled", "bottom_up"};

template <class T>
std::string out_of_range(const char* field, T value, const char* relation, T bound) {
  std::ostringstream s;
  s << field << " = " << value << " is " << relation << " " << bound;
  return s.str();
}

}  // namespace

const char* to_string(ProjectionOrder order) {
  return kOrderNames[static_cast<size_t>(order)];
}

bool parse_projection_order(const std::string& name, ProjectionOrder& out) {
  for (size_t i = 0; i < kOrderNames.size(); ++i) {
    if (name == kOrderNames[i]) {
      out = static_cast<ProjectionOrder>(i);
      return true;
    }
  }
  return false;
}

const char* to_string(Precision precision) {
  return precision == Precision::Float ? "float" : "double";
}

bool parse_precision(const std::string& name, Precision& out) {
  if (name == "double") out = Precision::Double;
  else if (name == "float") out = Precision::Float;
  else return false;
  return true;
}

const char* to_string(PbdMaterial material) {
  return material == PbdMaterial::Stiffness ? "stiffness" : "compliance";
}

bool parse_pbd_material(const std::string& name, PbdMaterial& out) {
  if (name == "compliance") out = PbdMaterial::Compliance;
  else if (name == "stiffness") out = PbdMaterial::Stiffness;
  else return false;
  return true;
}

int available_cores() {
  int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) cores = std::max(1, CPU_COUNT(&set));
  // A share given by a parent that runs several runs at once (sweep --jobs, harness/sweep.cpp).
  if (const char* share = std::getenv(kCoresVariable)) {
    char* end = nullptr;
    const long n = std::strtol(share, &end, 10);
    if (end != share && *end == '\0' && n >= 1) cores = std::min(cores, static_cast<int>(std::min(n, 1024L)));
  }
  return cores;
}

int resolve_threads(int threads) { return threads >= 1 ? threads : available_cores(); }

const std::vector<std::string>& seed_departure_ids() {
  static const std::vector<std::string> ids = {"D1", "D2", "D3", "D4", "D5", "D6",
                                               "D7", "D8", "D9", "D10", "D11"};
  return ids;
}

std::string SolverOptions::validate() const {
  {
    std::string names;
    bool known = false;
    for (const SolverInfo& s : solver_catalog()) {
      known = known || s.name == name;
      names += (names.empty() ? "" : ", ") + s.name;
    }
    if (!known) return "solver.name = '" + name + "' is not one of " + names;
  }
  if (iterations < 1) return out_of_range("solver.iterations", iterations, "below the minimum", 1);
  if (iterations > 100000)
    return out_of_range("solver.iterations", iterations, "above the maximum", 100000);
  if (substeps < 1) return out_of_range("solver.substeps", substeps, "below the minimum", 1);
  if (substeps > 100000)
    return out_of_range("solver.substeps", substeps, "above the maximum", 100000);
  if (threads < 0) return out_of_range("solver.threads", threads, "below the minimum", 0);
  if (threads > 1024) return out_of_range("solver.threads", threads, "above the maximum", 1024);
  if (!(jacobi_relaxation > 0.0))
    return out_of_range("solver.jacobi_relaxation", jacobi_relaxation, "not above", 0.0);
  if (!(jacobi_relaxation <= 2.0))
    return out_of_range("solver.jacobi_relaxation", jacobi_relaxation, "above the maximum", 2.0);
  if (!(contact_margin >= 0.0) || !std::isfinite(contact_margin))
    return out_of_range("solver.contact_margin", contact_margin, "below the minimum", 0.0);
  if (!(pbd_velocity_damping >= 0.0 && pbd_velocity_damping <= 1.0))
    return "solver.pbd.velocity_damping = " + std::to_string(pbd_velocity_damping) +
           " is outside [0, 1]";
  if (!(force_contact_stiffness > 0.0) || !std::isfinite(force_contact_stiffness))
    return out_of_range("solver.force.contact_stiffness", force_contact_stiffness, "not above", 0.0);
  if (!(force_contact_damping >= 0.0) || !std::isfinite(force_contact_damping))
    return out_of_range("solver.force.contact_damping", force_contact_damping, "below the minimum",
                        0.0);
  if (!(seed_damping >= 0.0 && seed_damping <= 1.0))
    return "solver.seed.damping = " + std::to_string(seed_damping) + " is outside [0, 1]";
  if (!(seed_reference_dt > 0.0) || !std::isfinite(seed_reference_dt))
    return out_of_range("solver.seed.reference_dt", seed_reference_dt, "not above", 0.0);
  if (!(seed_restitution >= 0.0 && seed_restitution <= 1.0))
    return "solver.seed.restitution = " + std::to_string(seed_restitution) + " is outside [0, 1]";
  if (seed_iteration_schedule != "fixed" && seed_iteration_schedule != "dynamic" &&
      seed_iteration_schedule != "mixed")
    return "solver.seed.iteration_schedule = '" + seed_iteration_schedule +
           "' is not one of fixed, dynamic, mixed";
  if (!(seed_fast_speed > 0.0) || !std::isfinite(seed_fast_speed))
    return out_of_range("solver.seed.fast_speed", seed_fast_speed, "not above", 0.0);
  if (seed_backup != "before_forces" && seed_backup != "after_damping")
    return "solver.seed.backup = '" + seed_backup + "' is not one of before_forces, after_damping";
  if (seed_dynamic_inverse_mass && seed_graded_inverse_mass)
    return "solver.seed.dynamic_inverse_mass and solver.seed.graded_inverse_mass are both true: "
           "each sets every inverse mass, choose one";
  if (!(ref_rtol > 0.0 && ref_rtol < 1.0))
    return "solver.ref.rtol = " + std::to_string(ref_rtol) + " is outside (0, 1)";
  if (!(ref_atol > 0.0) || !std::isfinite(ref_atol))
    return out_of_range("solver.ref.atol", ref_atol, "not above", 0.0);
  if (!(ref_atol_velocity > 0.0) || !std::isfinite(ref_atol_velocity))
    return out_of_range("solver.ref.atol_velocity", ref_atol_velocity, "not above", 0.0);
  if (ref_linear_solver != "reduced" && ref_linear_solver != "full")
    return "solver.ref.linear_solver = '" + ref_linear_solver + "' is not one of reduced, full";
  if (ref_max_steps < 1) return out_of_range("solver.ref.max_steps", ref_max_steps, "below the minimum", 1L);
  if (ref_max_steps > 1000000000L)
    return out_of_range("solver.ref.max_steps", ref_max_steps, "above the maximum", 1000000000L);
  if (ref_max_newton < 1) return out_of_range("solver.ref.max_newton", ref_max_newton, "below the minimum", 1);
  if (ref_max_newton > 100000)
    return out_of_range("solver.ref.max_newton", ref_max_newton, "above the maximum", 100000);
  if (!(ref_barrier_distance > 0.0) || !std::isfinite(ref_barrier_distance))
    return out_of_range("solver.ref.barrier_distance", ref_barrier_distance, "not above", 0.0);
  if (!(ref_barrier_stiffness >= 0.0) || !std::isfinite(ref_barrier_stiffness))
    return out_of_range("solver.ref.barrier_stiffness", ref_barrier_stiffness, "below", 0.0);
  if (!(ref_friction_velocity > 0.0) || !std::isfinite(ref_friction_velocity))
    return out_of_range("solver.ref.friction_velocity", ref_friction_velocity, "not above", 0.0);
  if (!(global_tolerance > 0.0) || !std::isfinite(global_tolerance))
    return out_of_range("solver.global.tolerance", global_tolerance, "not above", 0.0);
  if (global_max_iterations < 1)
    return out_of_range("solver.global.max_iterations", global_max_iterations, "below the minimum", 1);
  if (global_max_iterations > 1000000)
    return out_of_range("solver.global.max_iterations", global_max_iterations, "above the maximum", 1000000);
  if (!(global_regularization > 0.0 && global_regularization <= 1.0))
    return "solver.global.regularization = " + std::to_string(global_regularization) +
           " is outside (0, 1]";
  if (global_cg_preconditioner != "incomplete_cholesky" && global_cg_preconditioner != "jacobi")
    return "solver.global.cg_preconditioner = '" + global_cg_preconditioner +
           "' is not one of incomplete_cholesky, jacobi";
  if (!(global_cg_tolerance > 0.0 && global_cg_tolerance < 1.0))
    return "solver.global.cg_tolerance = " + std::to_string(global_cg_tolerance) +
           " is outside (0, 1)";
  if (global_cg_max_iterations < 1)
    return out_of_range("solver.global.cg_max_iterations", global_cg_max_iterations, "below the minimum", 1);
  if (global_cg_max_iterations > 100000000)
    return out_of_range("solver.global.cg_max_iterations", global_cg_max_iterations, "above the maximum", 100000000);
  if (global_ceres_method != "levenberg_marquardt" && global_ceres_method != "dogleg")
    return "solver.global.ceres_method = '" + global_ceres_method +
           "' is not one of levenberg_marquardt, dogleg";
  const auto& ids = seed_departure_ids();
  for (const std::string& f : seed_fixes)
    if (std::find(ids.begin(), ids.end(), f) == ids.end())
      return "solver.seed.fixes: '" + f + "' is not a departure id (D1 ... D" +
             std::to_string(ids.size()) + ")";
  return {};
}

}  // namespace pbdbench
