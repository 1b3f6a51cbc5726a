// ref-be with contact: backward Euler as an incremental potential with the IPC barrier.
// ref_contact.hpp, docs/reference.md "ref-be with contact".
#include "reference/ref_contact.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "core/cancel.hpp"
#include "core/contacts.hpp"
#include "reference/contact_potential.hpp"
#include "reference/ref_common.hpp"

namespace pbdbench {

double automatic_barrier_stiffness(const Model& model, double d_hat) {
  double m_max = 0.0;
  for (double w : model.inv_mass)
    if (w > 0.0) m_max = std::max(m_max, 1.0 / w);
  const double g = std::max(model.gravity.norm(), 1.0);
  return (m_max > 0.0 ? m_max : 1.0) * g / d_hat;
}

namespace {

using Clock = std::chrono::steady_clock;

// The fraction of each gap a Newton step may close (the collision check keeps the rest).
constexpr double kStepSlack = 0.9;
// Surface pairs: the fraction of each gap the conservative check guarantees to keep (it stops
// the step where the gap has fallen to twice that, core/proximity.hpp).
constexpr double kSurfaceKeep = 0.05;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The projection of a symmetric block onto the positive semi-definite cone.
template <int N>
Eigen::Matrix<double, N, N> project_psd(const Eigen::Matrix<double, N, N>& A) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> es(A);
  Eigen::Matrix<double, N, 1> ev = es.eigenvalues();
  if (ev.minCoeff() >= 0.0) return A;
  ev = ev.cwiseMax(0.0);
  return es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
}

class RefBeContact final : public Solver {
 public:
  RefBeContact(const SolverOptions& options, const Model& model)
      : substeps_(options.substeps), tolerance_(options.ref_atol),
        max_newton_(options.ref_max_newton), d_hat_(options.ref_barrier_distance),
        eps_v_(options.ref_friction_velocity), scene_(model), surface_(model) {
    const EnergyModel& energy = scene_.system().energy();
    if (energy.has_damping())
      throw std::invalid_argument(
          "ref-be with contact does not simulate constraint damping yet (the scene's damped "
          "constraints have no potential); set their damping to 0, or run without contact "
          "(solver.ref.ignore_colliders = true)");
    kappa_ = options.ref_barrier_stiffness > 0.0 ? options.ref_barrier_stiffness
                                                 : automatic_barrier_stiffness(model, d_hat_);
    particle_dof_.assign(static_cast<size_t>(model.particle_count()), -1);
    const std::vector<int>& dyn = energy.dynamic_particles();
    for (size_t k = 0; k < dyn.size(); ++k) particle_dof_[static_cast<size_t>(dyn[k])] = static_cast<int>(k);
  }

  std::string name() const override { return "ref-be"; }

  StepReport step(const Model& model, State& state, double dt) override {
    scene_.check_step(model, state, dt);
    StepReport report;
    report.substeps = substeps_;
    report.stop = StopReason::Converged;  // a stalled line search is noted (substep)
    report.residual_position = 0.0;
    report.barrier_energy = 0.0;
    if (!scene_.continues(state) || q_.size() != scene_.dofs()) scene_.gather(state, q_, u_);
    const double h = dt / substeps_;
    double t = state.time;
    for (int s = 0; s < substeps_; ++s) {
      substep(model, t, h, report);
      t = state.time + (s + 1) * h;
    }
    scene_.finish(state, state.time + dt, q_, u_);
    return report;
  }

 private:
  const EnergyModel& energy() const { return scene_.system().energy(); }

  // The contact set at x (gaps below d_hat) at time t: colliders and particle pairs (the
  // vertex-triangle and edge-edge contacts of find_contacts are left to the surface pairs).
  std::vector<Contact> active(const Model& model, const Points& x, double t) const {
    std::vector<Contact> out = find_contacts(model, x, t, d_hat_);
    if (surface_.enabled())
      out.erase(std::remove_if(out.begin(), out.end(),
                               [](const Contact& c) {
                                 return c.kind == ContactKind::Triangle || c.kind == ContactKind::Edge;
                               }),
                out.end());
    return out;
  }

  // The surface pairs (point-triangle, edge-edge) with gaps below d_hat at x.
  std::vector<barrier::SurfacePair> active_surface(const Points& x) const {
    return surface_.near(x, d_hat_);
  }

  // The incremental potential at q (positions x at t1, contacts `contacts`).
  double potential(const Model& model, const Eigen::VectorXd& q, const Points& x, double t1,
                   const std::vector<Contact>& contacts,
                   const std::vector<barrier::SurfacePair>& spairs, double* barrier_part = nullptr,
                   double* magnitude = nullptr) const {
    const Eigen::VectorXd& m = energy().mass();
    double e = 0.5 * (q - q_hat_).cwiseAbs2().dot(m);
    double U = energy().energy(x);
    double B = 0.0;
    for (const Contact& c : contacts)
      for (const barrier::Gap& g : barrier::barrier_terms(model, c, x, t1, d_hat_))
        B += kappa_ * barrier::value(g.d, d_hat_);
    for (const barrier::SurfacePair& sp : spairs)
      B += kappa_ * barrier::SurfaceBarrier::energy(sp, x, d_hat_);
    double D = 0.0;
    for (const barrier::FrictionContact& f : friction_)
      D += barrier::friction_value(f, barrier::tangential_displacement(f, x, x0_), eps_v_ * h_);
    for (const barrier::SurfaceFriction& f : surface_friction_)
      D += barrier::friction_value(f.f, barrier::tangential_displacement(f, x, x0_), eps_v_ * h_);
    if (barrier_part) *barrier_part = B;
    if (magnitude) *magnitude = e + h_ * h_ * (std::abs(U) + B + D);
    return e + h_ * h_ * (U + B + D);
  }

  void add_block(std::vector<Eigen::Triplet<double>>& trip, int pa, int pb, const Mat3& H) const {
    const int da = particle_dof_[static_cast<size_t>(pa)], db = particle_dof_[static_cast<size_t>(pb)];
    if (da < 0 || db < 0) return;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        if (H(r, c) != 0.0) trip.emplace_back(3 * da + r, 3 * db + c, H(r, c));
  }

  void add_gradient(Eigen::VectorXd& g, int p, const Vec3& v) const {
    const int d = particle_dof_[static_cast<size_t>(p)];
    if (d >= 0) g.segment<3>(3 * d) += v;
  }

  // Gradient and PSD-projected Hessian of E at q (x its positions at t1).
  void derivatives(const Model& model, const Eigen::VectorXd& q, const Points& x, double t1,
                   const std::vector<Contact>& contacts,
                   const std::vector<barrier::SurfacePair>& spairs, bool project,
                   Eigen::VectorXd& grad, Eigen::SparseMatrix<double>* H) {
    const Eigen::VectorXd& m = energy().mass();
    const double h2 = h_ * h_;
    energy().gradient(x, gU_);
    grad = m.cwiseProduct(q - q_hat_) + h2 * gU_;
    const SparsityPattern& P = energy().hessian_pattern();
    trip_.clear();
    if (H) energy().hessian(x, hvalues_, project);
    for (int c = 0; H && c < P.n; ++c) {
      trip_.emplace_back(c, c, m[c]);
      for (std::int64_t k = P.column_start[static_cast<size_t>(c)]; k < P.column_start[static_cast<size_t>(c) + 1]; ++k)
        if (hvalues_[static_cast<size_t>(k)] != 0.0)
          trip_.emplace_back(static_cast<int>(P.row[static_cast<size_t>(k)]), c, h2 * hvalues_[static_cast<size_t>(k)]);
    }
    for (const Contact& c : contacts)
    for (const barrier::Gap& gp : barrier::barrier_terms(model, c, x, t1, d_hat_)) {
      const double b1 = barrier::first(gp.d, d_hat_), b2 = barrier::second(gp.d, d_hat_);
      const Eigen::Matrix<double, 6, 1> gg = h2 * kappa_ * b1 * gp.grad;
      add_gradient(grad, c.a, gg.head<3>());
      if (gp.size == 6) add_gradient(grad, c.b, gg.tail<3>());
      if (!H) continue;
      if (gp.size == 3) {
        Mat3 Hc = h2 * kappa_ *
                  (b2 * gp.grad.head<3>() * gp.grad.head<3>().transpose() +
                   b1 * gp.hess.topLeftCorner<3, 3>());
        if (project) Hc = project_psd<3>(Hc);
        add_block(trip_, c.a, c.a, Hc);
      } else {
        Eigen::Matrix<double, 6, 6> Hc =
            h2 * kappa_ * (b2 * gp.grad * gp.grad.transpose() + b1 * gp.hess);
        if (project) Hc = project_psd<6>(Hc);
        add_block(trip_, c.a, c.a, Hc.topLeftCorner<3, 3>());
        add_block(trip_, c.a, c.b, Hc.topRightCorner<3, 3>());
        add_block(trip_, c.b, c.a, Hc.bottomLeftCorner<3, 3>());
        add_block(trip_, c.b, c.b, Hc.bottomRightCorner<3, 3>());
      }
    }
    for (const barrier::SurfacePair& sp : spairs) {
      const barrier::SurfaceTerm st = barrier::SurfaceBarrier::term(sp, x, d_hat_);
      if (st.value == 0.0 && st.grad.isZero(0.0)) continue;
      for (int i = 0; i < 4; ++i) add_gradient(grad, sp.v[static_cast<size_t>(i)], h2 * kappa_ * st.grad.segment<3>(3 * i));
      if (!H) continue;
      proximity::Mat12 Hs = h2 * kappa_ * st.hess;
      if (project) Hs = project_psd<12>(Hs);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          add_block(trip_, sp.v[static_cast<size_t>(i)], sp.v[static_cast<size_t>(j)], Hs.block<3, 3>(3 * i, 3 * j));
    }
    const double e = eps_v_ * h_;
    for (const barrier::SurfaceFriction& f : surface_friction_) {
      const Vec3 u = barrier::tangential_displacement(f, x, x0_);
      const Vec3 gf = h2 * barrier::friction_gradient(f.f, u, e);
      for (int i = 0; i < 4; ++i) add_gradient(grad, f.v[static_cast<size_t>(i)], f.c[static_cast<size_t>(i)] * gf);
      if (!H) continue;
      const Mat3 Hf = h2 * barrier::friction_hessian(f.f, u, e);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          add_block(trip_, f.v[static_cast<size_t>(i)], f.v[static_cast<size_t>(j)],
                    f.c[static_cast<size_t>(i)] * f.c[static_cast<size_t>(j)] * Hf);
    }
    for (const barrier::FrictionContact& f : friction_) {
      const Vec3 u = barrier::tangential_displacement(f, x, x0_);
      const Vec3 gf = h2 * barrier::friction_gradient(f, u, e);
      add_gradient(grad, f.contact.a, gf);
      if (f.contact.kind == ContactKind::Particle) add_gradient(grad, f.contact.b, -gf);
      if (!H) continue;
      const Mat3 Hf = h2 * barrier::friction_hessian(f, u, e);
      add_block(trip_, f.contact.a, f.contact.a, Hf);
      if (f.contact.kind == ContactKind::Particle) {
        add_block(trip_, f.contact.a, f.contact.b, -Hf);
        add_block(trip_, f.contact.b, f.contact.a, -Hf);
        add_block(trip_, f.contact.b, f.contact.b, Hf);
      }
    }
    if (!H) return;
    H->resize(P.n, P.n);
    H->setFromTriplets(trip_.begin(), trip_.end());
  }

  // The lagged friction contacts at the start of the step (x0 at t0).
  void lag_friction(const Model& model, double t0, double t1) {
    friction_.clear();
    for (const Contact& c : active(model, x0_, t0)) {
      const double mu = contact_friction(model, c);
      if (!(mu > 0.0)) continue;
      const barrier::Gap gp = barrier::gap(model, c, x0_, t0);
      if (!(gp.d > 0.0) || gp.d >= d_hat_) continue;
      barrier::FrictionContact f;
      f.contact = c;
      f.normal = gp.grad.head<3>().normalized();
      f.lambda = -kappa_ * barrier::first(gp.d, d_hat_);
      f.mu = mu;
      if (c.kind == ContactKind::Sphere) {
        const SphereCollider& s = model.spheres[static_cast<size_t>(c.b)];
        f.collider_motion = sphere_center(model, s, t1) - sphere_center(model, s, t0);
      }
      if (c.kind == ContactKind::Mesh) {
        const MeshCollider& m = model.meshes[static_cast<size_t>(c.b)];
        f.collider_motion = mesh_offset(model, m, t1) - mesh_offset(model, m, t0);
      }
      friction_.push_back(f);
    }
    surface_friction_ = surface_.lag_friction(x0_, kappa_, d_hat_);
  }

  // Throws when some gap at x (time t) is <= 0, naming the first.
  void require_separated(const Model& model, const Points& x, double t, const char* when) const {
    for (const Contact& c : active(model, x, t)) {
      const double d = barrier::gap(model, c, x, t).d;
      if (d <= 0.0) {
        std::ostringstream os;
        os << "ref-be with contact: " << when << ", particle " << c.a << " is in contact ("
           << to_string(c.kind) << " " << c.b << ") with gap " << d
           << " m <= 0; the barrier needs every gap > 0";
        throw std::runtime_error(os.str());
      }
    }
    for (const barrier::SurfacePair& sp : surface_.near(x, d_hat_)) {
      const double d = barrier::SurfaceBarrier::gap(sp, x);
      if (d <= 0.0) {
        std::ostringstream os;
        os << "ref-be with contact: " << when << ", "
           << (sp.kind == proximity::PairKind::PointTriangle ? "particle " : "edge ")
           << sp.first << " is in contact ("
           << (sp.kind == proximity::PairKind::PointTriangle ? "triangle " : "edge ")
           << sp.second << ") with gap " << d << " m <= 0; the barrier needs every gap > 0";
        throw std::runtime_error(os.str());
      }
    }
  }

  // The first iterate: the previous positions, except that a dynamic particle a moving sphere
  // comes closer to over the step (its gap against the sphere at t1 below that at t0) is carried
  // along by the sphere's displacement, which keeps that gap as it was (a translation). Without
  // it a sphere that moves into a resting particle within one step would make the first iterate
  // infeasible. (Two moving spheres closing on one particle can still do that: refused below.)
  void carry_by_moving_spheres(const Model& model, Eigen::VectorXd& q, double t0, double t1) const {
    const std::vector<int>& dyn = energy().dynamic_particles();
    for (const SphereCollider& s : model.spheres) {
      if (s.motion < 0) continue;
      const Vec3 c0 = sphere_center(model, s, t0), c1 = sphere_center(model, s, t1);
      const Vec3 shift = c1 - c0;
      if (shift.squaredNorm() == 0.0) continue;
      for (size_t k = 0; k < dyn.size(); ++k) {
        const Vec3 x = q.segment<3>(3 * static_cast<Eigen::Index>(k));
        const double r = model.radius[static_cast<size_t>(dyn[k])];
        const double sign = s.side == SphereSide::Outside ? 1.0 : -1.0;
        const double R = s.side == SphereSide::Outside ? s.radius + r : s.radius - r;
        const double g0 = sign * ((x - c0).norm() - R), g1 = sign * ((x - c1).norm() - R);
        if (g1 < g0 && g1 < d_hat_) q.segment<3>(3 * static_cast<Eigen::Index>(k)) += shift;
      }
    }
    // Moving meshes likewise (a translation keeps the gap to the mesh as it was).
    for (const MeshCollider& m : model.meshes) {
      if (m.motion < 0) continue;
      const Vec3 o0 = mesh_offset(model, m, t0), o1 = mesh_offset(model, m, t1);
      const Vec3 shift = o1 - o0;
      if (shift.squaredNorm() == 0.0) continue;
      for (size_t k = 0; k < dyn.size(); ++k) {
        const Vec3 x = q.segment<3>(3 * static_cast<Eigen::Index>(k));
        const double r = model.radius[static_cast<size_t>(dyn[k])];
        const double reach = r + d_hat_ + shift.norm();
        const MeshDistance m1 = mesh_distance(m, x - o1, reach);
        if (m1.triangle < 0 || !(m1.unsigned_distance - r < d_hat_)) continue;
        const MeshDistance m0 = mesh_distance(m, x - o0);
        if (m1.unsigned_distance < m0.unsigned_distance)
          q.segment<3>(3 * static_cast<Eigen::Index>(k)) += shift;
      }
    }
  }

  void substep(const Model& model, double t0, double h, StepReport& report) {
    throw_if_cancelled("a ref-be contact step");
    h_ = h;
    const double t1 = t0 + h;
    const int n = scene_.dofs();
    auto tc = Clock::now();
    energy().positions(q_, t0, x0_);
    require_separated(model, x0_, t0, "at the start of the step");
    lag_friction(model, t0, t1);
    report.time_contacts += seconds_since(tc);
    if (n == 0) return;
    const Eigen::VectorXd q_start = q_;
    q_hat_ = q_ + h * u_;
    Eigen::VectorXd q = q_;
    carry_by_moving_spheres(model, q, t0, t1);
    energy().positions(q, t1, x_);
    require_separated(model, x_, t1,
                      "when kinematic particles and moving colliders reach the end of the step");
    std::vector<Contact> contacts = active(model, x_, t1);
    std::vector<barrier::SurfacePair> spairs = active_surface(x_);
    double E_size = 0.0;
    double E = potential(model, q, x_, t1, contacts, spairs, nullptr, &E_size);
    Eigen::VectorXd grad, p;
    Eigen::SparseMatrix<double> H;
    double step_norm = std::numeric_limits<double>::infinity();
    bool converged = false, stalled = false;
    for (int it = 0; it < max_newton_; ++it) {
      throw_if_cancelled("a ref-be contact Newton iteration");
      auto tl = Clock::now();
      // The exact Hessian first (Newton's quadratic convergence needs the contacts' negative
      // curvature, -|b'| (I - n n^T) / r of a pressed pair); where M + h^2 K is then not
      // positive definite, each term projected onto the PSD cone (a descent direction always).
      derivatives(model, q, x_, t1, contacts, spairs, false, grad, &H);
      llt_.compute(H);
      ++report.linear_setups;
      ++report.cholesky_factorizations;
      if (llt_.info() != Eigen::Success) {
        derivatives(model, q, x_, t1, contacts, spairs, true, grad, &H);
        llt_.compute(H);
        ++report.linear_setups;
        ++report.cholesky_factorizations;
      }
      if (llt_.info() != Eigen::Success)
        throw std::runtime_error("ref-be with contact: the Newton matrix is not positive definite");
      p = -llt_.solve(grad);
      ++report.linear_solves;
      report.time_linear += seconds_since(tl);
      ++report.newton_iterations;
      step_norm = p.lpNorm<Eigen::Infinity>();
      if (!std::isfinite(step_norm))
        throw std::runtime_error("ref-be with contact: the Newton step is not finite");
      if (step_norm <= tolerance_) {
        converged = true;
        break;
      }
      // The continuous collision check: the largest fraction of p that keeps 10 % of each gap.
      auto tcc = Clock::now();
      Eigen::VectorXd q1 = q + p;
      energy().positions(q1, t1, x1_);
      double max_move = 0.0;
      for (int k = 0; k < n / 3; ++k) max_move = std::max(max_move, p.segment<3>(3 * k).norm());
      std::vector<Contact> candidates;
      if (model.particle_contact) {
        for (const Contact& c : find_contacts(model, x_, t1, 2.0 * max_move * (1.0 + 1e-9)))
          if (c.kind == ContactKind::Particle) candidates.push_back(c);
      }
      double alpha = barrier::step_bound(model, x_, x1_, t1, t1, candidates, kStepSlack);
      if (surface_.enabled())
        alpha = surface_.step_bound(x_, x1_, d_hat_, kSurfaceKeep, alpha, &ccd_iterations_);
      report.time_contacts += seconds_since(tcc);
      // Backtracking (Armijo) on E from the bound. Where the decrease the step predicts,
      // -alpha grad . p, is below the round-off of E (1e-13 of the size of its terms), E cannot
      // tell better from worse: the bounded step is taken as it is (it is feasible by the
      // bound; Newton's convergence near the solution rests on the gradient, which is exact).
      const double slope = grad.dot(p);
      int cuts = 0;
      for (;;) {
        Eigen::VectorXd qa = q + alpha * p;
        energy().positions(qa, t1, xa_);
        std::vector<Contact> ca = active(model, xa_, t1);
        std::vector<barrier::SurfacePair> sa = active_surface(xa_);
        double Ea_size = 0.0;
        const double Ea = potential(model, qa, xa_, t1, ca, sa, nullptr, &Ea_size);
        const bool below_roundoff = -alpha * slope <= 1e-13 * std::max(E_size, Ea_size);
        bool accept = std::isfinite(Ea) && (Ea <= E + 1e-4 * alpha * slope || (cuts == 0 && below_roundoff));
        if (accept && !below_roundoff) {
          // The upper side of the strong Wolfe condition: not far past the minimum along p, where
          // E rises steeply. Without it a step lands deep in a barrier (E is still lower there
          // than at the start), and Newton climbs out of a gap of 1e-9 m only slowly.
          derivatives(model, qa, xa_, t1, ca, sa, false, ga_, nullptr);
          accept = ga_.dot(p) <= -0.9 * slope;
        }
        if (accept) {
          E_size = Ea_size;
          q = qa;
          x_ = xa_;
          contacts = std::move(ca);
          spairs = std::move(sa);
          E = Ea;
          break;
        }
        alpha *= 0.5;
        ++cuts;
        if (cuts > 60) break;
      }
      report.line_search_cuts += cuts;
      if (cuts > 60) {
        // No decrease of E even along 1e-18 of the step: E is at its round-off floor, and the
        // step is above the tolerance only by round-off. Counted, kept, never hidden.
        stalled = true;
        break;
      }
    }
    if (!converged) {
      if (!stalled) {
        std::ostringstream os;
        os << "ref-be with contact: Newton did not converge in " << max_newton_
           << " iterations (last step " << step_norm << " m, tolerance " << tolerance_
           << " m) at t = " << t1;
        throw std::runtime_error(os.str());
      }
      ++report.convergence_failures;
      note_stop(report, StopReason::LineSearchFailed);
    }
    q_ = q;
    u_ = (q - q_start) / h;
    double B = 0.0;
    potential(model, q, x_, t1, contacts, spairs, &B);
    report.barrier_energy = B;
    report.contacts += static_cast<int>(contacts.size() + spairs.size());
    report.ref_steps += 1;
    report.residual_position = std::max(report.residual_position, step_norm);
  }

  int substeps_;
  double tolerance_;
  int max_newton_;
  double d_hat_, eps_v_, kappa_ = 0.0;
  SceneStepper scene_;
  std::vector<int> particle_dof_;
  Eigen::VectorXd q_, u_, q_hat_, gU_, ga_;
  double h_ = 0.0;
  Points x0_, x_, x1_, xa_;
  std::vector<barrier::FrictionContact> friction_;
  barrier::SurfaceBarrier surface_;
  std::vector<barrier::SurfaceFriction> surface_friction_;
  long ccd_iterations_ = 0;
  std::vector<double> hvalues_;
  std::vector<Eigen::Triplet<double>> trip_;
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt_;
};

}  // namespace

std::unique_ptr<Solver> make_ref_be_contact(const SolverOptions& options, const Model& model) {
  SolverOptions checked = options;
  checked.ref_ignore_colliders = true;  // contact is simulated here; the other checks stay
  check_reference_model("ref-be", model, checked);
  return std::make_unique<RefBeContact>(options, model);
}

}  // namespace pbdbench
