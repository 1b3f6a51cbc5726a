// IDA on the stabilised index-2 equations of motion (reference/dae_system.hpp).
//
// Residual F(t, y, y') with y = (q, u, lambda, mu):
//   F_q      = q' - u - M^-1 G^T mu
//   F_u      = M u' - f(t, q, u) - G^T lambda
//   F_lam_j  = n_j . (v_b - v_a)                  (= G_j u + dC_j/dt)
//   F_mu_j   = |x_b - x_a| - rest_j               (= C_j)
// with d = x_b - x_a, n = d / |d|, P = I - n n^T; a prescribed end takes its position and
// velocity from the callback. With s_a = -1, s_b = +1 the gradient of C_j with respect to end e
// is s_e n and its Hessian block for ends (e, e') is s_e s_e' P / |d|. The iteration matrix
// J = dF/dy + cj dF/dy' has the blocks
//   F_q rows:   cj I - M^-1 sum_j mu_j H_j  (q),   -I (u),                 -M^-1 G^T (mu)
//   F_u rows:   K - sum_j lambda_j H_j      (q),   cj M + D (u),           -G^T (lambda)
//   F_lam rows: s_e P (v_b - v_a) / |d|     (q),   s_e n^T (u)
//   F_mu rows:  s_e n^T                     (q)
// (K = -df/dq, D = -df/du from the MechanicalSystem). The pattern is built once by running the
// assembly with a recording sink; every later assembly adds its values through the recorded
// slots in the same order.
#include "reference/dae_system.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <ida/ida.h>
#include <ida/ida_ls.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include "core/cancel.hpp"
#include "reference/sundials_support.hpp"

namespace pbdbench {

namespace {

std::string number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// Per-constraint geometry at (t, q, u).
struct Geometry {
  Vec3 n = Vec3::Zero();  // unit direction a -> b
  Vec3 w = Vec3::Zero();  // v_b - v_a, m/s
  double length = 0.0;    // |x_b - x_a|, m
};

}  // namespace

// ---------------------------------------------------------------------------------------------

struct DaeIntegrator::Impl {
  const MechanicalSystem& sys;
  std::vector<RigidDistance> cons;
  PrescribedMotion prescribed;
  DaeSettings settings;
  int n = 0;  // dofs
  int m = 0;  // constraints
  int N = 0;  // 2n + 2m
  Eigen::VectorXd mass, inv_mass;

  // SUNDIALS objects, declared in the order they may be built and freed in reverse (IDA first).
  sun::Context ctx;
  std::optional<sun::Vector> yy, yp, id, atol;  // (N) y, y', algebraic mask, absolute tolerances
  std::optional<sun::SparseMatrix> A;           // the iteration matrix IDA hands to KLU
  std::optional<sun::TimedKlu> klu;
  sun::ErrorLog log;                             // IDA's last error message
  sun::Memory ida;

  // The Jacobian's fixed pattern (CSC, N x N) and, for each add() of the assembly in order, the
  // position of its value.
  sun::CscPattern pattern;
  std::vector<std::int64_t> slot;

  // Work buffers.
  Eigen::VectorXd qbuf, ubuf, fbuf;
  std::vector<double> kvals, dvals;
  std::vector<Geometry> geom;

  // Output at the last time.
  bool started = false;
  bool stop_time_set = false;  // IDASetStopTime was called since the last IDAReInit
  double t_out = 0.0;
  Eigen::VectorXd q_out, u_out, lambda_out, mu_out;

  DaeCounters counters;

  Impl(const MechanicalSystem& s, std::vector<RigidDistance> c, PrescribedMotion p, DaeSettings st)
      : sys(s), cons(std::move(c)), prescribed(std::move(p)), settings(st) {}

  void validate();
  void build_pattern();
  void create_ida(double t0);

  // Positions and velocities of constraint j's ends.
  Vec3 end_position(const RigidDistance& c, int e, double t, const double* q) const;
  void compute_geometry(double t, const double* q, const double* u);

  template <class Sink>
  void assemble(double cj, const double* lambda, const double* mu, Sink&& add) const;

  // G (m x n) at the geometry of the last compute_geometry().
  Eigen::SparseMatrix<double> constraint_jacobian() const;
  // Factorises S = G M^-1 G^T; false when it is singular (redundant constraints).
  bool factor(const Eigen::SparseMatrix<double>& G,
              Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt) const;
  // The multipliers of the acceleration-level constraint at (t, q, u), and the force
  // f + G^T lambda into fbuf:  G M^-1 (f + G^T lambda) + gamma = 0,
  // gamma_j = |P_j w_j|^2 / |d_j| + sum over prescribed ends of s_e n_j . a_e. Needs
  // compute_geometry(t, q, u) and the factorisation of G.
  Eigen::VectorXd acceleration_multipliers(
      double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
      const Eigen::SparseMatrix<double>& G,
      const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt);

  int residual(double t, const double* y, const double* ydot, double* r);
  int weights(const double* y, double* w) const;
  int jacobian(double t, double cj, const double* y, SUNMatrix J);
  void read_output(double t);
};

void DaeIntegrator::Impl::validate() {
  if (!(settings.rtol > 0.0) || !std::isfinite(settings.rtol))
    throw std::invalid_argument("ref-dae: rtol = " + number(settings.rtol) + " must be > 0");
  if (!(settings.atol > 0.0) || !std::isfinite(settings.atol))
    throw std::invalid_argument("ref-dae: atol = " + number(settings.atol) + " must be > 0");
  if (settings.max_steps < 1)
    throw std::invalid_argument("ref-dae: max_steps = " + std::to_string(settings.max_steps) +
                                " is below the minimum 1");
  if (settings.max_newton < 1)
    throw std::invalid_argument("ref-dae: max_newton = " + std::to_string(settings.max_newton) +
                                " is below the minimum 1");
  n = sys.dofs();
  m = static_cast<int>(cons.size());
  N = 2 * n + 2 * m;
  if (n < 1) throw std::invalid_argument("ref-dae: the system has no degree of freedom");
  mass = sys.mass();
  if (mass.size() != n || !(mass.array() > 0.0).all() || !mass.allFinite())
    throw std::invalid_argument("ref-dae: the system's masses must be n = " + std::to_string(n) +
                                " finite positive numbers");
  inv_mass = mass.cwiseInverse();
  const int blocks = n / 3;
  for (const RigidDistance& c : cons) {
    for (int e = 0; e < 2; ++e) {
      const int b = c.block[static_cast<size_t>(e)];
      if (b >= blocks || b < -1)
        throw std::invalid_argument("ref-dae: " + c.name + ": dof block " + std::to_string(b) +
                                    " is out of range [0, " + std::to_string(blocks) + ")");
      if (b < 0 && (c.point[static_cast<size_t>(e)] < 0 || !prescribed))
        throw std::invalid_argument("ref-dae: " + c.name + ": end " + std::to_string(e) +
                                    " is neither a dof block nor a prescribed point");
    }
    if (c.block[0] < 0 && c.block[1] < 0)
      throw std::invalid_argument("ref-dae: " + c.name +
                                  " joins two prescribed points: it constrains no dof");
    if (c.block[0] >= 0 && c.block[0] == c.block[1])
      throw std::invalid_argument("ref-dae: " + c.name + " joins a particle to itself");
    if (!(c.rest > 0.0) || !std::isfinite(c.rest))
      throw std::invalid_argument("ref-dae: " + c.name + ": rest length " + number(c.rest) +
                                  " must be > 0 (the gradient of |d| is undefined at d = 0)");
  }
  qbuf.resize(n);
  ubuf.resize(n);
  fbuf.resize(n);
  geom.resize(static_cast<size_t>(m));
}

Vec3 DaeIntegrator::Impl::end_position(const RigidDistance& c, int e, double t,
                                       const double* q) const {
  const int b = c.block[static_cast<size_t>(e)];
  if (b >= 0) return Vec3(q[3 * b], q[3 * b + 1], q[3 * b + 2]);
  return prescribed(c.point[static_cast<size_t>(e)], t).x;
}

void DaeIntegrator::Impl::compute_geometry(double t, const double* q, const double* u) {
  for (int j = 0; j < m; ++j) {
    const RigidDistance& c = cons[static_cast<size_t>(j)];
    Vec3 x[2], v[2];
    for (int e = 0; e < 2; ++e) {
      const int b = c.block[static_cast<size_t>(e)];
      if (b >= 0) {
        x[e] = Vec3(q[3 * b], q[3 * b + 1], q[3 * b + 2]);
        v[e] = u ? Vec3(u[3 * b], u[3 * b + 1], u[3 * b + 2]) : Vec3::Zero();
      } else {
        const PrescribedPoint p = prescribed(c.point[static_cast<size_t>(e)], t);
        x[e] = p.x;
        v[e] = p.v;
      }
    }
    Geometry& g = geom[static_cast<size_t>(j)];
    const Vec3 d = x[1] - x[0];
    g.length = d.norm();
    g.n = g.length > 0.0 ? Vec3(d / g.length) : Vec3::Zero();
    g.w = v[1] - v[0];
  }
}

// The iteration matrix, one add(row, col, value) per contribution, in an order that depends only
// on the structure (never on values), so that a recording pass gives the pattern.
template <class Sink>
void DaeIntegrator::Impl::assemble(double cj, const double* lambda, const double* mu,
                                   Sink&& add) const {
  const int u0 = n, l0 = 2 * n, m0 = 2 * n + m;
  // F_q rows: cj I (q), -I (u).
  for (int i = 0; i < n; ++i) {
    add(i, i, cj);
    add(i, u0 + i, -1.0);
  }
  // F_u rows: K (q), cj M + D (u).
  const SparsityPattern& p = sys.pattern();
  for (int c = 0; c < n; ++c) {
    for (std::int64_t k = p.column_start[static_cast<size_t>(c)];
         k < p.column_start[static_cast<size_t>(c) + 1]; ++k) {
      const int r = static_cast<int>(p.row[static_cast<size_t>(k)]);
      add(u0 + r, c, kvals[static_cast<size_t>(k)]);
      if (sys.has_damping()) add(u0 + r, u0 + c, dvals[static_cast<size_t>(k)]);
    }
  }
  for (int i = 0; i < n; ++i) add(u0 + i, u0 + i, cj * mass[i]);
  // Constraint terms.
  for (int j = 0; j < m; ++j) {
    const RigidDistance& c = cons[static_cast<size_t>(j)];
    const Geometry& g = geom[static_cast<size_t>(j)];
    const double inv_len = g.length > 0.0 ? 1.0 / g.length : 0.0;
    const Mat3 P = (Mat3::Identity() - g.n * g.n.transpose()) * inv_len;  // Hessian block / s s'
    const Vec3 Pw = P * g.w;
    for (int e = 0; e < 2; ++e) {
      const int be = c.block[static_cast<size_t>(e)];
      if (be < 0) continue;
      const double se = e == 0 ? -1.0 : 1.0;
      for (int r = 0; r < 3; ++r) {
        const int row = 3 * be + r;
        add(row, m0 + j, -inv_mass[row] * se * g.n[r]);           // F_q, mu
        add(u0 + row, l0 + j, -se * g.n[r]);                     // F_u, lambda
        add(l0 + j, row, se * Pw[r]);                            // F_lam, q
        add(l0 + j, u0 + row, se * g.n[r]);                      // F_lam, u
        add(m0 + j, row, se * g.n[r]);                           // F_mu, q
      }
      for (int f = 0; f < 2; ++f) {
        const int bf = c.block[static_cast<size_t>(f)];
        if (bf < 0) continue;
        const double sf = f == 0 ? -1.0 : 1.0;
        for (int r = 0; r < 3; ++r) {
          const int row = 3 * be + r;
          for (int s = 0; s < 3; ++s) {
            const double h = se * sf * P(r, s);
            add(row, 3 * bf + s, -inv_mass[row] * mu[j] * h);    // F_q, q
            add(u0 + row, 3 * bf + s, -lambda[j] * h);           // F_u, q
          }
        }
      }
    }
  }
}

void DaeIntegrator::Impl::build_pattern() {
  kvals.assign(static_cast<size_t>(sys.pattern().nnz()), 0.0);
  dvals.assign(static_cast<size_t>(sys.pattern().nnz()), 0.0);
  if (sys.pattern().n != n || static_cast<int>(sys.pattern().column_start.size()) != n + 1)
    throw std::invalid_argument("ref-dae: the system's sparsity pattern is not n x n, n = " +
                                std::to_string(n));
  std::vector<std::pair<std::int64_t, std::int64_t>> entries;  // (col, row)
  const std::vector<double> zeros(static_cast<size_t>(m), 0.0);
  assemble(1.0, zeros.data(), zeros.data(),
           [&](int r, int c, double) { entries.emplace_back(c, r); });
  std::vector<std::pair<std::int64_t, std::int64_t>> sorted = entries;
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  pattern.rows = N;
  pattern.cols = N;
  pattern.column_start.assign(static_cast<size_t>(N) + 1, 0);
  pattern.row.resize(sorted.size());
  for (size_t k = 0; k < sorted.size(); ++k) {
    pattern.column_start[static_cast<size_t>(sorted[k].first) + 1] += 1;
    pattern.row[k] = sorted[k].second;
  }
  for (int c = 0; c < N; ++c)
    pattern.column_start[static_cast<size_t>(c) + 1] += pattern.column_start[static_cast<size_t>(c)];
  slot.resize(entries.size());
  for (size_t k = 0; k < entries.size(); ++k)
    slot[k] = std::lower_bound(sorted.begin(), sorted.end(), entries[k]) - sorted.begin();
}

int DaeIntegrator::Impl::residual(double t, const double* y, const double* ydot, double* r) {
  const double* q = y;
  const double* u = y + n;
  const double* lambda = y + 2 * n;
  const double* mu = y + 2 * n + m;
  std::copy(q, q + n, qbuf.data());
  std::copy(u, u + n, ubuf.data());
  sys.force(t, qbuf, ubuf, fbuf);
  if (!fbuf.allFinite()) return 1;  // recoverable: IDA retries with a smaller step
  compute_geometry(t, q, u);
  for (int i = 0; i < n; ++i) {
    r[i] = ydot[i] - u[i];
    r[n + i] = mass[i] * ydot[n + i] - fbuf[i];
  }
  for (int j = 0; j < m; ++j) {
    const RigidDistance& c = cons[static_cast<size_t>(j)];
    const Geometry& g = geom[static_cast<size_t>(j)];
    if (!(g.length > 0.0) || !std::isfinite(g.length)) return 1;
    for (int e = 0; e < 2; ++e) {
      const int b = c.block[static_cast<size_t>(e)];
      if (b < 0) continue;
      const double s = e == 0 ? -1.0 : 1.0;
      for (int k = 0; k < 3; ++k) {
        const int i = 3 * b + k;
        r[i] -= inv_mass[i] * s * g.n[k] * mu[j];
        r[n + i] -= s * g.n[k] * lambda[j];
      }
    }
    r[2 * n + j] = g.n.dot(g.w);
    r[2 * n + m + j] = g.length - c.rest;
  }
  return 0;
}

int DaeIntegrator::Impl::jacobian(double t, double cj, const double* y, SUNMatrix J) {
  sun::ScopedTimer timer(klu->stats().seconds);
  const double* q = y;
  const double* u = y + n;
  std::copy(q, q + n, qbuf.data());
  std::copy(u, u + n, ubuf.data());
  sys.stiffness(t, qbuf, ubuf, kvals);
  if (sys.has_damping()) sys.damping(t, qbuf, ubuf, dvals);
  compute_geometry(t, q, u);
  sun::write_pattern(J, pattern);
  double* val = SUNSparseMatrix_Data(J);
  std::fill(val, val + pattern.nnz(), 0.0);
  size_t k = 0;
  assemble(cj, y + 2 * n, y + 2 * n + m, [&](int, int, double v) { val[slot[k++]] += v; });
  for (sunindextype i = 0; i < pattern.nnz(); ++i)
    if (!std::isfinite(val[i])) return 1;
  return 0;
}

int DaeIntegrator::Impl::weights(const double* y, double* w) const {
  sunrealtype h = 0.0;
  if (IDAGetCurrentStep(ida, &h) < 0 || !(h > 0.0)) h = 0.0;
  const double* at = N_VGetArrayPointer(*atol);
  for (int k = 0; k < 2 * n; ++k) w[k] = 1.0 / (settings.rtol * std::abs(y[k]) + at[k]);
  for (int k = 2 * n; k < N; ++k)
    w[k] = h > 0.0 ? 1.0 / (settings.rtol * std::abs(y[k]) + at[k] / h) : 0.0;
  return 0;
}

// ---------------------------------------------------------------------------------------------
// The callbacks IDA calls (user data: the Impl). An exception becomes an unrecoverable failure
// whose message IDA's failure then carries.

namespace {

extern "C" int dae_residual(sunrealtype t, N_Vector y, N_Vector yp, N_Vector r, void* data) {
  auto* impl = static_cast<DaeIntegrator::Impl*>(data);
  try {
    throw_if_cancelled("an IDA step");
    return impl->residual(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp), N_VGetArrayPointer(r));
  } catch (const std::exception& e) {
    impl->log.last = std::string("residual: ") + e.what();
    return -1;
  }
}

extern "C" int dae_jacobian(sunrealtype t, sunrealtype cj, N_Vector y, N_Vector, N_Vector,
                            SUNMatrix J, void* data, N_Vector, N_Vector, N_Vector) {
  auto* impl = static_cast<DaeIntegrator::Impl*>(data);
  try {
    return impl->jacobian(t, cj, N_VGetArrayPointer(y), J);
  } catch (const std::exception& e) {
    impl->log.last = std::string("Jacobian: ") + e.what();
    return -1;
  }
}

// Error weights. q and u: 1 / (rtol |y_k| + atol), as IDASVtolerances would give. lambda and mu
// are index-2 variables: a Newton correction of mu moves q by about h M^-1 G^T dmu and one of
// lambda moves u by h M^-1 G^T dlambda, and the round-off of C and of G u that the Newton
// iteration cannot remove reaches them multiplied by cj ~ 1/h. Their weights in the Newton
// convergence test are therefore scaled as index-2 components are in the analysis of Hairer,
// Lubich and Roche (1989): 1 / (rtol |y_k| + atol_k / h), h the step about to be attempted; with
// fixed weights the iteration stalls on round-off at small steps. (The local error test skips
// them: IDASetSuppressAlg.)
extern "C" int dae_weights(N_Vector y, N_Vector ewt, void* data) {
  auto* impl = static_cast<DaeIntegrator::Impl*>(data);
  return impl->weights(N_VGetArrayPointer(y), N_VGetArrayPointer(ewt));
}

}  // namespace

void DaeIntegrator::Impl::create_ida(double t0) {
  using sun::check;
  using sun::Flags;
  ida = sun::Memory(sun::check_ptr(IDACreate(ctx), "IDACreate"), IDAFree);
  check(IDASetErrHandlerFn(ida, sun::ErrorLog::handler, &log), "IDASetErrHandlerFn", Flags::Ida);
  check(IDAInit(ida, dae_residual, t0, *yy, *yp), "IDAInit", Flags::Ida, &log);
  check(IDAWFtolerances(ida, dae_weights), "IDAWFtolerances", Flags::Ida, &log);
  check(IDASetUserData(ida, this), "IDASetUserData", Flags::Ida, &log);
  check(IDASetId(ida, *id), "IDASetId", Flags::Ida, &log);
  check(IDASetSuppressAlg(ida, SUNTRUE), "IDASetSuppressAlg", Flags::Ida, &log);
  check(IDASetMaxNumSteps(ida, settings.max_steps), "IDASetMaxNumSteps", Flags::Ida, &log);
  check(IDASetMaxNonlinIters(ida, settings.max_newton), "IDASetMaxNonlinIters", Flags::Ida, &log);
  check(IDASetLinearSolver(ida, *klu, *A), "IDASetLinearSolver", Flags::IdaLs, &log);
  check(IDASetJacFn(ida, dae_jacobian), "IDASetJacFn", Flags::IdaLs, &log);
}

// The output at t: q, u and mu as IDA interpolates them; lambda from the acceleration-level
// constraint at the output (q, u), which is what the DAE's lambda is along the exact solution.
// IDA's own lambda is an index-2 variable left out of the error test: its interpolant at an
// output time between steps is not error-controlled (about 1e-7 relative on the pendulum at
// rtol 1e-10, where the recomputed one agrees with the closed form to round-off). It is kept
// when S is singular at the output.
void DaeIntegrator::Impl::read_output(double t) {
  const double* y = N_VGetArrayPointer(*yy);
  t_out = t;
  q_out = Eigen::Map<const Eigen::VectorXd>(y, n);
  u_out = Eigen::Map<const Eigen::VectorXd>(y + n, n);
  lambda_out = Eigen::Map<const Eigen::VectorXd>(y + 2 * n, m);
  mu_out = Eigen::Map<const Eigen::VectorXd>(y + 2 * n + m, m);
  if (m == 0) return;
  compute_geometry(t, q_out.data(), u_out.data());
  const Eigen::SparseMatrix<double> G = constraint_jacobian();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  if (!factor(G, ldlt)) return;
  const Eigen::VectorXd lambda = acceleration_multipliers(t, q_out, u_out, G, ldlt);
  if (lambda.allFinite()) lambda_out = lambda;
}

Eigen::SparseMatrix<double> DaeIntegrator::Impl::constraint_jacobian() const {
  std::vector<Eigen::Triplet<double>> trip;
  for (int j = 0; j < m; ++j) {
    const RigidDistance& c = cons[static_cast<size_t>(j)];
    for (int e = 0; e < 2; ++e) {
      const int b = c.block[static_cast<size_t>(e)];
      if (b < 0) continue;
      const double s = e == 0 ? -1.0 : 1.0;
      for (int k = 0; k < 3; ++k) trip.emplace_back(j, 3 * b + k, s * geom[static_cast<size_t>(j)].n[k]);
    }
  }
  Eigen::SparseMatrix<double> G(m, n);
  G.setFromTriplets(trip.begin(), trip.end());
  return G;
}

bool DaeIntegrator::Impl::factor(const Eigen::SparseMatrix<double>& G,
                                 Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt) const {
  const Eigen::SparseMatrix<double> S = G * inv_mass.asDiagonal() * G.transpose();
  ldlt.compute(S);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::VectorXd D = ldlt.vectorD().cwiseAbs();
  // A pivot 1e-12 of the largest: G has (numerically) dependent rows.
  return D.minCoeff() > 1e-12 * D.maxCoeff();
}

Eigen::VectorXd DaeIntegrator::Impl::acceleration_multipliers(
    double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
    const Eigen::SparseMatrix<double>& G,
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt) {
  sys.force(t, q, u, fbuf);
  Eigen::VectorXd gamma(m);
  for (int j = 0; j < m; ++j) {
    const RigidDistance& c = cons[static_cast<size_t>(j)];
    const Geometry& g = geom[static_cast<size_t>(j)];
    const Vec3 w_perp = g.w - g.n * g.n.dot(g.w);
    gamma[j] = w_perp.squaredNorm() / g.length;
    for (int e = 0; e < 2; ++e) {
      if (c.block[static_cast<size_t>(e)] >= 0) continue;
      const double s = e == 0 ? -1.0 : 1.0;
      gamma[j] += s * g.n.dot(prescribed(c.point[static_cast<size_t>(e)], t).a);
    }
  }
  const Eigen::VectorXd lambda = ldlt.solve(-gamma - G * inv_mass.cwiseProduct(fbuf));
  fbuf += G.transpose() * lambda;
  return lambda;
}

// ---------------------------------------------------------------------------------------------

DaeIntegrator::DaeIntegrator(const MechanicalSystem& system, std::vector<RigidDistance> constraints,
                             PrescribedMotion prescribed, DaeSettings settings)
    : impl_(std::make_unique<Impl>(system, std::move(constraints), std::move(prescribed), settings)) {
  Impl& I = *impl_;
  I.validate();
  I.build_pattern();
  I.yy.emplace(I.N, I.ctx);
  I.yp.emplace(I.N, I.ctx);
  I.id.emplace(I.N, I.ctx);
  I.atol.emplace(I.N, I.ctx);
  double* id = N_VGetArrayPointer(*I.id);
  double* at = N_VGetArrayPointer(*I.atol);
  const double multiplier_atol = I.settings.atol * I.mass.maxCoeff();
  for (int k = 0; k < I.N; ++k) {
    const bool differential = k < 2 * I.n;
    id[k] = differential ? 1.0 : 0.0;
    at[k] = differential ? I.settings.atol : multiplier_atol;
  }
  I.A.emplace(I.pattern, I.ctx);
  I.klu.emplace(*I.yy, *I.A, I.ctx);
}

DaeIntegrator::~DaeIntegrator() = default;

Eigen::VectorXd DaeIntegrator::constraint_values(double t, const Eigen::VectorXd& q) const {
  const Impl& I = *impl_;
  Eigen::VectorXd C(I.m);
  for (int j = 0; j < I.m; ++j) {
    const RigidDistance& c = I.cons[static_cast<size_t>(j)];
    C[j] = (I.end_position(c, 1, t, q.data()) - I.end_position(c, 0, t, q.data())).norm() - c.rest;
  }
  return C;
}

void DaeIntegrator::start(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& u0) {
  Impl& I = *impl_;
  const int n = I.n, m = I.m;
  if (q0.size() != n || u0.size() != n)
    throw std::invalid_argument("ref-dae: start needs q and u of size " + std::to_string(n));
  if (!q0.allFinite() || !u0.allFinite() || !std::isfinite(t0))
    throw std::invalid_argument("ref-dae: the initial state is not finite");

  // Positions: refuse unless every |C_j| is within atol + rtol rest_j.
  const Eigen::VectorXd C = constraint_values(t0, q0);
  int worst = -1;
  for (int j = 0; j < m; ++j) {
    const double allowed =
        kStartSlack * (I.settings.atol + I.settings.rtol * I.cons[static_cast<size_t>(j)].rest);
    if (std::abs(C[j]) > allowed && (worst < 0 || std::abs(C[j]) > std::abs(C[worst]))) worst = j;
  }
  if (worst >= 0) {
    const RigidDistance& c = I.cons[static_cast<size_t>(worst)];
    throw std::invalid_argument(
        "ref-dae: the initial positions violate the rigid constraints; the largest is " + c.name +
        " with |C| = " + number(std::abs(C[worst])) + " m, above " + number(kStartSlack) +
        " (atol + rtol rest) = " + number(kStartSlack * (I.settings.atol + I.settings.rtol * c.rest)) +
        " m (ref-dae does not project positions: start from a configuration that satisfies them)");
  }

  Eigen::VectorXd u = u0;
  Eigen::VectorXd lambda = Eigen::VectorXd::Zero(m);
  if (m > 0) {
    I.compute_geometry(t0, q0.data(), u.data());
    const Eigen::SparseMatrix<double> G = I.constraint_jacobian();
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
    if (!I.factor(G, ldlt))
      throw std::invalid_argument(
          "ref-dae: the rigid constraints are redundant at the initial positions (G M^-1 G^T is "
          "singular: for example a straight line of rigid links between two fixed points, such "
          "as the top row of a cloth pinned at both corners, a loop of rigid links lying on a "
          "line, or two rigid constraints on the same pair of particles); make some of them "
          "compliant");
    // Velocities: projected onto G u + dC/dt = 0.
    Eigen::VectorXd rate(m);
    for (int j = 0; j < m; ++j)
      rate[j] = I.geom[static_cast<size_t>(j)].n.dot(I.geom[static_cast<size_t>(j)].w);
    u -= I.inv_mass.asDiagonal() * (G.transpose() * ldlt.solve(rate));
    I.compute_geometry(t0, q0.data(), u.data());
    lambda = I.acceleration_multipliers(t0, q0, u, G, ldlt);
  } else {
    I.sys.force(t0, q0, u, I.fbuf);
  }
  if (!I.fbuf.allFinite() || !lambda.allFinite())
    throw std::invalid_argument("ref-dae: the initial forces or multipliers are not finite");

  double* y = N_VGetArrayPointer(*I.yy);
  double* yd = N_VGetArrayPointer(*I.yp);
  for (int i = 0; i < n; ++i) {
    y[i] = q0[i];
    y[n + i] = u[i];
    yd[i] = u[i];
    yd[n + i] = I.inv_mass[i] * I.fbuf[i];
  }
  for (int j = 0; j < m; ++j) {
    y[2 * n + j] = lambda[j];
    y[2 * n + m + j] = 0.0;
    yd[2 * n + j] = 0.0;
    yd[2 * n + m + j] = 0.0;
  }
  if (I.ida.get() == nullptr) {
    I.create_ida(t0);
  } else {
    sun::check(IDAReInit(I.ida, t0, *I.yy, *I.yp), "IDAReInit", sun::Flags::Ida, &I.log);
    // A stop time that was set and not reached stays set through IDAReInit (this version has
    // no IDAClearStopTime): move it out of the way.
    if (I.stop_time_set)
      sun::check(IDASetStopTime(I.ida, std::numeric_limits<double>::max()), "IDASetStopTime",
                 sun::Flags::Ida, &I.log);
  }
  I.read_output(t0);
  I.started = true;
}

bool DaeIntegrator::started() const { return impl_->started; }

void DaeIntegrator::advance(double tout, double stop_time) {
  Impl& I = *impl_;
  if (!I.started) throw std::invalid_argument("ref-dae: advance before start");
  if (!(tout > I.t_out))
    throw std::invalid_argument("ref-dae: output time " + number(tout) +
                                " is not after the current time " + number(I.t_out));
  if (!(stop_time >= tout))
    throw std::invalid_argument("ref-dae: stop time " + number(stop_time) +
                                " is before the output time " + number(tout));
  if (std::isfinite(stop_time)) {
    sun::check(IDASetStopTime(I.ida, stop_time), "IDASetStopTime", sun::Flags::Ida, &I.log);
    I.stop_time_set = true;
  }
  // IDA's counters are cumulative since IDAInit / IDAReInit: what this call did is a difference.
  const auto read = [&](long out[4]) {
    sun::check(IDAGetNumSteps(I.ida, &out[0]), "IDAGetNumSteps", sun::Flags::Ida);
    sun::check(IDAGetNumNonlinSolvIters(I.ida, &out[1]), "IDAGetNumNonlinSolvIters", sun::Flags::Ida);
    sun::check(IDAGetNumErrTestFails(I.ida, &out[2]), "IDAGetNumErrTestFails", sun::Flags::Ida);
    sun::check(IDAGetNumNonlinSolvConvFails(I.ida, &out[3]), "IDAGetNumNonlinSolvConvFails",
               sun::Flags::Ida);
  };
  long before[4], after[4];
  read(before);
  I.log.last.clear();
  sunrealtype tret = I.t_out;
  const int flag = IDASolve(I.ida, tout, &tret, *I.yy, *I.yp, IDA_NORMAL);
  read(after);
  I.counters.steps += after[0] - before[0];
  I.counters.newton_iterations += after[1] - before[1];
  I.counters.error_test_failures += after[2] - before[2];
  I.counters.convergence_failures += after[3] - before[3];
  if (flag < 0) {
    I.started = false;  // the next start() reinitialises
    sun::check(flag, "ref-dae: IDASolve from t = " + number(I.t_out) + " to " + number(tout) +
                         " (reached " + number(tret) + ")",
               sun::Flags::Ida, &I.log);
  }
  I.read_output(tout);
}

double DaeIntegrator::time() const { return impl_->t_out; }
const Eigen::VectorXd& DaeIntegrator::q() const { return impl_->q_out; }
const Eigen::VectorXd& DaeIntegrator::u() const { return impl_->u_out; }
const Eigen::VectorXd& DaeIntegrator::lambda() const { return impl_->lambda_out; }
const Eigen::VectorXd& DaeIntegrator::mu() const { return impl_->mu_out; }
DaeCounters DaeIntegrator::counters() const {
  DaeCounters c = impl_->counters;
  const sun::LinearSolverStats& k = impl_->klu->stats();
  c.linear_setups = k.setups;
  c.linear_solves = k.solves;
  c.time_linear = k.seconds;
  return c;
}
int DaeIntegrator::dofs() const { return impl_->n; }
int DaeIntegrator::constraint_count() const { return impl_->m; }

Eigen::VectorXd DaeIntegrator::residual(double t, const Eigen::VectorXd& y,
                                        const Eigen::VectorXd& yp) {
  Impl& I = *impl_;
  if (y.size() != I.N || yp.size() != I.N)
    throw std::invalid_argument("ref-dae: residual needs y and y' of size " + std::to_string(I.N));
  Eigen::VectorXd r(I.N);
  if (I.residual(t, y.data(), yp.data(), r.data()) != 0)
    throw std::runtime_error("ref-dae: the residual is undefined here");
  return r;
}

Eigen::MatrixXd DaeIntegrator::iteration_matrix(double t, double cj, const Eigen::VectorXd& y) {
  Impl& I = *impl_;
  if (y.size() != I.N)
    throw std::invalid_argument("ref-dae: iteration_matrix needs y of size " + std::to_string(I.N));
  sun::SparseMatrix J(I.pattern, I.ctx);
  const double saved = I.klu->stats().seconds;
  const int flag = I.jacobian(t, cj, y.data(), J);
  I.klu->stats().seconds = saved;
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(I.N, I.N);
  const double* val = J.values();
  for (int c = 0; c < I.N; ++c)
    for (sunindextype k = I.pattern.column_start[static_cast<size_t>(c)];
         k < I.pattern.column_start[static_cast<size_t>(c) + 1]; ++k)
      dense(I.pattern.row[static_cast<size_t>(k)], c) += val[k];
  if (flag != 0) throw std::runtime_error("ref-dae: the iteration matrix is not finite here");
  return dense;
}

double DaeIntegrator::drift() const {
  if (impl_->m == 0) return 0.0;
  return constraint_values(impl_->t_out, impl_->q_out).cwiseAbs().maxCoeff();
}

}  // namespace pbdbench
