// Pure projection kernels of the PBD family: what projecting one constraint does to the positions
// of its particles (and to its multiplier), given the constraint's evaluation C(x), grad C(x)
// (core/constraint_functions.hpp, core/contacts.hpp) and the inverse masses of its particles.
// No state and no globals: everything a kernel needs is an argument, the step size included.
//
// A stencil has `count` particles (2 for distance, 4 for volume and bending, 1 for a contact
// against a collider, 2 for a particle-particle contact); entry i of every array refers to the
// constraint's i-th particle.
#pragma once

#include <array>
#include <cstdint>

#include "core/constraint_functions.hpp"
#include "core/types.hpp"

namespace pbdbench {

using Weights = std::array<double, 4>;  // inverse masses of the stencil's particles, 1/kg

// What projecting one constraint does.
struct Correction {
  std::array<Vec3, 4> dx{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  // (count) m, position change of each particle of the stencil
  double dlambda = 0.0;  // change of the constraint's multiplier, units of C * kg
                         // (Mueller: dlambda = -s, so that dx_i = w_i grad_i C dlambda)
};

enum class Projection : std::uint8_t {
  Applied,   // `dx` and `dlambda` are filled
  Inactive,  // a contact (C >= 0 is allowed) that is not violated: nothing to do
  Skipped,   // gradient undefined, or the generalised inverse mass is zero: nothing done
};

// sum_i w_i |grad_i C|^2, the generalised inverse mass of the constraint (1/kg for distance).
double generalized_inverse_mass(const ConstraintEval& e, const Weights& w, int count);

// PBD projection of an equality constraint, Mueller et al. 2007, sec. 3.3:
//   s = C / sum_j w_j |grad_j C|^2,   dx_i = -k s w_i grad_i C,   dlambda = -k s.
// k in [0, 1] is the constraint's stiffness (or the corrected k', pbd_corrected_stiffness).
// Skipped when e.valid is false or the denominator is zero.
Projection pbd_project(const ConstraintEval& e, const Weights& w, int count, double k,
                       Correction& out);

// Mueller et al. 2007, sec. 3.3: k' = 1 - (1 - k)^(1/n). After n sweeps a single constraint's
// error is scaled by (1 - k')^n = 1 - k, whatever n.
double pbd_corrected_stiffness(double k, int iterations);

// PBD projection of a contact (inequality C >= 0), Mueller et al. 2007, sec. 3.3 and 4.1:
// projected only when C < 0, with k = 1 (pbd_project with k = 1); Inactive otherwise.
Projection pbd_project_contact(const ConstraintEval& e, const Weights& w, int count,
                               Correction& out);

// The per-substep coefficients of a compliant constraint, Macklin et al. 2016, eqs. 18 and 26:
//   alpha~ = alpha / h^2,   beta~ = h^2 beta,   gamma = alpha~ beta~ / h.
struct XpbdCoefficients {
  double alpha_tilde = 0.0;  // alpha / h^2, units of C^2 / (kg m^2)
  double gamma = 0.0;        // damping factor of eq. 26, dimensionless
};
XpbdCoefficients xpbd_coefficients(double compliance, double damping, double h);

// XPBD update of one equality constraint, Macklin et al. 2016, eq. 26 (eq. 18 when gamma = 0):
//   dlambda = (-C - alpha~ lambda - gamma grad C . (x - x_n))
//             / ((1 + gamma) sum_j w_j |grad_j C|^2 + alpha~),
//   dx_i = w_i grad_i C dlambda.
// `lambda` is the constraint's multiplier accumulated so far in this substep; `displacement[i]`
// = x_i - x_n,i, the motion of particle i since the start of the substep. Skipped when e.valid
// is false or the denominator is zero.
Projection xpbd_project(const ConstraintEval& e, const Weights& w, int count,
                        const XpbdCoefficients& k, double lambda,
                        const std::array<Vec3, 4>& displacement, Correction& out);

// XPBD update of a contact (rigid, alpha = 0, no damping), projected when C < 0: the multiplier
// accumulated over the substep is kept >= 0:
//   dlambda = max(lambda - C / sum_j w_j |grad_j C|^2, 0) - lambda,  dx_i = w_i grad_i C dlambda.
// (While C < 0 the unclamped dlambda is positive, so the clamp only guards round-off.)
Projection xpbd_project_contact(const ConstraintEval& e, const Weights& w, int count, double lambda,
                                Correction& out);

}  // namespace pbdbench
