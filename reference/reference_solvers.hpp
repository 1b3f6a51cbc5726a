// The reference solvers: the scene written as an energy (reference/energy.hpp) and integrated
// implicitly by SUNDIALS with Newton iterations on analytic sparse Jacobians and the KLU sparse
// direct solver. They implement the same Solver interface as the PBD family and are made by the
// same make_solver() (catalog/solver_catalog.hpp); docs/reference.md describes each.
//
//   ref-bdf     CVODE, BDF orders 1-5, adaptive steps, tolerances solver.ref.rtol/atol: the
//               continuous-time truth
//   ref-be      backward Euler with the fixed step dt / substeps (ARKODE, one-stage DIRK): the
//               time discretisation that converged XPBD is
//   ref-sdirk2  a two-stage, second-order SDIRK with the fixed step dt / substeps (ARKODE)
//   ref-dae     IDA on the constrained equations of motion in stabilised index-2 form (GGL),
//               for rigid distance constraints (compliance 0); the drift of C(x) is reported
//   ref-static  static equilibrium at each output time (KINSOL, Newton with line search)
//
// What the references simulate: compliant constraints (compliance > 0) as U = sum C^2/(2 alpha),
// their damping beta as forces -beta grad C (grad C . v), FEM elements with their material's
// energy, gravity, and kinematic particles on their scripted targets. Rigid constraints
// (compliance 0) only in ref-dae. No contacts: a scene with colliders or particle contact is
// refused unless solver.ref.ignore_colliders is set.
//
// The multipliers they leave in State::lambda are constraint forces per unit of C (N for a
// distance constraint): -C/alpha for a compliant constraint, the DAE's multiplier for a rigid
// one, so that the force of constraint j on particle i is grad_i C_j lambda_j.
#pragma once

// The factories, one per file, and the global solvers' (catalog/solver_catalog.cpp holds the rows).
#include "reference/global_solver.hpp"
#include "reference/integrators.hpp"
