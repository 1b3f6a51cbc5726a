// Options of the solvers: a flat struct with every default in place, able to validate itself.
// Each option is declared once, as a row of solver_option_rows() (options.cpp): its key, type,
// units, bounds, choices and doc, and how to read and write its field. The scenario schema
// (config/schema.cpp) makes its entries from the rows, the loader sets the fields through them,
// and validate() checks the bounds and choices they declare; the key path is in each comment.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <variant>
#include <vector>

namespace pbdbench {

// Order in which a sweep visits the constraints.
enum class ProjectionOrder : std::uint8_t {
  Sequential,  // Gauss-Seidel in the model's order (contacts after the model's constraints)
  Reversed,    // Gauss-Seidel in reverse order
  Shuffled,    // Gauss-Seidel in a random order drawn from shuffle_seed, redrawn every sweep
  Colored,     // Gauss-Seidel colour by colour (greedy graph colouring; constraints of one colour
               // share no dynamic particle, so their order within the colour does not matter)
  Jacobi,      // all corrections computed from the same positions, then applied, scaled by
               // jacobi_relaxation (and divided by each particle's constraint count when
               // jacobi_averaging)
  GroupedShuffled,  // the seed article's 5.4 "constraint groups, shuffled every frame": the
               // items are split into groups, the connected components of the graph in which
               // two items are adjacent when they share a dynamic particle (inv_mass > 0);
               // groups are visited in the order of their smallest item index, and within a
               // group in a random permutation drawn once per step from shuffle_seed and the
               // step index (the same in every sweep and substep of the step; Shuffled redraws
               // one global permutation every sweep)
  BottomUp,    // a support order, the practical stand-in for the article's 5.4 "topological
               // ordering of the constraint dependency graph": when contacts form a cycle
               // (A pushes into B, B into C, C into A) that graph has a cycle and no
               // topological order exists. Instead the items are sorted by the height (along
               // up = -gravity, +y without gravity) of their lowest dynamic particle at the
               // start of the substep, lowest first, ties by index; items without a dynamic
               // particle (they move nothing) come last
};

// The number of ProjectionOrder values (for tables of names).
inline constexpr int kProjectionOrderCount = 7;

const char* to_string(ProjectionOrder order);  // "sequential", "reversed", ...
// Parses the names above; returns false when unknown.
bool parse_projection_order(const std::string& name, ProjectionOrder& out);

// The precision pbd and xpbd compute in (solver.precision).
enum class Precision : std::uint8_t {
  Double,  // double
  Float,   // float32: the projections computed in float, positions, velocities, predicted
           // positions and multipliers stored in float (docs/solvers.md, "Precision")
};

const char* to_string(Precision precision);  // "double", "float"
// Parses the names above; returns false when unknown.
bool parse_precision(const std::string& name, Precision& out);

// Where pbd takes its per-iteration stiffness k of each constraint from (solver.pbd.material;
// solvers/pbd_material.hpp, docs/solvers.md "One material").
enum class PbdMaterial : std::uint8_t {
  Compliance,  // the default: the scene's physical material, its compliance alpha; k is derived
               // from it per substep by the effective-stiffness law of Mueller et al. 2007
  Stiffness,   // an explicit override: the scene's *_stiffness keys, k itself (the studies of
               // k: Mueller 2007's own experiments, the seed article's material)
};

const char* to_string(PbdMaterial material);  // "compliance", "stiffness"
// Parses the names above; returns false when unknown.
bool parse_pbd_material(const std::string& name, PbdMaterial& out);



// The families of solvers, one per option table: each reads its own options
// (OptionRow::families). The catalogue (catalog/) says which family each solver is of; a new
// PBD variant takes the family whose options it reads.
enum class SolverFamily : std::uint8_t {
  PbdSeed,    // pbd-seed: the seed article's listing (solver.seed.*)
  Pbd,        // pbd: Mueller et al. 2007 (solver.pbd.*)
  Xpbd,       // xpbd: Macklin et al. 2016 (solver.xpbd.*)
  Force,      // force-symplectic (solver.force.*)
  Reference,  // ref-*: SUNDIALS integrators of the scene's energy (solver.ref.*)
  Global,     // global-*: every step the converged global projection (solver.global.*)
};
inline constexpr int kSolverFamilyCount = 6;

// "pbd-seed", "pbd", "xpbd", "force-symplectic", "ref-*", "global-*": the solvers of a family.
const char* to_string(SolverFamily family);

// A set of families, one bit each (1 << SolverFamily).
using FamilySet = std::uint8_t;
inline constexpr FamilySet family_bit(SolverFamily f) {
  return static_cast<FamilySet>(1u << static_cast<unsigned>(f));
}
inline constexpr FamilySet kAllFamilies = (1u << kSolverFamilyCount) - 1;

// The CPUs this process may run on (its affinity mask), at least 1, and at most the share in the
// environment variable PBDBENCH_CORES when it holds a whole number >= 1 (sweep --jobs N gives
// each of its runs max(1, cores / N)): what solver.threads = 0 means.
inline constexpr const char* kCoresVariable = "PBDBENCH_CORES";
int available_cores();

// solver.threads resolved: `threads` when >= 1, else available_cores().
int resolve_threads(int threads);

// The ids of the seed listing's departures from Mueller et al. 2007 that solver.seed.fixes may
// correct, "D1" ... "D11" (docs/seed-departures.md).
const std::vector<std::string>& seed_departure_ids();

// Keys shared by every PBD-family solver: [solver] table.
struct SolverOptions {
  std::string name = "xpbd";        // solver.name: "pbd-seed" | "pbd" | "xpbd" |
                                    // "force-symplectic" | a reference or global solver
  int iterations = 10;              // solver.iterations: projection sweeps per substep, >= 1
  int substeps = 1;                 // solver.substeps: substeps per step (Macklin 2019), >= 1
  ProjectionOrder order = ProjectionOrder::Sequential;  // solver.order
  std::uint64_t shuffle_seed = 1;   // solver.shuffle_seed: seed of the Shuffled order
  double jacobi_relaxation = 1.0;   // solver.jacobi_relaxation: omega in (0, 2]
  bool jacobi_averaging = true;     // solver.jacobi_averaging: divide by constraint count
  double contact_margin = 0.0;      // solver.contact_margin: m, >= 0; contacts with C < margin
                                    // at the predicted positions are built each substep
  Precision precision = Precision::Double;  // solver.precision: pbd and xpbd, "double" or
                                    // "float" (the projections computed in float32, the state
                                    // stored as float32); pbd-seed is float by its D10, the
                                    // others ignore it
  int threads = 0;                  // solver.threads: threads of the colored and Jacobi sweeps
                                    // (pbd, xpbd); 0 (the default) = the cores this process may
                                    // run on (available_cores(): its share under sweep --jobs)
                                    // or one, for each sweep whichever its timings show faster
                                    // (solvers/sweep_threads.hpp: on a shared machine two
                                    // threads can be slower than one)

  // [solver.pbd]: Mueller et al. 2007.
  PbdMaterial pbd_material = PbdMaterial::Compliance;  // solver.pbd.material
  bool pbd_stiffness_correction = false;  // solver.pbd.stiffness_correction: k' = 1-(1-k)^(1/n)
                                          // of an explicit k (material = "stiffness" only)
  double pbd_velocity_damping = 0.0;      // solver.pbd.velocity_damping: k_damping in [0, 1],
                                          // sec. 3.5, damps motion relative to the rigid modes

  // [solver.xpbd]: Macklin et al. 2016 (the damping beta is per constraint, in the model).
  bool xpbd_residuals = true;  // solver.xpbd.residuals: compute g and h at the end of each step

  // [solver.force]: force-symplectic, explicit symplectic Euler with penalty contacts
  // (solvers/force_symplectic.hpp). Contact force F = max(0, k_c (-C) - d_c v_n) while C < 0.
  double force_contact_stiffness = 1e4;  // solver.force.contact_stiffness: k_c, N/m, > 0
  double force_contact_damping = 0.0;    // solver.force.contact_damping: d_c, N s/m, >= 0, on
                                         // the relative normal velocity v_n (> 0 separating)

  // [solver.seed]: the seed article's listing (docs/seed-departures.md).
  double seed_damping = 0.98;          // solver.seed.damping: alpha of step 4, in [0, 1]
  bool seed_damping_rescale = false;   // solver.seed.damping_rescale: alpha^(dt/reference_dt) (4.4)
  bool seed_gravity_rescale = false;   // solver.seed.gravity_rescale: g * reference_dt/dt (4.4)
  double seed_reference_dt = 0.02;     // solver.seed.reference_dt: s, > 0, the dt alpha was tuned at
  double seed_restitution = 0.2;       // solver.seed.restitution: in [0, 1], listing 3.4
  std::vector<std::string> seed_fixes; // solver.seed.fixes: ids of departures to correct (D1, ...)
  // The article's tuning options (docs/seed-departures.md, "tuning options from sections 4 and
  // 5"); the defaults are the listing. "Speed" is |v| of a particle at the start of the step.
  std::string seed_iteration_schedule = "fixed";  // solver.seed.iteration_schedule: "fixed"
                                       // (iterations), "dynamic" (4.1: 10 on the first step of
                                       // the run, then 3, or 5 when the fastest particle is faster
                                       // than fast_speed) or "mixed" (5.3: 1 when the fastest
                                       // particle is faster than fast_speed, else 3)
  double seed_fast_speed = 1.0;        // solver.seed.fast_speed: m/s, > 0, "fast" above this
  std::string seed_backup = "before_forces";  // solver.seed.backup: where old_pos is backed up:
                                       // "before_forces" (step 1, the listing) or "after_damping"
                                       // (3.1a's warned-against placement, after step 4)
  bool seed_dynamic_inverse_mass = false;  // solver.seed.dynamic_inverse_mass: 4.2, each step a
                                       // dynamic particle's inverse mass is 0.1 when it is faster
                                       // than fast_speed, else 0.3 (pinned stay 0)
  bool seed_graded_inverse_mass = false;   // solver.seed.graded_inverse_mass: 4.2, inverse masses
                                       // graded from the pins, w_i = 0.3 min(1, d_i / d_c)

  // [solver.ref]: the reference integrators (reference/, docs/reference.md).
  double ref_rtol = 1e-8;             // solver.ref.rtol: relative tolerance of the adaptive
                                      // integrators (ref-bdf, ref-dae), and of every Newton solve
  double ref_atol = 1e-10;            // solver.ref.atol: absolute tolerance of positions, m
  double ref_atol_velocity = 1e-8;    // solver.ref.atol_velocity: absolute tolerance of
                                      // velocities, m/s (ref-bdf)
  std::string ref_linear_solver = "reduced";  // solver.ref.linear_solver: "reduced" (the n x n
                                      // Schur complement, Cholesky with an LU fallback) or "full"
                                      // (KLU on the whole 2n x 2n Newton matrix)
  long ref_max_steps = 1000000;       // solver.ref.max_steps: internal steps per output step
  int ref_max_newton = 50;            // solver.ref.max_newton: Newton iterations per solve
  bool ref_ignore_colliders = false;  // solver.ref.ignore_colliders: run a scene that has
                                      // colliders without its contacts (ref-be simulates them)
  double ref_barrier_distance = 1e-3;  // solver.ref.barrier_distance: d_hat, m, > 0: ref-be's
                                      // contact barrier acts on gaps below this
  double ref_barrier_stiffness = 0.0;  // solver.ref.barrier_stiffness: kappa, N/m, >= 0; 0 =
                                      // automatic (reference/ref_contact.hpp)
  double ref_friction_velocity = 1e-3;  // solver.ref.friction_velocity: eps_v, m/s, > 0: ref-be's
                                      // friction is smoothed below this sliding speed

  // [solver.global]: the global projection solvers global-cholmod, global-cg, global-ceres
  // (reference/global_problem.hpp, docs/global.md).
  double global_tolerance = 1e-9;     // solver.global.tolerance: m, the step is converged when
                                      // its KKT residual in position units is below this
  int global_max_iterations = 200;    // solver.global.max_iterations: outer iterations (Newton
                                      // steps; Levenberg-Marquardt iterations for global-ceres)
  double global_regularization = 1e-4;  // solver.global.regularization: eta, the augmented
                                      // Lagrangian's penalty of a rigid constraint or contact r is
                                      // 1 / (eta w_r), w_r its generalised inverse mass
  std::string global_cg_preconditioner = "incomplete_cholesky";  // solver.global.cg_preconditioner:
                                      // "incomplete_cholesky" or "jacobi" (global-cg)
  bool global_matrix_free = false;    // solver.global.matrix_free: global-cg applies the Newton
                                      // matrix term by term instead of assembling it (Jacobi
                                      // preconditioner)
  double global_cg_tolerance = 1e-10;  // solver.global.cg_tolerance: relative residual of each
                                      // conjugate-gradient solve (global-cg)
  int global_cg_max_iterations = 100000;  // solver.global.cg_max_iterations (global-cg)
  bool global_factor_reuse = true;    // solver.global.factor_reuse: global-cholmod solves a Newton
                                      // system by conjugate gradients preconditioned with the
                                      // last Cholesky factorisation (of an earlier Newton matrix)
                                      // while that converges quickly, where a factorisation costs
                                      // at least two of its iterations; false: a factorisation
                                      // every Newton iteration (reference/global_newton.hpp)
  double global_reuse_tolerance = 1e-14;  // solver.global.reuse_tolerance: relative residual
                                      // |b - A dx| <= this |b| of such a solve (global-cholmod)
  int global_reuse_iterations = 6;    // solver.global.reuse_iterations: a solve that needs more
                                      // iterations than this makes the next Newton system
                                      // factorised; one not converged at 4 times this is
                                      // factorised at once (global-cholmod)
  std::string global_ceres_method = "levenberg_marquardt";  // solver.global.ceres_method:
                                      // "levenberg_marquardt" or "dogleg" (global-ceres)

  // Returns an empty string when valid, else a message naming the field and the bound broken,
  // e.g. "solver.iterations = 0 is below the minimum 1": every row's bounds and choices (except
  // solver.name's, which the catalogue checks), and the checks across fields.
  std::string validate() const;
  // The same for the solvers of one family: only the rows it reads (OptionRow::families) and
  // its own checks across fields. The options of other families are not read, so not checked
  // (config/ warns when a scenario sets them: config::unread_solver_keys). make_solver uses this.
  std::string validate(SolverFamily family) const;
};

// ---------------------------------------------------------------------------------------------
// The option rows: each [solver] key declared once.

enum class OptionType : std::uint8_t { Bool, Int, Float, String, StringList };

// A value of an option as the schema holds it: Int options as int64, enums as their names.
using OptionValue = std::variant<bool, std::int64_t, double, std::string, std::vector<std::string>>;

// Numeric bounds of an Int or Float option (unbounded: +-1e308).
struct OptionBounds {
  double min = -1e308;
  double max = 1e308;
  bool min_exclusive = false;
  bool max_exclusive = false;
};

struct OptionRow {
  std::string key;    // "solver.iterations", "solver.pbd.velocity_damping"
  OptionType type = OptionType::Float;
  std::string units;  // "m", "N/m", "1", "" for none (Int, Bool, String)
  OptionBounds bounds;
  std::vector<std::string> choices;  // allowed values of a String / StringList; empty: any
  std::string doc;                   // one line
  FamilySet families = kAllFamilies;  // the families whose solvers read it
  std::function<OptionValue(const SolverOptions&)> get;          // the field's value
  std::function<void(SolverOptions&, const OptionValue&)> set;   // throws std::invalid_argument
                                                                  // for a name no enum has
};

// Every solver option, in the schema's order (the keys every solver reads, then [solver.pbd],
// [solver.xpbd], [solver.force], [solver.seed], [solver.ref], [solver.global]). The default of a
// row is its get() of SolverOptions{}.
const std::vector<OptionRow>& solver_option_rows();

// The row of `key`, or nullptr.
const OptionRow* find_solver_option(const std::string& key);

// Whether the solvers of `family` read the option of `row`.
inline bool option_applies(const OptionRow& row, SolverFamily family) {
  return (row.families & family_bit(family)) != 0;
}

// The families of `row` in words: "pbd-seed, pbd, xpbd", "every solver".
std::string families_text(const OptionRow& row);

}  // namespace pbdbench
