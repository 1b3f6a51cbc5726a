// The kinds of constraint a model holds (core/model.hpp), with their arity: a header of its own,
// without Eigen, so that the projection kernels' instruction-set files (solvers/projection_avx2.cpp)
// can name them.
#pragma once

#include <cstdint>

namespace pbdbench {

// Constraints that live for the whole run (bilateral, equality C(x) = 0).
// The constraint functions themselves are in core/constraint_functions.hpp and
// core/constraint_stencils.hpp.
enum class ConstraintKind : std::uint8_t {
  Distance,  // C = |x1 - x0| - rest                                     (m)
             // Mueller et al. 2007, sec. 3.3 (stretching)
  Volume,    // C = (1/6) (x1-x0) . ((x2-x0) x (x3-x0)) - rest          (m^3)
             // Mueller et al. 2007, sec. 4.4 (tetrahedral volume); positive for a positively
             // oriented tetrahedron.
  Bending,   // C = acos(n1 . n2) - rest                                 (rad)
             // n1 = unit((x1-x0) x (x2-x0)), n2 = unit((x1-x0) x (x3-x0));
             // x0,x1: the shared edge; x2,x3: the two wing vertices.
             // Mueller et al. 2007, sec. 4.2 and appendix A. A flat sheet has rest = pi.
             // (Evaluated without acos: core/constraint_stencils.hpp.)
  FemDeviatoric,   // C = sqrt(tr(F^T F)) - rest, rest = 0                  (1)
                   // F = Ds Dm^-1 of Model::elements[element]; compliance 1/(mu V)
  FemHydrostatic,  // C = det F - rest, rest = 1 + mu / lambda_snh          (1)
                   // compliance 1/(lambda_snh V). With the deviatoric one its energy
                   // C^2/(2 alpha) is V times the stable neo-Hookean energy density of
                   // core/fem.hpp up to a constant (Macklin and Mueller 2021). These two are
                   // energy terms, not targets: their C is not zero at rest, and the constraint
                   // error metrics leave them out.
  FemStrainTriangle,  // C = the strain vector of Model::elements[element], a triangle:
                      // (E00, E11, sqrt 2 E01) with E its 2 x 2 strain (Mandel's form of
                      // Voigt's vector, so that E : E = |C|^2)                       (1)
  FemStrainTet,       // the same for a tet: (E00, E11, E22, sqrt 2 E12, sqrt 2 E02, sqrt 2 E01)
                      // Macklin et al. 2016, sec. 6.3, eqs. 27 and 28: the strain components of
                      // an element are one vector constraint with the compliance matrix
                      // alpha = K^-1 / V, K the linear isotropic stiffness, so that
                      // C^T alpha^-1 C / 2 = V Psi (StVK: Green strain; linear: small strain).
                      // The matrix comes from the element (fem::strain_compliance); the scalar
                      // `compliance` holds its deviatoric entry 1 / (2 mu V) for the record. Energy
                      // terms, like the two above: left out of the constraint error metrics.
};

inline constexpr int kConstraintKindCount = 7;

// True for the kinds that stand for an FEM element's energy (FemDeviatoric, FemHydrostatic,
// FemStrainTriangle, FemStrainTet).
constexpr bool is_fem_kind(ConstraintKind kind) {
  return kind == ConstraintKind::FemDeviatoric || kind == ConstraintKind::FemHydrostatic ||
         kind == ConstraintKind::FemStrainTriangle || kind == ConstraintKind::FemStrainTet;
}

// True for the vector (strain) kinds, whose multiplier is a vector (fem::eval_strain).
constexpr bool is_strain_kind(ConstraintKind kind) {
  return kind == ConstraintKind::FemStrainTriangle || kind == ConstraintKind::FemStrainTet;
}

// Number of particles a constraint of this kind acts on.
constexpr int arity(ConstraintKind kind) {
  switch (kind) {
    case ConstraintKind::Distance: return 2;
    case ConstraintKind::Volume: return 4;
    case ConstraintKind::Bending: return 4;
    case ConstraintKind::FemDeviatoric: return 4;
    case ConstraintKind::FemHydrostatic: return 4;
    case ConstraintKind::FemStrainTriangle: return 3;
    case ConstraintKind::FemStrainTet: return 4;
  }
  return 0;
}

// "distance", "volume", "bending", "fem_deviatoric", "fem_hydrostatic", "fem_strain_triangle",
// "fem_strain_tet"
const char* to_string(ConstraintKind kind);

}  // namespace pbdbench
