// force-symplectic: the force-based solver of practice, explicit symplectic (semi-implicit) Euler
// with springs and penalty contacts, run on the same models as the PBD family. It is the
// "force-based solver" of the seed article's claims (force -> acceleration -> velocity ->
// position), so that those claims can be measured against xpbd on the same scenes
// (docs/solvers.md, "force-symplectic").
//
// Per substep of h = dt / substeps (t_end = the time at its end):
//   kinematic particles: x_i = target(t_end), v_i = motion velocity          (as pbd and xpbd)
//   contacts = find_contacts(x, t_end, contact_margin)
//   f = f(x, v): constraint springs and dampers, FEM elements, penalty contacts (below)
//   v_i += h (g + w_i f_i),   x_i += h v_i                                   (dynamic particles)
//
// The pieces of f are pure functions, declared here so that the tests can check each against
// its closed form.
#pragma once

#include <memory>
#include <vector>

#include "core/contacts.hpp"
#include "core/model.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// Builds the solver. Throws std::invalid_argument naming the constraint and its kind when a
// model constraint is rigid (compliance 0: a force-based solver needs a compliance, the spring
// being the energy C^2 / (2 alpha)).
std::unique_ptr<Solver> make_force_symplectic_solver(const SolverOptions& options,
                                                     const Model& model);

// The force of one compliant constraint (alpha = c.compliance > 0, beta = c.damping), added to
// f (n x 3, N) on its dynamic and kinematic particles alike (the caller ignores the latter):
//   f_i += grad_i C lambda,   lambda = -C / alpha - beta dC/dt,   dC/dt = sum_j grad_j C . v_j,
// the gradient of the spring energy C^2 / (2 alpha) and xpbd's continuous damping (Macklin et
// al. 2016, eq. 26 in the limit h -> 0: a damper of coefficient beta on C). C and grad C from
// eval_constraint(model, c, x), the FEM kinds included. Returns lambda (the force per unit of C,
// State::lambda's convention), or 0 without touching f when the gradient is undefined (`valid`
// is then false).
double add_constraint_force(const Model& model, const Constraint& c, const Points& x,
                            const Points& v, Points& f, bool& valid);

// What a contact's penalty force was.
struct ContactForce {
  double C = 0.0;      // m, the contact's value at x (< 0: penetrating, the force acts)
  double force = 0.0;  // N, F below
  bool valid = true;   // the contact's gradient was defined
};

// The penalty force of one contact at time t, added to f (n x 3, N):
//   F = max(0, k_c (-C) - d_c v_n)  while C < 0, else 0,
//   f_a += F grad_a C,  f_b += F grad_b C (particle pairs),
// with v_n = grad_a C . (v_a - u) the relative normal velocity (u: contact_surface_velocity),
// > 0 when separating. A linear spring-dashpot along the unit contact normal, damped whether
// approaching or separating, clamped so that a contact never pulls. No friction. Nothing is
// added when the contact's gradient is undefined.
ContactForce add_contact_force(const Model& model, const Contact& contact, const Points& x,
                               const Points& v, double t, double stiffness, double damping,
                               Points& f);

}  // namespace pbdbench
