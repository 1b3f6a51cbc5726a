#include "solver_api/options.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>

#include <sched.h>

namespace pbdbench {

namespace {

constexpr std::array<const char*, kProjectionOrderCount> kOrderNames = {
    "sequential", "reversed", "shuffled", "colored", "jacobi", "grouped_shuffled", "bottom_up"};

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

const char* to_string(SolverFamily family) {
  switch (family) {
    case SolverFamily::PbdSeed: return "pbd-seed";
    case SolverFamily::Pbd: return "pbd";
    case SolverFamily::Xpbd: return "xpbd";
    case SolverFamily::Force: return "force-symplectic";
    case SolverFamily::Reference: return "ref-*";
    case SolverFamily::Global: return "global-*";
  }
  return "unknown";
}

std::string families_text(const OptionRow& row) {
  if (row.families == kAllFamilies) return "every solver";
  std::string out;
  for (int f = 0; f < kSolverFamilyCount; ++f)
    if (option_applies(row, static_cast<SolverFamily>(f)))
      out += (out.empty() ? "" : ", ") + std::string(to_string(static_cast<SolverFamily>(f)));
  return out;
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

// ---------------------------------------------------------------------------------------------
// The option rows (solver_option_rows): each option declared once.

namespace {

OptionBounds any_value() { return {}; }
OptionBounds at_least(double v) { return {v, 1e308, false, false}; }
OptionBounds above(double v) { return {v, 1e308, true, false}; }
OptionBounds within(double lo, double hi) { return {lo, hi, false, false}; }
OptionBounds above_upto(double lo, double hi) { return {lo, hi, true, false}; }
OptionBounds within_open(double lo, double hi) { return {lo, hi, true, true}; }

OptionRow row(std::string key, OptionType type, std::string units, OptionBounds bounds,
              std::vector<std::string> choices, std::string doc) {
  OptionRow r;
  r.key = std::move(key);
  r.type = type;
  r.units = std::move(units);
  r.bounds = bounds;
  r.choices = std::move(choices);
  r.doc = std::move(doc);
  return r;
}

// A number read from an OptionValue that holds an integer or a double.
double number_of(const OptionValue& v) {
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  return std::get<double>(v);
}

OptionRow real(std::string key, double SolverOptions::*field, std::string units, OptionBounds b,
               std::string doc) {
  OptionRow r = row(std::move(key), OptionType::Float, std::move(units), b, {}, std::move(doc));
  r.get = [field](const SolverOptions& o) -> OptionValue { return o.*field; };
  r.set = [field](SolverOptions& o, const OptionValue& v) { o.*field = number_of(v); };
  return r;
}

template <class Int>
OptionRow integer(std::string key, Int SolverOptions::*field, OptionBounds b, std::string doc) {
  OptionRow r = row(std::move(key), OptionType::Int, "", b, {}, std::move(doc));
  r.get = [field](const SolverOptions& o) -> OptionValue { return static_cast<std::int64_t>(o.*field); };
  r.set = [field](SolverOptions& o, const OptionValue& v) {
    o.*field = static_cast<Int>(std::get<std::int64_t>(v));
  };
  return r;
}

OptionRow boolean(std::string key, bool SolverOptions::*field, std::string doc) {
  OptionRow r = row(std::move(key), OptionType::Bool, "", any_value(), {}, std::move(doc));
  r.get = [field](const SolverOptions& o) -> OptionValue { return o.*field; };
  r.set = [field](SolverOptions& o, const OptionValue& v) { o.*field = std::get<bool>(v); };
  return r;
}

OptionRow text(std::string key, std::string SolverOptions::*field,
               std::vector<std::string> choices, std::string doc) {
  OptionRow r = row(std::move(key), OptionType::String, "", any_value(), std::move(choices),
                    std::move(doc));
  r.get = [field](const SolverOptions& o) -> OptionValue { return o.*field; };
  r.set = [field](SolverOptions& o, const OptionValue& v) { o.*field = std::get<std::string>(v); };
  return r;
}

// An enum stored as its name: to_string and parse_* of the enum.
template <class Enum>
OptionRow named(std::string key, Enum SolverOptions::*field, std::vector<std::string> choices,
                bool (*parse)(const std::string&, Enum&), std::string doc) {
  OptionRow r = row(std::move(key), OptionType::String, "", any_value(), std::move(choices),
                    std::move(doc));
  r.get = [field](const SolverOptions& o) -> OptionValue { return std::string(to_string(o.*field)); };
  const std::string path = r.key;
  r.set = [field, parse, path](SolverOptions& o, const OptionValue& v) {
    const std::string& name = std::get<std::string>(v);
    if (!parse(name, o.*field))
      throw std::invalid_argument(path + ": unknown value '" + name + "'");
  };
  return r;
}

OptionRow strings(std::string key, std::vector<std::string> SolverOptions::*field,
                  std::vector<std::string> choices, std::string doc) {
  OptionRow r = row(std::move(key), OptionType::StringList, "", any_value(), std::move(choices),
                    std::move(doc));
  r.get = [field](const SolverOptions& o) -> OptionValue { return o.*field; };
  r.set = [field](SolverOptions& o, const OptionValue& v) {
    o.*field = std::get<std::vector<std::string>>(v);
  };
  return r;
}

std::vector<std::string> order_names() {
  std::vector<std::string> names;
  for (const char* n : kOrderNames) names.emplace_back(n);
  return names;
}

std::string format_number(double v, OptionType type) {
  std::ostringstream s;
  if (type == OptionType::Int) s << static_cast<long long>(v);
  else s << v;
  return s.str();
}

// The problem with one row's value, or "".
std::string check_row(const OptionRow& r, const OptionValue& value) {
  if (r.type == OptionType::Int || r.type == OptionType::Float) {
    const double v = number_of(value);
    const std::string shown = r.key + " = " + format_number(v, r.type);
    if (!std::isfinite(v)) return shown + " is not a finite number";
    const OptionBounds& b = r.bounds;
    if (b.min_exclusive ? !(v > b.min) : !(v >= b.min))
      return shown + (b.min_exclusive ? " must be greater than " : " is below the minimum ") +
             format_number(b.min, r.type);
    if (b.max_exclusive ? !(v < b.max) : !(v <= b.max))
      return shown + (b.max_exclusive ? " must be less than " : " is above the maximum ") +
             format_number(b.max, r.type);
    return {};
  }
  if (r.choices.empty()) return {};
  auto allowed = [&](const std::string& s) {
    return std::find(r.choices.begin(), r.choices.end(), s) != r.choices.end();
  };
  std::string list;
  for (const std::string& c : r.choices) list += (list.empty() ? "" : ", ") + c;
  if (r.type == OptionType::String) {
    const std::string& s = std::get<std::string>(value);
    if (!allowed(s)) return r.key + " = '" + s + "' is not one of " + list;
  } else if (r.type == OptionType::StringList) {
    for (const std::string& s : std::get<std::vector<std::string>>(value))
      if (!allowed(s)) return r.key + ": '" + s + "' is not one of " + list;
  }
  return {};
}

std::vector<OptionRow> make_rows() {
  using S = SolverOptions;
  std::vector<OptionRow> rows;
  // Each row names the families that read it (SolverFamily): its value is checked for their
  // solvers only (validate(family)), and a scenario that sets it for another solver is warned.
  auto add = [&rows](FamilySet families, OptionRow r) {
    r.families = families;
    rows.push_back(std::move(r));
  };
  constexpr FamilySet kSeed = family_bit(SolverFamily::PbdSeed);
  constexpr FamilySet kPbd = family_bit(SolverFamily::Pbd);
  constexpr FamilySet kXpbd = family_bit(SolverFamily::Xpbd);
  constexpr FamilySet kForce = family_bit(SolverFamily::Force);
  constexpr FamilySet kReference = family_bit(SolverFamily::Reference);
  constexpr FamilySet kGlobal = family_bit(SolverFamily::Global);
  constexpr FamilySet kProjecting = kSeed | kPbd | kXpbd;  // projection sweeps
  // Substeps: every family (of ref-*, ref-be and ref-sdirk2 read it; ref-bdf, ref-dae and
  // ref-static integrate to the output time with their own steps).
  constexpr FamilySet kSubstepping = kAllFamilies;
  // Contacts built each substep at the predicted positions (ref-be finds its own).
  constexpr FamilySet kContactBuilding = kProjecting | kForce | kGlobal;
  // [solver]: the keys of every family or of the families named.
  add(kAllFamilies, text("solver.name", &S::name, {},
           "solver: pbd-seed (the seed article's listing), pbd (Mueller et al. 2007), xpbd "
           "(Macklin et al. 2016), force-symplectic (explicit symplectic Euler, penalty "
           "contacts), a reference integrator ref-* or a global solver global-* (`pbdbench list` "
           "names every solver)"));
  add(kProjecting, integer("solver.iterations", &S::iterations, within(1, 100000), "projection sweeps per substep"));
  add(kSubstepping, integer("solver.substeps", &S::substeps, within(1, 100000),
              "substeps per step (Macklin et al. 2019)"));
  add(kProjecting, named("solver.order", &S::order, order_names(), parse_projection_order,
            "order of a sweep: sequential, reversed, shuffled, colored, grouped_shuffled, "
            "bottom_up (Gauss-Seidel) or jacobi (docs/solvers.md)"));
  add(kProjecting, integer("solver.shuffle_seed", &S::shuffle_seed, at_least(0),
              "seed of the shuffled and grouped_shuffled orders"));
  add(kProjecting, real("solver.jacobi_relaxation", &S::jacobi_relaxation, "1", above_upto(0, 2),
           "relaxation omega of the jacobi order"));
  add(kProjecting, boolean("solver.jacobi_averaging", &S::jacobi_averaging,
              "jacobi: divide each correction by the particle's constraint count"));
  add(kContactBuilding, real("solver.contact_margin", &S::contact_margin, "m", at_least(0),
           "contacts closer than this at the predicted positions are built each substep"));
  add(kPbd | kXpbd, named("solver.precision", &S::precision, {"double", "float"}, parse_precision,
            "pbd, xpbd: the precision they compute in: double, or float (the projections in "
            "float32, positions, velocities, predictions and multipliers stored in float32; "
            "docs/solvers.md); pbd-seed is float by its departure D10"));
  add(kPbd | kXpbd, integer("solver.threads", &S::threads, within(0, 1024),
              "pbd, xpbd: threads of the colored and Jacobi sweeps (the results are the same "
              "bits at any count); 0: the cores the run may use (its share under sweep --jobs) "
              "or one, sweep by sweep whichever the run's own timings show faster "
              "(docs/solvers.md)"));
  // [solver.pbd], [solver.xpbd]
  add(kPbd, named("solver.pbd.material", &S::pbd_material, {"compliance", "stiffness"}, parse_pbd_material,
            "pbd: where each constraint's per-iteration stiffness k comes from: compliance (the "
            "scene's one physical material, the *_compliance keys; k derived per substep by the "
            "effective-stiffness law of Mueller et al. 2007, docs/solvers.md) or stiffness (an "
            "explicit override: the *_stiffness keys are k itself)"));
  add(kPbd, boolean("solver.pbd.stiffness_correction", &S::pbd_stiffness_correction,
              "pbd with material = stiffness: use k' = 1 - (1 - k)^(1/iterations) (Mueller et "
              "al. 2007, sec. 3.3)"));
  add(kPbd, real("solver.pbd.velocity_damping", &S::pbd_velocity_damping, "1", within(0, 1),
           "pbd: damping of the motion relative to the rigid modes (Mueller et al. 2007, sec. 3.5)"));
  add(kXpbd, boolean("solver.xpbd.residuals", &S::xpbd_residuals,
              "xpbd: compute the residuals g and h at the end of each step"));
  // [solver.force]
  add(kForce, real("solver.force.contact_stiffness", &S::force_contact_stiffness, "N/m", above(0),
           "force-symplectic: penalty stiffness k_c of a contact, force k_c (-C) while C < 0"));
  add(kForce, real("solver.force.contact_damping", &S::force_contact_damping, "N s/m", at_least(0),
           "force-symplectic: contact damping d_c, force -d_c v_n on the relative normal "
           "velocity while C < 0 (approaching or separating; the contact force never pulls)"));
  // [solver.seed]
  add(kSeed, real("solver.seed.damping", &S::seed_damping, "1", within(0, 1),
           "pbd-seed: velocity damping factor alpha of step 4"));
  add(kSeed, boolean("solver.seed.damping_rescale", &S::seed_damping_rescale,
              "pbd-seed: use alpha^(dt / reference_dt)"));
  add(kSeed, boolean("solver.seed.gravity_rescale", &S::seed_gravity_rescale,
              "pbd-seed: scale gravity by reference_dt / dt"));
  add(kSeed, real("solver.seed.reference_dt", &S::seed_reference_dt, "s", above(0),
           "pbd-seed: the time step alpha was tuned at"));
  add(kSeed, real("solver.seed.restitution", &S::seed_restitution, "1", within(0, 1),
           "pbd-seed: restitution of the listing's collision response"));
  add(kSeed, strings("solver.seed.fixes", &S::seed_fixes, seed_departure_ids(),
              "pbd-seed: ids of the departures from Mueller et al. 2007 to correct"));
  add(kSeed, text("solver.seed.iteration_schedule", &S::seed_iteration_schedule,
           {"fixed", "dynamic", "mixed"},
           "pbd-seed: sweeps per substep: fixed (solver.iterations), dynamic (article 4.1: 10 on "
           "the run's first step, then 3, or 5 when the fastest particle is faster than "
           "fast_speed) or mixed (5.3: 1 when the fastest particle is faster than fast_speed, "
           "else 3); speeds at the start of the step"));
  add(kSeed, real("solver.seed.fast_speed", &S::seed_fast_speed, "m/s", above(0),
           "pbd-seed: the speed above which a particle is fast (iteration_schedule, "
           "dynamic_inverse_mass)"));
  add(kSeed, text("solver.seed.backup", &S::seed_backup, {"before_forces", "after_damping"},
           "pbd-seed: where old_pos is backed up: before_forces (step 1, the listing) or "
           "after_damping (after step 4, the placement article 3.1a warns against: step 5 then "
           "sets every velocity to 0)"));
  add(kSeed, boolean("solver.seed.dynamic_inverse_mass", &S::seed_dynamic_inverse_mass,
              "pbd-seed: article 4.2, each step every dynamic particle's inverse mass is 0.1 "
              "(1/kg) when it is faster than fast_speed, else 0.3; pinned stay 0"));
  add(kSeed, boolean("solver.seed.graded_inverse_mass", &S::seed_graded_inverse_mass,
              "pbd-seed: article 4.2, inverse masses graded from the pins: 0.3 min(1, d / d_c) "
              "(1/kg), d the hop distance from the nearest pin over constraint edges, d_c half "
              "the largest (at least 1); needs a pin"));
  // [solver.ref]
  add(kReference, real("solver.ref.rtol", &S::ref_rtol, "1", within_open(0, 1),
           "reference: relative tolerance of the adaptive integrators and of every Newton solve"));
  add(kReference, real("solver.ref.atol", &S::ref_atol, "m", above(0), "reference: absolute tolerance of positions"));
  add(kReference, real("solver.ref.atol_velocity", &S::ref_atol_velocity, "m/s", above(0),
           "ref-bdf: absolute tolerance of velocities"));
  add(kReference, text("solver.ref.linear_solver", &S::ref_linear_solver, {"reduced", "full"},
           "ref-bdf, ref-be, ref-sdirk2: Newton systems solved through the n x n reduced matrix "
           "M + gamma D + gamma^2 K (Cholesky, LU fallback) or by LU on the whole 2n x 2n matrix"));
  add(kReference, integer("solver.ref.max_steps", &S::ref_max_steps, within(1, 1000000000),
              "reference: internal steps allowed to advance by one output step"));
  add(kReference, integer("solver.ref.max_newton", &S::ref_max_newton, within(1, 100000),
              "reference: Newton iterations allowed per nonlinear solve"));
  add(kReference, boolean("solver.ref.ignore_colliders", &S::ref_ignore_colliders,
              "reference: run a scene that has colliders without its contacts (ref-be "
              "simulates them, the other references refuse them; the run file records this key)"));
  add(kReference, real("solver.ref.barrier_distance", &S::ref_barrier_distance, "m", above(0),
           "ref-be with contact: d_hat, the IPC barrier acts on gaps below this"));
  add(kReference, real("solver.ref.barrier_stiffness", &S::ref_barrier_stiffness, "N/m", at_least(0),
           "ref-be with contact: kappa, the barrier's stiffness; 0 = the heaviest dynamic "
           "particle's weight per d_hat"));
  add(kReference, real("solver.ref.friction_velocity", &S::ref_friction_velocity, "m/s", above(0),
           "ref-be with contact: eps_v, friction is smoothed to 0 below this sliding speed"));
  // [solver.global]
  add(kGlobal, real("solver.global.tolerance", &S::global_tolerance, "m", above(0),
           "global-*: converged when the step's KKT residual, in position units, is below this"));
  add(kGlobal, integer("solver.global.max_iterations", &S::global_max_iterations, within(1, 1000000),
              "global-*: outer iterations allowed per step (Newton, or Levenberg-Marquardt for "
              "global-ceres)"));
  add(kGlobal, real("solver.global.regularization", &S::global_regularization, "1", above_upto(0, 1),
           "global-*: eta; a rigid constraint or contact r gets the augmented-Lagrangian penalty "
           "1 / (eta w_r), w_r its generalised inverse mass"));
  add(kGlobal, text("solver.global.cg_preconditioner", &S::global_cg_preconditioner,
           {"incomplete_cholesky", "jacobi"}, "global-cg: preconditioner of the assembled matrix"));
  add(kGlobal, boolean("solver.global.matrix_free", &S::global_matrix_free,
              "global-cg: apply the Newton matrix term by term, never assembled (Jacobi "
              "preconditioner)"));
  add(kGlobal, real("solver.global.cg_tolerance", &S::global_cg_tolerance, "1", within_open(0, 1),
           "global-cg: relative residual at which each conjugate-gradient solve stops"));
  add(kGlobal, integer("solver.global.cg_max_iterations", &S::global_cg_max_iterations,
              within(1, 100000000), "global-cg: conjugate-gradient iterations per solve"));
  add(kGlobal, boolean("solver.global.factor_reuse", &S::global_factor_reuse,
              "global-cholmod: solve a Newton system by conjugate gradients preconditioned with "
              "the last Cholesky factorisation while they converge within reuse_iterations, "
              "where a factorisation costs at least two of their iterations (false: factorise "
              "every Newton iteration)"));
  add(kGlobal, real("solver.global.reuse_tolerance", &S::global_reuse_tolerance, "1", within_open(0, 1),
           "global-cholmod with factor_reuse: relative residual at which such a solve stops"));
  add(kGlobal, integer("solver.global.reuse_iterations", &S::global_reuse_iterations,
              within(1, 10000),
              "global-cholmod with factor_reuse: a solve needing more iterations factorises the "
              "next Newton system; one not converged at 4 times this is factorised at once"));
  add(kGlobal, text("solver.global.ceres_method", &S::global_ceres_method,
           {"levenberg_marquardt", "dogleg"}, "global-ceres: the trust-region strategy"));
  return rows;
}

}  // namespace

const std::vector<OptionRow>& solver_option_rows() {
  static const std::vector<OptionRow> rows = make_rows();
  return rows;
}

const OptionRow* find_solver_option(const std::string& key) {
  for (const OptionRow& r : solver_option_rows())
    if (r.key == key) return &r;
  return nullptr;
}

namespace {

// The bounds and choices of the rows read by `families`, and their checks across fields.
std::string validate_rows(const SolverOptions& o, FamilySet families) {
  for (const OptionRow& r : solver_option_rows())
    if ((r.families & families) != 0)
      if (std::string problem = check_row(r, r.get(o)); !problem.empty()) return problem;
  if ((families & family_bit(SolverFamily::PbdSeed)) != 0 && o.seed_dynamic_inverse_mass &&
      o.seed_graded_inverse_mass)
    return "solver.seed.dynamic_inverse_mass and solver.seed.graded_inverse_mass are both true: "
           "each sets every inverse mass, choose one";
  return {};
}

}  // namespace

std::string SolverOptions::validate() const {
  // solver.name is checked against the catalogue by make_solver (catalog/) and the schema's
  // choices; every other row by its bounds or choices.
  return validate_rows(*this, kAllFamilies);
}

std::string SolverOptions::validate(SolverFamily family) const {
  return validate_rows(*this, family_bit(family));
}

}  // namespace pbdbench
