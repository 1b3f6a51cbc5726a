// Tests of reference/ref_static: the hanging chain of compliant links at rest (each link
// stretched by alpha times the weight below it, references.md item 5), convergence from a far
// start thanks to the line search (and failure without it), the projected-Newton fallback on a
// singular stiffness, report fields, zero velocities, refusals.
#include "catalog/solver_catalog.hpp"
#include "reference/ref_static.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/generators.hpp"
#include "reference/scene_system.hpp"
#include "solver_api/solver.hpp"
#include "tests/reference/integrator_fixtures.hpp"

namespace pbdbench {
namespace {

// U = sum_i s_i (sqrt(1 + (q_i - c_i)^2) - 1): F = s x / sqrt(1 + x^2), K = s (1 + x^2)^(-3/2)
// with x = q - c. Newton's step maps x to -x^3, so it diverges from |x| > 1 without a line
// search. The solution is q = c.
class PseudoHuber final : public MechanicalSystem {
 public:
  PseudoHuber(Eigen::VectorXd s, Eigen::VectorXd c)
      : s_(std::move(s)), c_(std::move(c)), m_(Eigen::VectorXd::Ones(s_.size())),
        p_(test::full_pattern(static_cast<int>(s_.size()), false)) {}
  int dofs() const override { return static_cast<int>(s_.size()); }
  const Eigen::VectorXd& mass() const override { return m_; }
  void force(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, Eigen::VectorXd& f) const override {
    const Eigen::ArrayXd x = (q - c_).array();
    f = -(s_.array() * x / (1.0 + x * x).sqrt()).matrix();
  }
  const SparsityPattern& pattern() const override { return p_; }
  void stiffness(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, std::vector<double>& v) const override {
    v.resize(static_cast<size_t>(dofs()));
    for (int i = 0; i < dofs(); ++i) {
      const double x = q[i] - c_[i];
      v[static_cast<size_t>(i)] = s_[i] * std::pow(1.0 + x * x, -1.5);
    }
  }
  void damping(double, const Eigen::VectorXd&, const Eigen::VectorXd&, std::vector<double>& v) const override {
    v.assign(static_cast<size_t>(dofs()), 0.0);
  }
  bool has_damping() const override { return false; }
  double potential(double, const Eigen::VectorXd& q) const override {
    const Eigen::ArrayXd x = (q - c_).array();
    return (s_.array() * ((1.0 + x * x).sqrt() - 1.0)).sum();
  }

 private:
  Eigen::VectorXd s_, c_, m_;
  SparsityPattern p_;
};

// A particle (x, y) between anchors at (-1, 0) and (1, 0) on two springs of rest length 1 and
// stiffness k, under gravity -g y. At the start (0, 0) the springs are straight and slack-free:
// K = diag(2k, 0) is singular, so exact Newton cannot even factorise it.
class Sag final : public MechanicalSystem {
 public:
  Sag(double k, double m, double g) : k_(k), g_(g), m_(Eigen::VectorXd::Constant(2, m)), p_(test::full_pattern(2)) {}
  int dofs() const override { return 2; }
  const Eigen::VectorXd& mass() const override { return m_; }
  void force(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, Eigen::VectorXd& f) const override {
    f = Eigen::Vector2d(0.0, -m_[0] * g_);
    for (double ax : {-1.0, 1.0}) {
      const Eigen::Vector2d d = q - Eigen::Vector2d(ax, 0.0);
      const double len = d.norm();
      f -= k_ * (len - 1.0) * d / len;
    }
  }
  const SparsityPattern& pattern() const override { return p_; }
  void stiffness(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, std::vector<double>& v) const override {
    Eigen::Matrix2d K = Eigen::Matrix2d::Zero();
    for (double ax : {-1.0, 1.0}) {
      const Eigen::Vector2d d = q - Eigen::Vector2d(ax, 0.0);
      const double len = d.norm();
      const Eigen::Vector2d n = d / len;
      K += k_ * (n * n.transpose() + (len - 1.0) / len * (Eigen::Matrix2d::Identity() - n * n.transpose()));
    }
    v = {K(0, 0), K(1, 0), K(0, 1), K(1, 1)};
  }
  void damping(double, const Eigen::VectorXd&, const Eigen::VectorXd&, std::vector<double>& v) const override {
    v.assign(4, 0.0);
  }
  bool has_damping() const override { return false; }
  double potential(double, const Eigen::VectorXd& q) const override {
    double U = m_[0] * g_ * q[1];
    for (double ax : {-1.0, 1.0}) {
      const double len = (q - Eigen::Vector2d(ax, 0.0)).norm();
      U += 0.5 * k_ * (len - 1.0) * (len - 1.0);
    }
    return U;
  }

 private:
  double k_, g_;
  Eigen::VectorXd m_;
  SparsityPattern p_;
};

TEST(RefStatic, HangingChainLinksStretchByAlphaTimesTheWeightBelow) {
  for (const char* compliance : {"1e-3", "1e-8"}) {
    auto c = test::catalog("hanging_chain", {{"solver.name", "ref-static"},
                                             {"scene.compliance", compliance},
                                             {"solver.ref.rtol", "1e-12"},
                                             {"solver.ref.atol", "1e-14"}});
    const Model& model = c.scene.model;
    State state = c.scene.initial;
    auto solver = make_solver(c.options, model);
    EXPECT_EQ(solver->name(), "ref-static");
    const StepReport r = solver->step(model, state, 1.0 / 60.0);
    EXPECT_EQ(r.ref_steps, 1);
    EXPECT_GT(r.newton_iterations, 0);
    EXPECT_GT(r.linear_setups, 0);
    EXPECT_GT(r.linear_solves, 0);
    // The chain starts straight and slack-free: no transverse stiffness, K is singular and
    // exact Newton cannot factorise it; the fallback takes over (one failed KINSOL attempt).
    EXPECT_EQ(r.convergence_failures, 1);
    std::printf("[ measured ] alpha %s: %ld Newton iterations, %ld factorisations\n", compliance,
                r.newton_iterations, r.linear_setups);

    const double alpha = std::stod(compliance);
    const double m = c.config.get_double("scene.mass");
    const double L = c.config.get_double("scene.link_length");
    const double g = model.gravity.norm();
    const int links = model.constraint_count();
    double worst = 0.0, worst_lambda = 0.0;
    for (int j = 0; j < links; ++j) {
      const int a = model.constraints[static_cast<size_t>(j)].particles[0];
      const int b = model.constraints[static_cast<size_t>(j)].particles[1];
      const double weight = (links - j) * m * g;  // particles j+1 .. links hang below link j
      const double stretch = (state.x.row(b) - state.x.row(a)).norm() - L;
      worst = std::max(worst, std::abs(stretch - alpha * weight));
      worst_lambda = std::max(worst_lambda, std::abs(state.lambda[static_cast<size_t>(j)] + weight) / weight);
      EXPECT_NEAR(state.x(b, 0), 0.0, 1e-15);  // straight down
    }
    std::printf("[ measured ] alpha %s: largest |stretch - alpha W| %.3g m, |lambda + W| / W %.3g\n",
                compliance, worst, worst_lambda);
    // rtol 1e-12 on positions of about 2 m: the step test leaves at most ~2e-12 m before the
    // last (quadratically converging) Newton step; 1e-11 m allows round-off in the 19 sums.
    EXPECT_LT(worst, 1e-11);
    EXPECT_LT(worst_lambda, 1e-11 / (alpha * m * g) + 1e-12);
    for (int i = 0; i < model.particle_count(); ++i) EXPECT_EQ(state.v.row(i).norm(), 0.0);

    // From the equilibrium, the next solve has (almost) nothing to do: KINSOL takes a start as
    // solved only at 1e-2 of its final force test, so it may add an iteration or two.
    const Points before = state.x;
    const StepReport r2 = solver->step(model, state, 1.0 / 60.0);
    EXPECT_LE(r2.newton_iterations, 2);
    EXPECT_EQ(r2.convergence_failures, 0);
    EXPECT_LT((state.x - before).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(state.step, 2);

    // From a chain already under some tension (each link 1 % long, and swung 0.1 rad aside),
    // exact Newton with the line search does it alone, to the same equilibrium.
    auto direct = make_solver(c.options, model);
    State tense = c.scene.initial;
    const Vec3 top = tense.x.row(0);
    for (int i = 1; i < model.particle_count(); ++i) {
      const double d = 1.01 * L * i;
      tense.x.row(i) = (top + d * Vec3(std::sin(0.1), -std::cos(0.1), 0.0)).transpose();
    }
    const StepReport r3 = direct->step(model, tense, 1.0 / 60.0);
    // With alpha = 1e-8 the swing is a large rotation of very stiff links, and Newton on |F|^2
    // may not find its way (the fallback then does); with alpha = 1e-3 it does alone.
    if (alpha > 1e-4) {
      EXPECT_EQ(r3.convergence_failures, 0);
    }
    std::printf("[ measured ] from a tense, swung chain: %ld Newton iterations, %ld failed KINSOL "
                "attempts\n", r3.newton_iterations, r3.convergence_failures);
    EXPECT_LT((tense.x - state.x).cwiseAbs().maxCoeff(), 1e-11);
  }
}

TEST(RefStatic, LineSearchConvergesFromAFarStartWhereNewtonDiverges) {
  Eigen::VectorXd s(3), c(3);
  s << 1.0, 10.0, 0.5;
  c << 0.3, -1.0, 2.0;
  PseudoHuber sys(s, c);
  StaticSettings with{1e-10, 1e-12, 100, true, false};
  StaticSolver solver(sys, with);
  Eigen::VectorXd q = c + Eigen::VectorXd::Constant(3, 10.0);  // x = 10: Newton maps it to -1000
  solver.solve(0.0, q);
  std::printf("[ measured ] line search: |q - c| = %.3g after %ld iterations\n",
              (q - c).cwiseAbs().maxCoeff(), solver.counters().newton_iterations);
  EXPECT_LT((q - c).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_FALSE(solver.last_used_fallback());
  EXPECT_GE(solver.last_flag(), 0);

  StaticSettings without{1e-10, 1e-12, 100, false, false};
  StaticSolver newton(sys, without);
  q = c + Eigen::VectorXd::Constant(3, 10.0);
  try {
    newton.solve(0.0, q);
    ADD_FAILURE() << "full Newton steps converged from x = 10: q - c = " << (q - c).transpose();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("KINSol failed: KIN_"), std::string::npos) << e.what();
  }
}

TEST(RefStatic, FallbackSolvesASingularStart) {
  const double k = 1000.0, m = 1.0, g = 9.81;
  Sag sys(k, m, g);
  // y* > 0 with 2 k (sqrt(1 + y^2) - 1) y / sqrt(1 + y^2) = m g, by bisection.
  double lo = 0.0, hi = 1.0;
  for (int i = 0; i < 200; ++i) {
    const double y = 0.5 * (lo + hi), len = std::sqrt(1.0 + y * y);
    (2.0 * k * (len - 1.0) * y / len < m * g ? lo : hi) = y;
  }
  const double y_star = 0.5 * (lo + hi);

  StaticSolver plain(sys, StaticSettings{1e-12, 1e-14, 50, true, false});
  Eigen::VectorXd q = Eigen::VectorXd::Zero(2);
  try {
    plain.solve(0.0, q);
    ADD_FAILURE() << "exact Newton solved a singular start";
  } catch (const std::runtime_error& e) {
    std::printf("[ measured ] without the fallback: %s\n", e.what());
  }

  StaticSolver solver(sys, StaticSettings{1e-12, 1e-14, 50, true, true});
  q.setZero();
  solver.solve(0.0, q);
  EXPECT_TRUE(solver.last_used_fallback());
  EXPECT_EQ(solver.counters().convergence_failures, 1);
  std::printf("[ measured ] fallback: y = %.15g (expected %.15g), %ld iterations\n", q[1], -y_star,
              solver.counters().newton_iterations);
  EXPECT_NEAR(q[0], 0.0, 1e-12);
  EXPECT_NEAR(q[1], -y_star, 1e-11);
}

// A chain pinned at both ends, laid out straight between them: no transverse stiffness at the
// start. Whichever path solves it, the result must be in force balance and symmetric.
TEST(RefStatic, SlackFreeChainBetweenTwoPinsSags) {
  Model model;
  ChainSpec s;
  s.links = 10;
  s.link_length = 0.1;
  s.top = Vec3::Zero();
  s.direction = Vec3::UnitX();
  s.mass = 0.1;
  s.link.compliance = 1e-4;
  add_chain(model, s);
  const int last = model.particle_count() - 1;
  model.inv_mass[static_cast<size_t>(last)] = 0.0;
  Attachment a;
  a.particle = last;
  a.anchor = model.rest_positions.row(last).transpose();
  model.attachments.push_back(a);

  SolverOptions options;
  options.name = "ref-static";
  options.ref_rtol = 1e-12;
  options.ref_atol = 1e-14;
  auto solver = make_solver(options, model);
  State state = rest_state(model);
  const StepReport r = solver->step(model, state, 0.1);
  std::printf("[ measured ] %ld Newton iterations, %ld failed KINSOL attempts\n", r.newton_iterations,
              r.convergence_failures);
  SceneSystem sys(model);
  Eigen::VectorXd q, u, f;
  sys.gather(state, q, u);
  sys.force(state.time, q, Eigen::VectorXd::Zero(q.size()), f);
  // Forces of about 1 N (weights) and 1e4 N/m stiffness: balance to 1e-8 N means positions to
  // about 1e-12 m.
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT(state.x(5, 1), -1e-3);  // it sags
  for (int i = 0; i <= last; ++i)
    EXPECT_NEAR(state.x(i, 1), state.x(last - i, 1), 1e-10) << "particle " << i;
}

TEST(RefStatic, RejectsBadDtAndRefuses) {
  auto c = test::catalog("hanging_chain", {{"solver.name", "ref-static"}});
  auto solver = make_solver(c.options, c.scene.model);
  State state = c.scene.initial;
  EXPECT_THROW(solver->step(c.scene.model, state, 0.0), std::invalid_argument);
  EXPECT_THROW(solver->step(c.scene.model, state, -std::numeric_limits<double>::infinity()),
               std::invalid_argument);
  Model rigid = c.scene.model;
  rigid.constraints[4].compliance = 0.0;
  try {
    make_solver(c.options, rigid);
    ADD_FAILURE() << "accepted a rigid constraint";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ref-static cannot simulate rigid constraints (compliance 0): constraint 4"),
              std::string::npos) << what;
  }
  Model contact = c.scene.model;
  contact.particle_contact = true;
  EXPECT_THROW(make_solver(c.options, contact), std::invalid_argument);
}

TEST(RefStatic, Deterministic) {
  auto c = test::catalog("hanging_chain", {{"solver.name", "ref-static"}, {"scene.compliance", "1e-4"}});
  auto run = [&] {
    auto solver = make_solver(c.options, c.scene.model);
    State s = c.scene.initial;
    for (int k = 0; k < 3; ++k) solver->step(c.scene.model, s, 0.5);
    return s;
  };
  const State a = run(), b = run();
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.lambda, b.lambda);
}

}  // namespace
}  // namespace pbdbench
