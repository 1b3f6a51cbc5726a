// ref-be on a scene with contact: backward Euler written as the minimisation of an incremental
// potential with the IPC barrier and lagged friction of reference/contact_potential.hpp (Li et
// al. 2020), solved by Newton's method with a backtracking line search whose every trial point is
// first bounded by the continuous collision check. docs/reference.md, "ref-be with contact".
//
// One step of h = dt / substeps from (q_n, u_n) at t_n to t_{n+1} = t_n + h minimises
//
//   E(q) = 1/2 |q - q_n - h u_n|_M^2 + h^2 ( U(x(t_{n+1}, q)) + kappa sum_k b(d_k) + sum_k D_k )
//
// over the dynamic coordinates q (kinematic particles and moving spheres at t_{n+1}); then
// u_{n+1} = (q - q_n) / h. Its stationarity is backward Euler with the barrier's and friction's
// forces: M (u_{n+1} - u_n) = h f(q_{n+1}). Newton: the Hessian M + h^2 (K + barrier + friction)
// with each term projected onto the positive semi-definite cone, so the direction descends E;
// Cholesky (Eigen's simplicial LL^T) solves it. The iteration stops when the Newton step's
// largest component is at most solver.ref.atol (m).
//
// The guarantee: every iterate, so every accepted state, has every gap > 0 (no penetration): the
// first iterate is q_n (the previous state, separated), and each line-search trial point lies
// within the step bound that keeps at least 10 % of each gap (exact for planes, spheres and
// particle pairs on straight paths). The price: contact forces act from a distance d_hat (the
// barrier distance) and bodies at rest sit with gaps in (0, d_hat); a scene that starts with a gap
// <= 0 is refused, and so is a step whose kinematic motion (a scripted particle, a moving sphere)
// would carry something into contact within one step.
#pragma once

#include <memory>

#include "core/model.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// The barrier stiffness kappa (N/m) a model gets when solver.ref.barrier_stiffness = 0: the
// weight m |g| of its heaviest dynamic particle (|g| at least 1 m/s^2) per d_hat, so that a
// resting particle sits at about 0.55 d_hat (where -b'(d) = d_hat).
double automatic_barrier_stiffness(const Model& model, double d_hat);

// The ref-be solver for a scene with colliders or particle contact (make_ref_be chooses it).
// Throws std::invalid_argument for constraint damping (not written as a potential yet), and for
// what check_reference_model refuses besides contact.
std::unique_ptr<Solver> make_ref_be_contact(const SolverOptions& options, const Model& model);

}  // namespace pbdbench
