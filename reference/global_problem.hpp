// The global projection problem of one (sub)step: the step that PBD's sweeps of local projections
// approximate, written whole, for the global solvers (global-cholmod, global-cg, global-ceres;
// docs/global.md).
//
// With h the (sub)step, x_n the positions at its start and x~ = x_n + h v_n + h^2 g the predicted
// positions (kinematic particles on their targets at the end of the step), the step is
//
//   x* = argmin  E(x) = 1/2 |x - x~|_M^2 + sum_j C_j(x)^2 / (2 alpha~_j) + h/2 (x - x_n)^T D (x - x_n)
//        subject to  C_r(x) = 0   for the rigid model constraints (compliance 0),
//                    C_k(x) >= 0  for the step's contacts,
//
// alpha~_j = alpha_j / h^2 over the compliant constraints (compliance > 0, the FEM-kind pair of
// a stable neo-Hookean element included), D = sum_j beta_j grad C_j grad C_j^T at x_n over the
// damped ones (Macklin et al. 2016, eq. 26, with the gradient frozen at the start of the step,
// so that the damping has a potential). E is h^2 times backward Euler's incremental potential;
// its stationarity conditions are XPBD's g = 0 and h = 0 (Macklin et al. 2016, eqs. 8 and 9)
// with the compliant multipliers lambda_j = -C_j / alpha~_j.
//
// The rows of the constrained set are the rigid constraints, then the contacts. Their multipliers
// lambda_r follow XPBD's convention (units of C times kg; x moves by M^-1 grad C^T lambda), so that
// stationarity reads
//   g(x, lambda) = grad E(x) - sum_r grad C_r(x)^T lambda_r = 0,
//   C_r(x) = 0 (rigid),  C_k(x) >= 0, lambda_k >= 0, lambda_k C_k(x) = 0 (contacts).
//
// How far a point is from that, in metres (Residuals::position, the one number every global
// solver is stopped by and every history reports): the largest of |g_i| / m_i over the dofs, of
// |C_r| / |grad C_r| over the rigid rows, and over the contacts of max(-C_k, 0) and, where
// lambda_k > 0, |C_k|.
//
// The elastic part of E is evaluated through the scene's energy (reference/energy.hpp: the
// element energy stands for each FEM-kind pair, equal to it up to a constant; bending in its form
// that is smooth at flat), and equals the constraint form sum C^2 / (2 alpha~) that global-ceres
// builds term by term.
#pragma once

#include <array>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "core/contacts.hpp"
#include "core/model.hpp"
#include "reference/energy.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// One row of the constrained set.
struct GlobalRow {
  bool inequality = false;  // a contact (C >= 0), else a rigid constraint (C = 0)
  int constraint = -1;      // the model constraint of a rigid row, else -1
  int contact = -1;         // the index into the step's contacts of a contact row, else -1
};

// C of a row or of a model constraint, with its gradient for each particle of the stencil.
struct RowEval {
  double C = 0.0;
  int count = 0;                                 // particles in the stencil (1 to 4)
  std::array<int, 4> particles{-1, -1, -1, -1};  // model particle indices
  std::array<Vec3, 4> grad{};                    // dC/dx of each
  bool valid = true;                             // gradient defined
};

// One entry of a solve's convergence history.
struct IterationRecord {
  int iteration = 0;           // 0: the starting point
  double residual = 0.0;       // m, Residuals::position at this iterate
  double time = 0.0;           // s of wall clock since the solve began
  long inner_iterations = 0;   // cumulative: conjugate-gradient iterations (global-cg),
                               // Levenberg-Marquardt iterations (global-ceres)
};

// What a global solve did.
struct GlobalResult {
  bool converged = false;          // Residuals::position <= the tolerance
  StopReason stop = StopReason::IterationLimit;  // why the solve stopped (Converged with
                                   // converged; else the limit, the line search or the solver)
  int iterations = 0;              // outer iterations: Newton steps (global-cholmod, global-cg),
                                   // augmented-Lagrangian rounds (global-ceres)
  long inner_iterations = 0;       // conjugate-gradient or Levenberg-Marquardt iterations
  long factorizations = 0;         // Cholesky factorisations (global-cholmod, global-ceres)
  long linear_solves = 0;          // linear systems solved
  double time_linear = 0.0;        // s in assembly, factorisation and linear solves
  double residual_g = 0.0;         // |g|_2 at the solution, kg m
  double residual_h = 0.0;         // |h|_2 over the rows (C of rigid rows; of contacts the
                                   // violation max(-C, 0), or C where lambda > 0), units of C
  double residual = 0.0;           // Residuals::position at the solution, m
  double factor_cost_ratio = std::numeric_limits<double>::quiet_NaN();  // global-cholmod: a
                                   // factorisation's flops over one preconditioned CG
                                   // iteration's, from CHOLMOD's analysis (NaN otherwise)
  std::vector<IterationRecord> history;  // the starting point and every outer iteration
};

class GlobalProblem {
 public:
  // Keeps a pointer to `model`, which must outlive this object. Throws std::invalid_argument
  // naming the offender when the model has a rigid bending constraint or an FEM element whose
  // material has no constraint form (only stable_neo_hookean has one, as in xpbd).
  explicit GlobalProblem(const Model& model);

  const Model& model() const { return *model_; }
  const EnergyModel& energy() const { return energy_; }
  int dofs() const { return energy_.dofs(); }
  const Eigen::VectorXd& mass() const { return energy_.mass(); }  // (dofs) kg per dof
  // The dof block of a particle (its dofs are 3 b .. 3 b + 2), or -1 when it is not dynamic.
  int particle_dof(int particle) const { return particle_dof_[static_cast<size_t>(particle)]; }
  // Model constraints in E (compliance > 0, FEM-kind included), and the damped ones in D.
  const std::vector<int>& compliant() const { return compliant_; }
  const std::vector<int>& damped() const { return damped_; }

  // The step: x_start = x_n and x_pred = x~ (n x 3 each, kinematic particles on their targets
  // at t_end in both), h > 0, and the contacts to hold (found by the caller). The rows are the
  // rigid constraints then these contacts.
  void begin_step(const Points& x_start, const Points& x_pred, double h, double t_end,
                  std::vector<Contact> contacts);
  double h() const { return h_; }
  double t_end() const { return t_end_; }
  const Points& x_start() const { return x_start_; }
  const Points& x_pred() const { return x_pred_; }
  const std::vector<Contact>& contacts() const { return contacts_; }
  const std::vector<GlobalRow>& rows() const { return rows_; }
  double alpha_tilde(int constraint) const;  // compliance / h^2 of a model constraint

  // E(x) (kg m^2) and its gradient over the dofs (kg m); x holds every particle.
  double objective(const Points& x) const;
  void gradient(const Points& x, Eigen::VectorXd& g) const;
  // The Hessian of E with every term projected onto the positive semi-definite cone, as a
  // (dofs x dofs) matrix with both triangles.
  Eigen::SparseMatrix<double> hessian(const Points& x) const;
  // The same Hessian's values in the order of energy().hessian_pattern() (values is resized
  // and overwritten; a caller that keeps it between calls allocates nothing).
  void hessian_values(const Points& x, std::vector<double>& values) const;
  // out = (that Hessian) v, term by term without assembling it.
  void hessian_product(const Points& x, const Eigen::VectorXd& v, Eigen::VectorXd& out) const;
  // The diagonal of that Hessian (for a Jacobi preconditioner).
  Eigen::VectorXd hessian_diagonal(const Points& x) const;

  // Row r at positions x; its Hessian d2C_r/dx2 over its stencil (3 count square, top left of
  // the 12 x 12; zero for a plane contact).
  RowEval eval_row(int r, const Points& x) const;
  Eigen::Matrix<double, 12, 12> row_hessian(int r, const Points& x) const;
  // A compliant model constraint as global-ceres writes its term C / sqrt(alpha~): C and its
  // gradient, bending in the form smooth at flat (reference/energy.hpp, smooth_bending).
  RowEval eval_compliant(int constraint, const Points& x) const;
  // sum_i w_i |grad_i C|^2 over the dynamic particles of a row evaluation (1/kg for distance).
  double generalized_inverse_mass(const RowEval& e) const;

  struct Residuals {
    double g_norm = 0.0;    // |g|_2, kg m
    double h_norm = 0.0;    // |h|_2 over the rows, units of C
    double position = 0.0;  // m, the largest of the terms in the header comment
  };
  // At positions x (every particle) and row multipliers (rows().size(), kg m per unit of C).
  Residuals residuals(const Points& x, const std::vector<double>& row_lambda) const;
  // Of those terms, only the stationarity part: max |g_i| / m_i over the dofs, m.
  double stationarity_residual(const Points& x, const std::vector<double>& row_lambda) const;

  // Positions of every particle from the dofs q (the others from x_start) and back.
  void positions(const Eigen::VectorXd& q, Points& x) const;
  Eigen::VectorXd gather(const Points& x) const;

  // State::lambda for the model constraints at the solution (forces per unit of C, N for a
  // distance constraint): -C_j / alpha_j for a compliant one (C at x), lambda_r / h^2 for a rigid
  // one. Contacts are not model constraints; their lambda_r (kg m) feeds the velocity pass as is.
  void constraint_forces(const Points& x, const std::vector<double>& row_lambda,
                         std::vector<double>& lambda) const;

 private:
  // g(x, lambda) over the dofs, and the rows' evaluations when `evals` is given.
  void stationarity(const Points& x, const std::vector<double>& row_lambda, Eigen::VectorXd& g,
                    std::vector<RowEval>* evals) const;

  const Model* model_;
  EnergyModel energy_;
  std::vector<int> particle_dof_;
  std::vector<int> compliant_;
  std::vector<int> damped_;
  std::vector<int> rigid_;
  double h_ = 0.0;
  double t_end_ = 0.0;
  Points x_start_;
  Points x_pred_;
  Eigen::VectorXd q_start_;
  Eigen::VectorXd q_hat_;     // x~ without gravity's h^2 g (E's mass term, U holds gravity)
  std::vector<double> damping_values_;  // D at x_start in the energy's pattern
  std::vector<Contact> contacts_;
  std::vector<GlobalRow> rows_;
};

}  // namespace pbdbench
