// One material, whatever the solver: the per-iteration stiffness k that pbd projects each model
// constraint with, derived from the scene's physical material (its compliance alpha), or taken
// from the explicit *_stiffness keys when solver.pbd.material = "stiffness" (an override, stated
// as such in describe and in the run file). docs/solvers.md, "One material", has the derivation.
//
// The rule (solver.pbd.material = "compliance", the default): Mueller et al. 2007, sec. 3.3,
// after n projections of stiffness k a single constraint keeps the fraction (1 - k)^n of its
// error. One backward Euler (or converged XPBD) step of a constraint of stiffness K = 1 / alpha
// on a particle of mass m keeps the fraction 1 / (1 + K h^2 / m) of the error at the predicted
// position. Equating the two:
//   k = 1 - (1 + h^2 S / alpha)^(-1/n),   S = sum_i |w_i| |grad_i C|^2 = 1 / m_eff,
// with h the substep, n solver.iterations and the gradient taken at the rest positions. alpha = 0
// gives k = 1; S = 0 (every particle pinned, or no gradient at rest) gives k = 1, the projection
// having nothing to move. Exact for one constraint whose C is linear along its correction (a
// spring on one particle: the same step map as xpbd, hence its static stretch m g alpha); with
// coupled constraints an approximation (Gauss-Seidel couples them; each k sees only its own
// constraint). FEM elements have no such rule: pbd refuses them (pbd_material_problem).
#pragma once

#include <string>
#include <vector>

#include "core/model.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

// S = sum_i |w_i| |grad_i C|^2 of one constraint at the rest positions (units 1 / (kg units of
// C^2)): distance sum |w_i| (|grad| = 1); volume from its gradient at rest; bending from the
// gradient of the signed dihedral angle at rest (well defined at a flat rest shape, where the
// unsigned angle C = acos(n1 . n2) has a kink: |grad C| is the same from either side). Absolute
// inverse masses, so that a (defective) negative one still gives a mass scale. 0 for the FEM
// kinds and where the rest shape gives no gradient.
double pbd_inverse_mass_sum(const Model& model, const Constraint& c);

// k = 1 - (1 + h^2 S / alpha)^(-1/n): 1 when alpha = 0 or S = 0.
double pbd_stiffness_from_compliance(double alpha, double inverse_mass_sum, double h, int iterations);

// The inverse of the rule: the compliance a stiffness k acts as at substep h over n iterations,
// alpha = h^2 S / ((1 - k)^-n - 1); 0 for k = 1, infinite for k = 0.
double pbd_compliance_of_stiffness(double k, double inverse_mass_sum, double h, int iterations);

// The k of every model constraint at substep h, in model order: derived from its compliance by
// the rule (material = compliance; `inverse_mass_sums` from pbd_inverse_mass_sums), or its
// explicit stiffness (material = stiffness; k' = 1 - (1 - k)^(1/n) with
// solver.pbd.stiffness_correction).
std::vector<double> pbd_inverse_mass_sums(const Model& model);
std::vector<double> pbd_stiffness(const Model& model, const SolverOptions& options,
                                  const std::vector<double>& inverse_mass_sums, double h);

// Why pbd cannot run this model's material ("" when it can): FEM elements (a Young's modulus has
// no per-constraint k), naming scene.material.
std::string pbd_material_problem(const Model& model);

// What pbd uses for one constraint group and kind, for describe and the run file.
struct PbdGroupMaterial {
  std::string group;            // Model::group_names entry
  ConstraintKind kind = ConstraintKind::Distance;
  int count = 0;                // constraints
  double compliance_min = 0.0, compliance_max = 0.0;  // the scene's alpha
  double k_min = 1.0, k_max = 1.0;                    // the k pbd projects with
  bool derived = true;          // true: by the rule from alpha; false: the explicit override
};
std::vector<PbdGroupMaterial> pbd_material_summary(const Model& model, const SolverOptions& options,
                                                   double h);

// One line per group: "stretch (1984 x distance): k = 0.83 .. 0.91 derived from alpha = 1e-04
// (Mueller 2007 effective stiffness, h = 0.0167 s, n = 10)" or "... k = 0.1 (explicit override:
// solver.pbd.material = stiffness)".
std::string pbd_material_text(const Model& model, const SolverOptions& options, double h);

// The material a solver uses, one line per constraint group and kind: for pbd,
// pbd_material_text at the substep dt / substeps; for pbd-seed, k (its listing's stiffness, the
// compliance not read); for every other solver, the compliance alpha (the FEM kinds' from their
// element's modulus). For describe and the run file's "material" attribute.
std::string material_text(const Model& model, const SolverOptions& options, double dt);

// Whether elastic_energy (metrics/metrics.hpp: the scene's physical material, sum C^2 / (2 alpha)
// and the FEM energy) is the energy of the material `options.name` simulates: false for pbd with
// material = stiffness and for pbd-seed (whose listing reads k) when some constraint's k is not
// the rigid k = 1 of a rigid (alpha = 0) constraint; true otherwise.
bool elastic_energy_defined(const Model& model, const SolverOptions& options);

}  // namespace pbdbench
