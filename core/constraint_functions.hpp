// Constraint functions C(x) and their gradients, one pure function per kind. Solvers project with
// them, metrics measure with them: the same code whatever solver produced the state.
//
// Each function returns the value and the gradient with respect to each particle it touches.
// `valid` is false when the gradient is undefined at this configuration (coincident particles,
// a degenerate triangle, a dihedral angle at exactly 0 or pi); C is still reported.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/model.hpp"
#include "core/types.hpp"

namespace pbdbench {

struct ConstraintEval {
  double C = 0.0;                // constraint value, units of the kind
  std::array<Vec3, 4> grad{};    // dC/dx_i for the first arity entries
  bool valid = true;             // gradient defined
};

// C = |x1 - x0| - rest.                                       Mueller et al. 2007, sec. 3.3.
ConstraintEval eval_distance(const Vec3& x0, const Vec3& x1, double rest);

// Signed volume (1/6) (x1-x0) . ((x2-x0) x (x3-x0)).
double tet_signed_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3);

// C = tet_signed_volume(x0..x3) - rest.                        Mueller et al. 2007, sec. 4.4.
// grad_1 = (1/6) (x2-x0) x (x3-x0), grad_2 = (1/6) (x3-x0) x (x1-x0),
// grad_3 = (1/6) (x1-x0) x (x2-x0), grad_0 = -(grad_1 + grad_2 + grad_3).
ConstraintEval eval_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                           double rest);

// Dihedral angle acos(n1 . n2) in [0, pi] of the triangles (x0, x1, x2) and (x0, x1, x3),
// n1 = unit((x1-x0) x (x2-x0)), n2 = unit((x1-x0) x (x3-x0)).
double dihedral_angle(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3);

// C = dihedral_angle(x0..x3) - rest.              Mueller et al. 2007, sec. 4.2 and appendix A.
// The gradient is -grad(n1.n2) / sqrt(1 - (n1.n2)^2): undefined (valid = false) when
// 1 - (n1.n2)^2 < 1e-12 or a triangle is degenerate.
ConstraintEval eval_bending(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                            double rest);

// Evaluate a model constraint on positions x (n x 3).
ConstraintEval eval_constraint(const Constraint& c, const Points& x);

// Evaluate any model constraint on positions x (n x 3): the FEM kinds through their element
// model.elements[c.element] (fem::eval_deviatoric, fem::eval_hydrostatic in core/fem.hpp; C is
// the measured value minus c.rest; the strain kinds, vector constraints, report the norm of
// fem::eval_strain's vector as C with valid = false), the others as the overload above. valid = false, C = 0 when a
// FEM-kind constraint's element index is out of range. (The overload above, without the model,
// reports the FEM kinds as C = 0, valid = false.)
ConstraintEval eval_constraint(const Model& model, const Constraint& c, const Points& x);

// The model's constraints as constraint_values reads them: runs of one kind in model order, their
// particles and rest values in arrays of their own (16 to 24 bytes read a constraint where its record
// has 64, most of them what the solvers need). Built once for a model (the metrics: once a run,
// MetricsBaseline); a model whose constraints change needs new runs.
struct ConstraintRuns {
  struct Run {
    ConstraintKind kind = ConstraintKind::Distance;
    std::size_t begin = 0, end = 0;  // model constraints [begin, end)
  };
  std::vector<Run> runs;                              // in model order, every constraint in one
  std::array<std::vector<std::int32_t>, 4> particle;  // particle[i][j]: particle i of constraint j,
                                                      // -1 past its arity and for the FEM kinds
  std::vector<double> rest;                           // rest[j]: constraint j's rest value
};
ConstraintRuns constraint_runs(const Model& model);

// C of every model constraint at positions x (n x 3), in model order: the values
// eval_constraint(model, c, x).C gives, bit for bit (the same stencils without their gradients,
// a run of neighbouring constraints of one kind at a time in the lanes of a pack, as wide as the
// processor has: 8 doubles with AVX-512, 4 with AVX2, 2 otherwise). For the metrics, which need
// every C of every step and no gradient.
void constraint_values(const Model& model, const Points& x, std::vector<double>& C);
// The same from the model's runs (constraint_runs(model)), built once; std::invalid_argument
// when they were built for a model with another number of constraints.
void constraint_values(const ConstraintRuns& runs, const Model& model, const Points& x, std::vector<double>& C);
// The same in 16-byte packs (SSE2) whatever the processor has: for the tests, which compare the
// widths bit for bit.
void constraint_values_sse2(const Model& model, const Points& x, std::vector<double>& C);

// The error of a constraint as the metrics report it: |C| / |rest| for distance and volume when
// rest != 0 (relative, dimensionless), |C| otherwise (absolute: m or m^3); |C| in radians for
// bending.
inline double normalized_error(const Constraint& c, double C) {
  switch (c.kind) {
    case ConstraintKind::Distance:
    case ConstraintKind::Volume:
      return std::abs(c.rest) > 0.0 ? std::abs(C) / std::abs(c.rest) : std::abs(C);
    case ConstraintKind::Bending:
    case ConstraintKind::FemDeviatoric:
    case ConstraintKind::FemHydrostatic:
    case ConstraintKind::FemStrainTriangle:
    case ConstraintKind::FemStrainTet:
      return std::abs(C);
  }
  return std::abs(C);
}

}  // namespace pbdbench
