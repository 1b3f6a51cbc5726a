// Options of the PBD-family solvers: flat structs with every default in place, each able to
// validate itself. The scenario schema (config/) maps the keys of a [solver] table onto these
// fields one to one; the key path is in each comment.
#pragma once

#include <cstdint>
#include <string>
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
};

const char* to_string(ProjectionOrder order);  // "sequential", "reversed", ...
// Parses the names above; returns false when unknown.
bool parse_projection_order(const std::string& name, ProjectionOrder& out);

// The ids of the seed listing's departures from Mueller et al. 2007 that solver.seed.fixes may
// correct, "D1" ... "D11" (docs/seed-departures.md).
const std::vector<std::string>& seed_departure_ids();

// Keys shared by every PBD-family solver: [solver] table.
struct SolverOptions {
  std::string name = "xpbd";        // solver.name: "pbd-seed" | "pbd" | "xpbd"
  int iterations = 10;              // solver.iterations: projection sweeps per substep, >= 1
  int substeps = 1;                 // solver.substeps: substeps per step (Macklin 2019), >= 1
  ProjectionOrder order = ProjectionOrder::Sequential;  // solver.order
  std::uint64_t shuffle_seed = 1;   // solver.shuffle_seed: seed of the Shuffled order
  double jacobi_relaxation = 1.0;   // solver.jacobi_relaxation: omega in (0, 2]
  bool jacobi_averaging = true;     // solver.jacobi_averaging: divide by constraint count
  double contact_margin = 0.0;      // solver.contact_margin: m, >= 0; contacts with C < margin
                                    // at the predicted positions are built each substep

  // [solver.pbd]: Mueller et al. 2007.
  bool pbd_stiffness_correction = false;  // solver.pbd.stiffness_correction: k' = 1-(1-k)^(1/n)
  double pbd_velocity_damping = 0.0;      // solver.pbd.velocity_damping: k_damping in [0, 1],
                                          // sec. 3.5, damps motion relative to the rigid modes

  // [solver.xpbd]: Macklin et al. 2016 (the damping beta is per constraint, in the model).
  bool xpbd_residuals = true;  // solver.xpbd.residuals: compute g and h at the end of each step

  // [solver.seed]: the seed article's listing (docs/seed-departures.md).
  double seed_damping = 0.98;          // solver.seed.damping: alpha of step 4, in [0, 1]
  bool seed_damping_rescale = false;   // solver.seed.damping_rescale: alpha^(dt/reference_dt) (4.4)
  bool seed_gravity_rescale = false;   // solver.seed.gravity_rescale: g * reference_dt/dt (4.4)
  double seed_reference_dt = 0.02;     // solver.seed.reference_dt: s, > 0, the dt alpha was tuned at
  double seed_restitution = 0.2;       // solver.seed.restitution: in [0, 1], listing 3.4
  std::vector<std::string> seed_fixes; // solver.seed.fixes: ids of departures to correct (D1, ...)

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
                                      // colliders without its contacts (the references have none)

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
  std::string global_ceres_method = "levenberg_marquardt";  // solver.global.ceres_method:
                                      // "levenberg_marquardt" or "dogleg" (global-ceres)

  // Returns an empty string when valid, else a message naming the field and the bound broken,
  // e.g. "solver.iterations = 0 is below the minimum 1".
  std::string validate() const;
};

}  // namespace pbdbench
