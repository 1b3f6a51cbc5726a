// Velocity-level operations shared by pbd and xpbd (and by pbd-seed when its departures D2 and
// D8 are fixed): friction and restitution on contacts after the position solve, and the velocity
// damping of Mueller et al. 2007, sec. 3.5.
#pragma once

#include <vector>

#include "core/contacts.hpp"
#include "core/model.hpp"
#include "core/types.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

// A contact below this value of C (m) after the solve counts as touching.
inline constexpr double kTouchingTolerance = 1e-9;

// Friction and restitution on the substep's contacts, after the positions are final and the
// velocities have been set to (x - x_n) / h. For each contact that is touching (C <= 1e-9 m at
// the final positions x, or lambda > 0), in list order:
//   n      = grad_a C (unit), pointing away from the collider / from particle b;
//   v_rel  = v_a - u, with u = contact_surface_velocity (the sphere's motion, or v_b);
//   v_n    = n . v_rel after the solve, v~_n = n . v~_rel before it (from v_before, the velocities
//            after the gravity step, at the same normal);
//   v_t    = v_rel - n v_n.
//   Friction (dry friction, as a velocity change limited by the normal one; Macklin et al. 2019,
//   Mueller et al. 2020 style): the contact changed the relative normal velocity by
//   dv_n = W lambda / h this substep (W = w_a + w_b; lambda the contact's accumulated multiplier,
//   so W lambda is the relative normal displacement it applied); then
//      dv_rel -= v_t / |v_t| * min(mu dv_n, |v_t|).
//   Restitution: e_eff = 0 when |v~_n| <= 2 |g| h (a resting contact does not jitter), else e;
//      dv_rel += n (-v_n + max(-e_eff v~_n, 0)).
//   The change is split by inverse mass: v_a += (w_a / W) dv_rel, v_b -= (w_b / W) dv_rel.
// lambda: (contacts) accumulated multipliers, units kg m; t_end: time at the end of the substep.
// With Precision::Float (solver.precision) the velocities a contact changes are rounded to float
// after its change, before the next contact reads them.
void velocity_pass(const Model& model, const std::vector<Contact>& contacts,
                   const std::vector<double>& lambda, const Points& x, const Points& v_before,
                   Points& v, double t_end, double h, Precision precision = Precision::Double);

// The bodies of a model for velocity damping: the connected components of the graph whose nodes
// are the dynamic particles (inv_mass > 0) and whose edges join the dynamic particles of each
// constraint. Pinned and kinematic particles belong to no body. Each list is sorted.
std::vector<std::vector<int>> dynamic_bodies(const Model& model);

// Mueller et al. 2007, sec. 3.5, for each body: x_cm, v_cm, L = sum r_i x m_i v_i,
// I = sum m_i [r_i]^T [r_i] (r_i = x_i - x_cm), omega = I^-1 L (pseudo-inverse over the
// eigenvalues above 1e-12 of the largest, so that a single particle or a straight chain works),
// then v_i += k (v_cm + omega x r_i - v_i). Motion that is a rigid translation or rotation of the
// body is unchanged. k in [0, 1].
void damp_velocities(const std::vector<std::vector<int>>& bodies,
                     const std::vector<double>& inv_mass, const Points& x, Points& v, double k);

}  // namespace pbdbench
