// Tests of reference/ref_dae.cpp and reference/dae_system.cpp: ref-dae, IDA on the stabilised
// index-2 equations of motion (Gear, Gupta and Leimkuhler 1985).
//
// The DAE core is checked on hand-written systems (its iteration matrix against central
// differences of its residual, prescribed moving ends); the solver on models: the rigid
// pendulum's period against the elliptic integral, the drift of C, the hanging chain's
// multipliers against the weight below each link, the swinging chain's energy, refusals,
// determinism and the step report. Every tolerance is stated where it is used, with its reason.
// PBDBENCH_DAE_VERBOSE=1 prints the measured errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <ostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "core/generators.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "reference/dae_system.hpp"
#include "reference/mechanical_system.hpp"
#include "reference/ref_dae.hpp"
#include "reference/reference_solvers.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {
namespace {

bool verbose() {
  const char* v = std::getenv("PBDBENCH_DAE_VERBOSE");
  return v != nullptr && std::string(v) != "0";
}

// Expects `f` to throw E with a message containing every one of `parts`.
template <class E, class F>
void expect_throw_naming(F&& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one naming " << parts.front();
  } catch (const E& e) {
    const std::string what = e.what();
    for (const std::string& p : parts)
      EXPECT_NE(what.find(p), std::string::npos) << "message: " << what << "\nmissing: " << p;
  }
}

// ---------------------------------------------------------------------------------------------
// A hand-written MechanicalSystem: point masses under gravity, a linear drag -c u, and zero-rest-
// length springs k (x_b - x_a) between pairs of dof blocks (so that K and D are not trivial).
class PointMasses final : public MechanicalSystem {
 public:
  PointMasses(std::vector<double> masses, Vec3 gravity, double drag,
              std::vector<std::array<int, 3>> springs /* block a, block b, k (N/m) */)
      : gravity_(gravity), drag_(drag), springs_(std::move(springs)) {
    const int blocks = static_cast<int>(masses.size());
    mass_.resize(3 * blocks);
    for (int b = 0; b < blocks; ++b) mass_.segment<3>(3 * b).setConstant(masses[static_cast<size_t>(b)]);
    // A dense pattern: small systems only.
    pattern_.n = 3 * blocks;
    for (int c = 0; c <= pattern_.n; ++c) pattern_.column_start.push_back(static_cast<std::int64_t>(c) * pattern_.n);
    for (int c = 0; c < pattern_.n; ++c)
      for (int r = 0; r < pattern_.n; ++r) pattern_.row.push_back(r);
  }
  int dofs() const override { return static_cast<int>(mass_.size()); }
  const Eigen::VectorXd& mass() const override { return mass_; }
  void force(double, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
             Eigen::VectorXd& f) const override {
    f.resize(q.size());
    for (int i = 0; i < q.size(); ++i) f[i] = mass_[i] * gravity_[i % 3] - drag_ * u[i];
    for (const auto& s : springs_) {
      const Vec3 d = q.segment<3>(3 * s[1]) - q.segment<3>(3 * s[0]);
      f.segment<3>(3 * s[0]) += s[2] * d;
      f.segment<3>(3 * s[1]) -= s[2] * d;
    }
  }
  const SparsityPattern& pattern() const override { return pattern_; }
  void stiffness(double, const Eigen::VectorXd&, const Eigen::VectorXd&,
                 std::vector<double>& values) const override {
    const int n = pattern_.n;
    values.assign(static_cast<size_t>(n) * static_cast<size_t>(n), 0.0);
    for (const auto& s : springs_)
      for (int k = 0; k < 3; ++k) {
        const int a = 3 * s[0] + k, b = 3 * s[1] + k;
        values[static_cast<size_t>(a * n + a)] += s[2];
        values[static_cast<size_t>(b * n + b)] += s[2];
        values[static_cast<size_t>(a * n + b)] -= s[2];
        values[static_cast<size_t>(b * n + a)] -= s[2];
      }
  }
  void damping(double, const Eigen::VectorXd&, const Eigen::VectorXd&,
               std::vector<double>& values) const override {
    const int n = pattern_.n;
    values.assign(static_cast<size_t>(n) * static_cast<size_t>(n), 0.0);
    for (int i = 0; i < n; ++i) values[static_cast<size_t>(i * n + i)] = drag_;
  }
  bool has_damping() const override { return drag_ > 0.0; }
  double potential(double, const Eigen::VectorXd& q) const override {
    double U = 0.0;
    for (int i = 0; i < q.size(); ++i) U -= mass_[i] * gravity_[i % 3] * q[i];
    for (const auto& s : springs_)
      U += 0.5 * s[2] * (q.segment<3>(3 * s[1]) - q.segment<3>(3 * s[0])).squaredNorm();
    return U;
  }

 private:
  Eigen::VectorXd mass_;
  Vec3 gravity_;
  double drag_;
  std::vector<std::array<int, 3>> springs_;
  SparsityPattern pattern_;
};

// A pivot moving with constant velocity V from P0: x = P0 + V t.
PrescribedMotion moving_pivot(const Vec3& P0, const Vec3& V) {
  return [P0, V](int, double t) {
    PrescribedPoint p;
    p.x = P0 + V * t;
    p.v = V;
    return p;
  };
}

RigidDistance distance(int a, int b, double rest, int point_a = -1, int point_b = -1) {
  RigidDistance r;
  r.block = {a, b};
  r.point = {point_a, point_b};
  r.rest = rest;
  r.name = "link " + std::to_string(a) + "-" + std::to_string(b);
  return r;
}

// The iteration matrix dF/dy + cj dF/dy' against central differences of F, at a random point
// off the solution (random lambda, mu, y') and with a moving prescribed end, drag and a spring.
TEST(DaeCore, IterationMatrixMatchesCentralDifferences) {
  PointMasses sys({0.7, 1.3, 0.4}, Vec3(0.0, -9.81, 0.0), 0.3, {{0, 2, 5}});
  // Prescribed ends at a (the first) and at b (the last constraint).
  std::vector<RigidDistance> cons = {distance(-1, 0, 0.8, 0, -1), distance(0, 1, 1.1),
                                     distance(2, 1, 0.6), distance(2, -1, 0.9, -1, 0)};
  DaeIntegrator dae(sys, cons, moving_pivot(Vec3(0.1, 0.2, -0.3), Vec3(0.4, -0.2, 0.7)), {});
  const int N = 2 * 9 + 2 * 4;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);  // values only: no portability needed
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd y(N), yp(N);
    for (int k = 0; k < N; ++k) {
      y[k] = uni(rng);
      yp[k] = uni(rng);
    }
    const double t = 0.3 + trial, cj = 3.7 + trial;
    const Eigen::MatrixXd J = dae.iteration_matrix(t, cj, y);
    // Central differences with h = 1e-6 on entries of order 1-10: truncation h^2 |F'''| ~ 1e-11,
    // round-off eps |F| / h ~ 1e-9; 1e-6 + 1e-6 |J| leaves two orders of margin and still catches
    // any wrong or missing term (the smallest terms, mu and lambda times P / |d|, are > 1e-2).
    const double h = 1e-6;
    for (int c = 0; c < N; ++c) {
      Eigen::VectorXd yph = y, ymh = y, ypph = yp, ypmh = yp;
      yph[c] += h;
      ymh[c] -= h;
      ypph[c] += h;
      ypmh[c] -= h;
      const Eigen::VectorXd col = (dae.residual(t, yph, yp) - dae.residual(t, ymh, yp)) / (2 * h) +
                                  cj * (dae.residual(t, y, ypph) - dae.residual(t, y, ypmh)) / (2 * h);
      for (int r = 0; r < N; ++r)
        ASSERT_NEAR(J(r, c), col[r], 1e-6 + 1e-6 * std::abs(col[r]))
            << "entry (" << r << ", " << c << "), trial " << trial;
    }
  }
}

TEST(DaeCore, RefusesMalformedConstraintsNamingThem) {
  PointMasses sys({1.0, 1.0}, Vec3(0.0, -9.81, 0.0), 0.0, {});
  const auto make = [&](RigidDistance r, PrescribedMotion p = {}) {
    r.name = "the constraint under test";
    DaeIntegrator dae(sys, {r}, std::move(p), {});
  };
  expect_throw_naming<std::invalid_argument>([&] { make(distance(0, 1, 0.0)); },
                                             {"the constraint under test", "rest length 0"});
  expect_throw_naming<std::invalid_argument>([&] { make(distance(0, 2, 1.0)); },
                                             {"the constraint under test", "dof block 2"});
  expect_throw_naming<std::invalid_argument>([&] { make(distance(0, 0, 1.0)); },
                                             {"the constraint under test", "itself"});
  expect_throw_naming<std::invalid_argument>(
      [&] { make(distance(-1, -1, 1.0, 0, 1), moving_pivot(Vec3::Zero(), Vec3::Zero())); },
      {"the constraint under test", "two prescribed points"});
  expect_throw_naming<std::invalid_argument>([&] { make(distance(-1, 0, 1.0, 0, -1)); },
                                             {"the constraint under test", "prescribed point"});
  DaeSettings bad;
  bad.rtol = 0.0;
  expect_throw_naming<std::invalid_argument>(
      [&] { DaeIntegrator(sys, {distance(0, 1, 1.0)}, {}, bad); }, {"rtol"});
}

TEST(DaeCore, RefusesRedundantConstraints) {
  PointMasses sys({1.0, 1.0}, Vec3(0.0, -9.81, 0.0), 0.0, {});
  DaeIntegrator dae(sys, {distance(0, 1, 1.0), distance(1, 0, 1.0)}, {}, {});
  Eigen::VectorXd q(6);
  q << 0, 0, 0, 1, 0, 0;
  expect_throw_naming<std::invalid_argument>([&] { dae.start(0.0, q, Eigen::VectorXd::Zero(6)); },
                                             {"redundant"});
}

// Galilean invariance: a pendulum whose pivot moves with constant velocity V, started with the
// bob moving at V, swings relative to the pivot exactly as one with a fixed pivot. Checks the
// prescribed end's position and velocity terms (dC/dt) in the residual and the Jacobian.
TEST(DaeCore, PendulumOnAMovingPivotSwingsAsOnAFixedOne) {
  PointMasses sys({1.0}, Vec3(0.0, -9.81, 0.0), 0.0, {});
  const Vec3 P0(0.5, 1.0, -0.2), V(0.8, -0.3, 0.4);
  const double L = 0.7;
  DaeSettings s;
  s.rtol = 1e-10;
  s.atol = 1e-12;
  DaeIntegrator fixed(sys, {distance(-1, 0, L, 0, -1)}, moving_pivot(P0, Vec3::Zero()), s);
  DaeIntegrator moving(sys, {distance(-1, 0, L, 0, -1)}, moving_pivot(P0, V), s);
  const Vec3 offset = L * Vec3(std::sin(1.0), -std::cos(1.0), 0.0);
  Eigen::VectorXd q = P0 + offset, u = Eigen::VectorXd::Zero(3);
  fixed.start(0.0, q, u);
  moving.start(0.0, q, u + V);
  for (int k = 1; k <= 200; ++k) {
    const double t = 0.01 * k;
    fixed.advance(t);
    moving.advance(t);
    // Two integrations of the same relative motion to rtol 1e-10 over 2 s (about 1.5 periods):
    // their difference is a global error, of order 1e-9 m; 1e-7 m is two orders of margin.
    const Vec3 rel_fixed = fixed.q() - P0, rel_moving = moving.q() - (P0 + V * t);
    ASSERT_LT((rel_fixed - rel_moving).norm(), 1e-7) << "t = " << t;
    ASSERT_LT((fixed.u() - (moving.u() - V)).norm(), 1e-6) << "t = " << t;
    ASSERT_NEAR(fixed.lambda()[0], moving.lambda()[0], 1e-6 * std::abs(fixed.lambda()[0]));
  }
}

// Velocities that violate G u + dC/dt = 0 are projected (an impulse): a bob at rest on a pivot
// that starts moving away from it along the rod picks up the pivot's velocity along the rod.
TEST(DaeCore, ProjectsInconsistentInitialVelocities) {
  PointMasses sys({2.0}, Vec3::Zero(), 0.0, {});
  const Vec3 V(0.0, 3.0, 1.0);  // rod along -y: the y part is along the rod
  DaeIntegrator dae(sys, {distance(-1, 0, 1.0, 0, -1)}, moving_pivot(Vec3::Zero(), V), {});
  Eigen::VectorXd q(3), u = Eigen::VectorXd::Zero(3);
  q << 0.0, -1.0, 0.0;
  dae.start(0.0, q, u);
  EXPECT_NEAR(dae.u()[0], 0.0, 1e-15);
  EXPECT_NEAR(dae.u()[1], 3.0, 1e-15);
  EXPECT_NEAR(dae.u()[2], 0.0, 1e-15);
}

// ---------------------------------------------------------------------------------------------
// The solver on models.

SolverOptions dae_options(double rtol = 1e-10, double atol = 1e-12) {
  SolverOptions o;
  o.name = "ref-dae";
  o.ref_rtol = rtol;
  o.ref_atol = atol;
  return o;
}

// A rigid pendulum of length L (m) with a bob of `mass` (kg), pivot pinned at the origin,
// released at rest `theta0` (rad) from the downward vertical in the xy plane. Particle 0 is the
// pivot, particle 1 the bob.
Scene pendulum(double theta0, double L = 1.0, double mass = 1.0) {
  Scene s;
  s.model.name = "pendulum";
  ChainSpec spec;
  spec.links = 1;
  spec.link_length = L;
  spec.direction = Vec3(std::sin(theta0), -std::cos(theta0), 0.0);
  spec.mass = mass;
  add_chain(s.model, spec);
  s.initial = rest_state(s.model);
  return s;
}

// A chain of `links` rigid links hanging from a pinned top particle along `direction`.
Scene chain(int links, const Vec3& direction, double link_length = 0.1, double mass = 0.1,
            double end_mass = 0.0) {
  Scene s;
  s.model.name = "chain";
  ChainSpec spec;
  spec.links = links;
  spec.link_length = link_length;
  spec.direction = direction;
  spec.mass = mass;
  spec.end_mass = end_mass;
  add_chain(s.model, spec);
  s.initial = rest_state(s.model);
  return s;
}

// The complete elliptic integral of the first kind, K(k) = pi / (2 AGM(1, sqrt(1 - k^2))).
double elliptic_k(double k) {
  double a = 1.0, b = std::sqrt(1.0 - k * k);
  for (int i = 0; i < 60 && std::abs(a - b) > 1e-16 * a; ++i) {
    const double an = 0.5 * (a + b);
    b = std::sqrt(a * b);
    a = an;
  }
  return std::numbers::pi / (2.0 * a);
}

// T = 4 sqrt(L / g) K(sin(theta0 / 2)) (docs/notes: references.md, closed form 3).
double pendulum_period(double theta0, double L, double g) {
  return 4.0 * std::sqrt(L / g) * elliptic_k(std::sin(0.5 * theta0));
}

struct Sample {
  double t, x, v;  // time (s), horizontal offset of the bob from the pivot (m), its rate (m/s)
};

// Times where x crosses zero, each located on the cubic Hermite interpolant of (x, v) between
// consecutive samples, by bisection to machine precision. The interpolant's error is
// h^4 / 384 max|x''''|: with h = 0.01 s and |x''''| < 1e3 m/s^4 (the 150 degree pendulum) it is
// under 3e-9 m, a crossing time error under 3e-9 m / |x'| (|x'| > 2 m/s at every crossing here),
// about 1e-9 s.
std::vector<double> zero_crossings(const std::vector<Sample>& s) {
  std::vector<double> out;
  for (size_t k = 1; k < s.size(); ++k) {
    const Sample& a = s[k - 1];
    const Sample& b = s[k];
    if ((a.x < 0.0) == (b.x < 0.0) || a.x == 0.0) continue;
    const double h = b.t - a.t;
    const auto p = [&](double r) {
      const double r2 = r * r, r3 = r2 * r;
      return (2 * r3 - 3 * r2 + 1) * a.x + (r3 - 2 * r2 + r) * h * a.v + (-2 * r3 + 3 * r2) * b.x +
             (r3 - r2) * h * b.v;
    };
    double lo = 0.0, hi = 1.0;
    const bool lo_negative = a.x < 0.0;
    for (int i = 0; i < 100; ++i) {
      const double mid = 0.5 * (lo + hi);
      if ((p(mid) < 0.0) == lo_negative) lo = mid;
      else hi = mid;
    }
    out.push_back(a.t + 0.5 * (lo + hi) * h);
  }
  return out;
}

struct PendulumRun {
  double period = 0.0;         // s, measured
  double first_crossing = 0.0; // s
  double max_drift = 0.0;      // m, max over the output steps of StepReport::constraint_drift
  double first_drift = 0.0;    // m, max over the first period
  double last_drift = 0.0;     // m, max over the last period
  double lambda_error = 0.0;   // N, max |lambda - (-(m g cos(theta) + m L theta'^2))|
  long steps = 0;
};

// Runs the pendulum for `periods` (expected) periods with outputs every dt and measures the
// period from the zero crossings of the bob's horizontal offset (the angle crosses zero at the
// same times): 2 (t_last - t_first) / (crossings - 1), consecutive crossings being half a period
// apart. Also checks the multiplier against the closed form of the rod tension.
PendulumRun run_pendulum(double theta0, double periods, const SolverOptions& options,
                         double dt = 0.01) {
  const Scene scene = pendulum(theta0);
  const double g = 9.81, L = 1.0, m = 1.0;
  const double T = pendulum_period(theta0, L, g);
  auto solver = make_solver(options, scene.model);
  State state = scene.initial;
  std::vector<Sample> samples{{0.0, state.x(1, 0), state.v(1, 0)}};
  PendulumRun run;
  const int steps = static_cast<int>(std::ceil(periods * T / dt));
  for (int k = 0; k < steps; ++k) {
    const StepReport r = solver->step(scene.model, state, dt);
    samples.push_back({state.time, state.x(1, 0), state.v(1, 0)});
    run.max_drift = std::max(run.max_drift, r.constraint_drift);
    if (state.time <= T) run.first_drift = std::max(run.first_drift, r.constraint_drift);
    if (state.time >= (periods - 1.0) * T) run.last_drift = std::max(run.last_drift, r.constraint_drift);
    run.steps += r.ref_steps;
    // Rod tension: the force on the bob is grad C lambda = n lambda (n from pivot to bob), and
    // m L theta'^2 = -lambda - m g cos(theta): lambda = -(m g cos(theta) + m |v|^2 / L).
    const Vec3 d = state.x.row(1).transpose();
    const double cos_theta = -d.y() / d.norm();
    const double expected = -(m * g * cos_theta + m * state.v.row(1).squaredNorm() / L);
    run.lambda_error = std::max(run.lambda_error, std::abs(state.lambda[0] - expected));
  }
  const std::vector<double> c = zero_crossings(samples);
  EXPECT_GE(c.size(), 3u);
  if (c.size() >= 2) {
    run.period = 2.0 * (c.back() - c.front()) / static_cast<double>(c.size() - 1);
    run.first_crossing = c.front();
  }
  return run;
}

struct PeriodCase {
  double degrees;
  double ratio;  // T / T0 from references.md, four digits
};

void PrintTo(const PeriodCase& c, std::ostream* os) { *os << c.degrees << " degrees"; }

class RefDaePendulum : public ::testing::TestWithParam<PeriodCase> {};

// The rigid pendulum's period against T = 4 sqrt(L/g) K(sin(theta0/2)) to 1e-6 relative, at
// rtol 1e-10, atol 1e-12, over 5 periods (10 crossings).
TEST_P(RefDaePendulum, PeriodMatchesTheEllipticIntegral) {
  const PeriodCase pc = GetParam();
  const double theta0 = pc.degrees * std::numbers::pi / 180.0;
  const double T = pendulum_period(theta0, 1.0, 9.81);
  const double T0 = 2.0 * std::numbers::pi * std::sqrt(1.0 / 9.81);
  // The closed form itself against references.md's four-digit ratios (rounding: 5e-5).
  EXPECT_NEAR(T / T0, pc.ratio, 5e-5);
  const PendulumRun run = run_pendulum(theta0, 5.25, dae_options());
  const double error = std::abs(run.period - T) / T;
  if (verbose())
    std::printf("pendulum %g deg: T = %.12f s, measured %.12f s, relative error %.3e; first "
                "crossing error %.3e s; max drift %.3e m; max lambda error %.3e N; %ld IDA steps\n",
                pc.degrees, T, run.period, error, std::abs(run.first_crossing - 0.25 * T),
                run.max_drift, run.lambda_error, run.steps);
  EXPECT_LT(error, 1e-6) << "measured " << run.period << " s, closed form " << T << " s";
  // The phase: the first crossing is at T/4 (the same 1e-6 relative, of T).
  EXPECT_NEAR(run.first_crossing, 0.25 * T, 1e-6 * T);
  // The multiplier is the rod tension (sign: the force on the bob, n lambda, points to the
  // pivot). It is computed from the output (q, u), so it departs from the closed form
  // evaluated on the same (q, u) only through their own constraint violation (|C| < 5e-11 m,
  // the radial velocity at the velocity tolerance): measured 5e-12, 4e-10 and 1.5e-9 N at 30,
  // 90 and 150 degrees. 1e-8 N is 3e-10 of the 30 N tension at 150 degrees.
  EXPECT_LT(run.lambda_error, 1e-8);
}

INSTANTIATE_TEST_SUITE_P(ReleaseAngles, RefDaePendulum,
                         ::testing::Values(PeriodCase{30.0, 1.0174}, PeriodCase{90.0, 1.1803},
                                           PeriodCase{150.0, 1.7622}),
                         [](const auto& info) {
                           return std::to_string(static_cast<int>(info.param.degrees)) + "deg";
                         });

// The drift of C stays at the tolerance level over many periods and does not grow: the position
// constraint is part of the DAE, so each IDA step satisfies it to the Newton tolerance, and an
// output between steps is off by the interpolation error, of the order of the local error test.
TEST(RefDae, DriftStaysAtTheToleranceOverManyPeriods) {
  for (const double rtol : {1e-10, 1e-8, 1e-6}) {
    const double atol = 1e-2 * rtol;
    const PendulumRun run = run_pendulum(std::numbers::pi / 2.0, 30.0, dae_options(rtol, atol), 0.01);
    if (verbose())
      std::printf("drift, 90 deg pendulum over 30 periods, rtol %g atol %g: max %.3e m, first "
                  "period %.3e m, last period %.3e m (rtol L = %.1e m)\n",
                  rtol, atol, run.max_drift, run.first_drift, run.last_drift, rtol);
    // IDA's local error test bounds the weighted RMS norm of the error estimate over the
    // N = 2 n + 2 m = 8 components by 1, so one component may reach sqrt(N) (rtol |y| + atol);
    // |C| moves with the bob's coordinates (|grad C| = 1, |q| <= L = 1 m). Measured: 0.7, 1.1
    // and 0.9 (rtol L + atol) at rtol 1e-10, 1e-8, 1e-6.
    EXPECT_LE(run.max_drift, std::sqrt(8.0) * (rtol * 1.0 + atol)) << "rtol " << rtol;
    // No secular growth: the last period's drift is of the same order as the first period's.
    EXPECT_LE(run.last_drift, 10.0 * run.first_drift + atol) << "rtol " << rtol;
  }
}

// A rigid chain hanging at rest: the multiplier of each link is minus the weight below it (the
// force on the lower particle, grad C lambda = n lambda with n pointing down, is the tension
// pulling it up), and the top link's is minus the total hanging weight: the support force.
TEST(RefDae, HangingChainMultipliersAreTheWeightBelow) {
  const int links = 12;
  const double mass = 0.1, end_mass = 2.5, g = 9.81;
  const Scene scene = chain(links, Vec3(0.0, -1.0, 0.0), 0.1, mass, end_mass);
  auto solver = make_solver(dae_options(), scene.model);
  State state = scene.initial;
  double worst = 0.0;
  for (int k = 0; k < 50; ++k) {
    solver->step(scene.model, state, 0.02);
    for (int j = 0; j < links; ++j) {
      // Particles j+1 .. links hang below link j; the last one has end_mass.
      const double below = g * ((links - j - 1) * mass + end_mass);
      worst = std::max(worst, std::abs(state.lambda[static_cast<size_t>(j)] + below) / below);
    }
    // The chain stays where it hangs (the equilibrium is exact in the DAE).
    ASSERT_LT((state.x - scene.initial.x).cwiseAbs().maxCoeff(), 1e-12);
  }
  const double total = g * ((links - 1) * mass + end_mass);
  if (verbose())
    std::printf("hanging chain: max relative multiplier error %.3e; support force %.15g N, "
                "weight %.15g N\n",
                worst, -state.lambda[0], total);
  // The multipliers solve the algebraic part exactly at rest (no motion, no truncation error):
  // round-off in sums of a dozen forces of order 10 N, a few ulps; 1e-12 relative is margin.
  EXPECT_LT(worst, 1e-12);
  EXPECT_NEAR(-state.lambda[0], total, 1e-12 * total);
}

// A swinging rigid chain without damping conserves energy to about the tolerance.
TEST(RefDae, SwingingChainConservesEnergy) {
  const int links = 6;
  const Scene scene = chain(links, Vec3(1.0, 0.0, 0.0), 0.1, 0.1);  // released horizontal
  const Vec3 g = scene.model.gravity;
  const auto energy = [&](const State& s) {
    double E = 0.0;
    for (int p = 1; p <= links; ++p)
      E += 0.5 * 0.1 * s.v.row(p).squaredNorm() - 0.1 * g.dot(s.x.row(p).transpose());
    return E;
  };
  for (const double rtol : {1e-10, 1e-8}) {
    auto solver = make_solver(dae_options(rtol, 1e-2 * rtol), scene.model);
    State state = scene.initial;
    const double E0 = energy(state);
    // Scale of the energy exchanged: the chain's fall, sum m g h, about 0.2 J.
    double scale = 0.0;
    for (int p = 1; p <= links; ++p) scale += 0.1 * 9.81 * 0.1 * p;
    double worst = 0.0, max_drift = 0.0;
    for (int k = 0; k < 300; ++k) {  // 3 s
      const StepReport r = solver->step(scene.model, state, 0.01);
      worst = std::max(worst, std::abs(energy(state) - E0) / scale);
      max_drift = std::max(max_drift, r.constraint_drift);
    }
    if (verbose())
      std::printf("swinging chain of %d links, rtol %g: max relative energy error %.3e over 3 s, "
                  "max drift %.3e m\n",
                  links, rtol, worst, max_drift);
    // BDF dissipates at the rate of its local error, which accumulates over the thousands of
    // internal steps of 3 s: measured 26 rtol (rtol 1e-10) and 12 rtol (rtol 1e-8) relative to
    // the energy exchanged. 100 rtol leaves a factor of four and fails for an error ten times
    // the measured one.
    EXPECT_LT(worst, 100.0 * rtol) << "rtol " << rtol;
    // The drift bound of DriftStaysAtTheToleranceOverManyPeriods: sqrt(N) (rtol |q| + atol),
    // N = 2 (18 dofs) + 2 (6 links) = 48 components, |q| <= 0.6 m (the chain's length).
    EXPECT_LE(max_drift, std::sqrt(48.0) * (rtol * 0.6 + 1e-2 * rtol)) << "rtol " << rtol;
  }
}

// A model without rigid constraints is an index-0 DAE (an implicit ODE): a compliant spring
// against its closed form x(t) = 1 + 0.5 cos(w t), w = 1 / sqrt(alpha m).
TEST(RefDae, ModelWithoutRigidConstraintsIsAnImplicitOde) {
  Scene s;
  s.model.gravity = Vec3::Zero();
  ChainSpec spec;
  spec.links = 1;
  spec.link_length = 1.0;
  spec.direction = Vec3(1.0, 0.0, 0.0);
  spec.link.compliance = 1e-3;
  add_chain(s.model, spec);
  s.initial = rest_state(s.model);
  s.initial.x(1, 0) = 1.5;
  auto solver = make_solver(dae_options(), s.model);
  State state = s.initial;
  const double w = 1.0 / std::sqrt(1e-3 * 1.0);
  double worst = 0.0;
  for (int k = 0; k < 100; ++k) {
    const StepReport r = solver->step(s.model, state, 0.01);
    EXPECT_EQ(r.constraint_drift, 0.0);
    worst = std::max(worst, std::abs(state.x(1, 0) - (1.0 + 0.5 * std::cos(w * state.time))));
    // The compliant constraint's multiplier is -C / alpha.
    EXPECT_NEAR(state.lambda[0], -(state.x(1, 0) - 1.0) / 1e-3, 1e-9);
  }
  // About 5 periods of w = 31.6 rad/s at rtol 1e-10: a global error of order 1e-8 m.
  EXPECT_LT(worst, 1e-6);
}

// A pendulum hung from a kinematic particle moving at constant velocity, with the bob started at
// that velocity, swings relative to it as the fixed one does (the model's attachment motion as
// the prescribed end).
TEST(RefDae, KinematicPivotUsesTheAttachmentTarget) {
  Scene fixed = pendulum(1.0);
  Scene moving = pendulum(1.0);
  Motion motion;
  motion.kind = MotionKind::Linear;
  motion.velocity = Vec3(0.5, 0.25, 0.0);
  moving.model.motions.push_back(motion);
  ASSERT_EQ(moving.model.attachments.size(), 1u);
  moving.model.attachments[0].motion = 0;
  moving.initial = rest_state(moving.model);
  moving.initial.v.row(1) = motion.velocity.transpose();
  auto a = make_solver(dae_options(), fixed.model);
  auto b = make_solver(dae_options(), moving.model);
  State sa = fixed.initial, sb = moving.initial;
  for (int k = 0; k < 100; ++k) {
    a->step(fixed.model, sa, 0.02);
    b->step(moving.model, sb, 0.02);
    ASSERT_LT((sb.x.row(0) - sa.x.row(0) - sb.time * motion.velocity.transpose()).norm(), 1e-14);
    // Same relative motion to the global error (1e-9 m at rtol 1e-10); 1e-7 is margin.
    ASSERT_LT(((sb.x.row(1) - sb.x.row(0)) - (sa.x.row(1) - sa.x.row(0))).norm(), 1e-7);
    ASSERT_NEAR(sb.lambda[0], sa.lambda[0], 1e-6);
  }
}

// A pendulum hanging at rest from a kinematic particle that starts moving horizontally at
// t = 0.33 s and stops at t = 0.71 s: two kinks, each an impulse through the rod. The solver
// stops on them and restarts there whatever the output steps, so runs with different dt agree;
// before the start the bob hangs still (lambda = -m g exactly), after the stop the pendulum
// swings about a fixed pivot with constant energy.
TEST(RefDae, KinksOfAScriptedMotionAreSteppedOnNotOver) {
  const auto make = [] {
    Scene s = pendulum(0.0);
    Motion motion;
    motion.kind = MotionKind::Linear;
    motion.velocity = Vec3(1.0, 0.0, 0.0);
    motion.start = 0.33;
    motion.stop = 0.71;
    s.model.motions.push_back(motion);
    s.model.attachments[0].motion = 0;
    s.initial = rest_state(s.model);
    return s;
  };
  const Scene a = make(), b = make();
  auto sa = make_solver(dae_options(), a.model);
  auto sb = make_solver(dae_options(), b.model);
  State xa = a.initial, xb = b.initial;
  const auto energy = [](const State& s) {  // about the pivot, fixed after the stop
    return 0.5 * s.v.row(1).squaredNorm() + 9.81 * (s.x(1, 1) - s.x(0, 1));
  };
  double e_after_stop = std::nan("");
  for (int k = 0; k < 15; ++k) {  // to 1.5 s in steps of 0.1 s
    sa->step(a.model, xa, 0.1);
    if (xa.time < 0.33) {
      EXPECT_NEAR(xa.lambda[0], -9.81, 1e-12);
    }
    if (k == 7) e_after_stop = energy(xa);  // t = 0.8
    if (k > 7) {
      EXPECT_NEAR(energy(xa), e_after_stop, 1e-8) << "t = " << xa.time;
    }
  }
  for (int k = 0; k < 30; ++k) sb->step(b.model, xb, 0.05);
  // The pivot moved 0.38 m and the bob swings behind it.
  EXPECT_NEAR(xa.x(0, 0), 0.38, 1e-14);
  EXPECT_GT(e_after_stop + 9.81, 1e-2);  // it took up energy from the jerks
  // Two output grids, the same kinks: the same motion to the global error (1e-9 m at rtol
  // 1e-10); 1e-7 m is margin.
  EXPECT_LT((xa.x - xb.x).cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_LT((xa.v - xb.v).cwiseAbs().maxCoeff(), 1e-6);
}

// A pendulum hanging from a kinematic particle that oscillates vertically from t = 0: the rigid
// rod carries the bob along, y_bob = y_pivot - L (the velocity at the motion's start is its right
// limit A w, applied by the initial projection), and the rod force is m (g + a_pivot):
// lambda = -m (g - A w^2 sin(w t)). Checks the prescribed velocity and acceleration of a moving
// end.
TEST(RefDae, VerticallyOscillatingPivotCarriesTheBob) {
  Scene s = pendulum(0.0);
  Motion motion;
  motion.kind = MotionKind::Oscillate;
  motion.amplitude = Vec3(0.0, 0.05, 0.0);
  motion.frequency = 2.0;
  s.model.motions.push_back(motion);
  s.model.attachments[0].motion = 0;
  s.initial = rest_state(s.model);
  auto solver = make_solver(dae_options(), s.model);
  State state = s.initial;
  const double w = 2.0 * std::numbers::pi * 2.0, A = 0.05;
  double worst_y = 0.0, worst_lambda = 0.0;
  for (int k = 0; k < 100; ++k) {
    solver->step(s.model, state, 0.01);
    const double t = state.time;
    worst_y = std::max(worst_y, std::abs(state.x(1, 1) - (A * std::sin(w * t) - 1.0)));
    worst_lambda = std::max(worst_lambda, std::abs(state.lambda[0] + (9.81 - A * w * w * std::sin(w * t))));
    EXPECT_NEAR(state.x(1, 0), 0.0, 1e-12);
  }
  if (verbose())
    std::printf("oscillating pivot: max |y - closed form| %.3e m, max |lambda - closed form| %.3e N\n",
                worst_y, worst_lambda);
  // Positions to the global error of rtol 1e-10 on a 1 m pendulum (measured 1e-11 m). The
  // multiplier comes from the output state and the closed-form acceleration of the pivot, with
  // the bob exactly below it: round-off of sums of terms of order 10 N (measured 2e-15 N).
  EXPECT_LT(worst_y, 1e-9);
  EXPECT_LT(worst_lambda, 1e-12);
}

// The kinematic end's velocity and acceleration against central differences of its position and
// velocity, for each motion kind, at times inside the smooth parts; and the right limits at the
// start of an Oscillate and a Circle motion.
TEST(RefDae, AttachmentPointDerivativesMatchCentralDifferences) {
  Model model;
  Motion linear, oscillate, circle;
  linear.kind = MotionKind::Linear;
  linear.velocity = Vec3(0.3, -0.2, 0.1);
  linear.start = 0.2;
  linear.stop = 0.9;
  oscillate.kind = MotionKind::Oscillate;
  oscillate.amplitude = Vec3(0.1, 0.05, -0.02);
  oscillate.frequency = 1.7;
  oscillate.start = 0.1;
  circle.kind = MotionKind::Circle;
  circle.axis = Vec3(1.0, 2.0, -0.5).normalized();
  circle.radius = 0.3;
  circle.frequency = 1.5;
  circle.start = 0.25;
  model.motions = {linear, oscillate, circle};
  for (int k = 0; k < 3; ++k) {
    Attachment a;
    a.particle = k;
    a.anchor = Vec3(k, 1.0, -1.0);
    a.motion = k;
    model.attachments.push_back(a);
  }
  // Central differences with h = 1e-5 s: truncation h^2 |x'''| / 6 < 1e-10 * r w^4 ~ 3e-7 for the
  // circle (w = 9.4 rad/s), round-off eps |x| / h ~ 1e-10; 1e-6 + 1e-6 |value| bounds both.
  const double h = 1e-5;
  for (int k = 0; k < 3; ++k) {
    for (const double t : {0.31, 0.52, 0.77, 1.4}) {
      const PrescribedPoint p = ref_dae::attachment_point(model, k, t);
      const PrescribedPoint plus = ref_dae::attachment_point(model, k, t + h);
      const PrescribedPoint minus = ref_dae::attachment_point(model, k, t - h);
      const Vec3 v_fd = (plus.x - minus.x) / (2.0 * h);
      const Vec3 a_fd = (plus.v - minus.v) / (2.0 * h);
      EXPECT_LT((p.v - v_fd).norm(), 1e-6 + 1e-6 * p.v.norm()) << "motion " << k << ", t = " << t;
      EXPECT_LT((p.a - a_fd).norm(), 1e-6 + 1e-6 * p.a.norm()) << "motion " << k << ", t = " << t;
    }
  }
  // Right limits at the start of the smooth motions: the velocity of what follows (A w, r w),
  // not motion_velocity's 0.
  for (int k = 1; k < 3; ++k) {
    const double start = model.motions[static_cast<size_t>(k)].start;
    const PrescribedPoint at = ref_dae::attachment_point(model, k, start);
    const PrescribedPoint after = ref_dae::attachment_point(model, k, start + 1e-9);
    EXPECT_GT(at.v.norm(), 0.1) << "motion " << k;
    EXPECT_LT((at.v - after.v).norm(), 1e-6) << "motion " << k;
    EXPECT_LT((at.a - after.a).norm(), 1e-5) << "motion " << k;
  }
  // The circle's acceleration points to its centre with magnitude r w^2.
  const PrescribedPoint c = ref_dae::attachment_point(model, 2, 0.6);
  const double w = 2.0 * std::numbers::pi * 1.5;
  EXPECT_NEAR(c.a.norm(), 0.3 * w * w, 1e-12 * 0.3 * w * w);
  EXPECT_NEAR(c.a.dot(circle.axis), 0.0, 1e-12);
}

// A model whose particles are all kinematic has nothing to integrate: the particles follow their
// targets, the rigid constraint between two of them has lambda 0 and is not in the drift.
TEST(RefDae, KinematicOnlyModelFollowsItsTargets) {
  Scene s = pendulum(0.3);
  s.model.inv_mass[1] = 0.0;
  Motion motion;
  motion.kind = MotionKind::Linear;
  motion.velocity = Vec3(0.0, 0.0, 2.0);
  s.model.motions.push_back(motion);
  Attachment a;
  a.particle = 1;
  a.anchor = s.model.rest_positions.row(1).transpose();
  a.motion = 0;
  s.model.attachments.push_back(a);
  s.initial = rest_state(s.model);
  auto solver = make_solver(dae_options(), s.model);
  State state = s.initial;
  const StepReport r = solver->step(s.model, state, 0.5);
  EXPECT_NEAR(state.x(1, 2), 1.0, 1e-15);
  EXPECT_EQ(state.lambda[0], 0.0);
  EXPECT_EQ(r.constraint_drift, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Refusals.

TEST(RefDae, RefusesRigidConstraintsOtherThanDistanceNamingThem) {
  Scene s = pendulum(0.5);
  // A rigid volume constraint on four dynamic particles.
  Model& m = s.model;
  const int base = m.particle_count();
  for (const Vec3& p : {Vec3(2, 0, 0), Vec3(3, 0, 0), Vec3(2, 1, 0), Vec3(2, 0, 1)}) {
    m.rest_positions.conservativeResize(m.particle_count() + 1, 3);
    m.rest_positions.row(m.particle_count() - 1) = p.transpose();
    m.inv_mass.push_back(1.0);
    m.radius.push_back(0.01);
  }
  Constraint c;
  c.kind = ConstraintKind::Volume;
  c.particles = {base, base + 1, base + 2, base + 3};
  c.rest = 1.0 / 6.0;
  c.compliance = 0.0;
  m.constraints.push_back(c);
  expect_throw_naming<std::invalid_argument>(
      [&] { make_solver(dae_options(), m); },
      {"constraint 1", "volume", "rigid", "distance constraints only"});
}

TEST(RefDae, RefusesCollidersUnlessIgnored) {
  {
    Scene s = pendulum(0.5);
    s.model.planes.push_back(PlaneCollider{});
    expect_throw_naming<std::invalid_argument>([&] { make_solver(dae_options(), s.model); },
                                               {"plane collider 0", "ignore_colliders"});
    SolverOptions o = dae_options();
    o.ref_ignore_colliders = true;
    auto solver = make_solver(o, s.model);
    State st = s.initial;
    EXPECT_NO_THROW(solver->step(s.model, st, 0.01));
  }
  {
    Scene s = pendulum(0.5);
    s.model.spheres.push_back(SphereCollider{});
    expect_throw_naming<std::invalid_argument>([&] { make_solver(dae_options(), s.model); },
                                               {"sphere collider 0", "ignore_colliders"});
  }
  {
    Scene s = pendulum(0.5);
    s.model.particle_contact = true;
    expect_throw_naming<std::invalid_argument>([&] { make_solver(dae_options(), s.model); },
                                               {"particle contact", "ignore_colliders"});
  }
}

TEST(RefDae, RefusesInitialPositionsOffTheConstraintsNamingTheWorst) {
  const Scene scene = chain(4, Vec3(0.0, -1.0, 0.0));
  State state = scene.initial;
  state.x(2, 1) -= 1e-6;  // stretches link 1 by 1e-6 m, shortens link 2 by 1e-6 m
  state.x(4, 1) -= 3e-6;  // stretches link 3 by 3e-6 m: the largest
  auto solver = make_solver(dae_options(1e-8, 1e-10), scene.model);
  expect_throw_naming<std::invalid_argument>(
      [&] { solver->step(scene.model, state, 0.01); },
      {"constraint 3 (distance, particles 3 4", "|C| = 3e-06"});
}

TEST(RefDae, NonPositiveTimeStepThrows) {
  const Scene scene = pendulum(0.5);
  auto solver = make_solver(dae_options(), scene.model);
  State state = scene.initial;
  for (const double dt : {0.0, -0.01, std::nan("")})
    expect_throw_naming<std::invalid_argument>([&] { solver->step(scene.model, state, dt); },
                                               {"dt = "});
  EXPECT_EQ(state.time, 0.0);
}

// ---------------------------------------------------------------------------------------------
// Determinism, restarts and the report.

TEST(RefDae, TwoRunsAreIdentical) {
  const Scene scene = chain(5, Vec3(std::sqrt(0.5), -std::sqrt(0.5), 0.0));
  const auto run = [&] {
    auto solver = make_solver(dae_options(1e-8, 1e-10), scene.model);
    State s = scene.initial;
    for (int k = 0; k < 100; ++k) solver->step(scene.model, s, 0.01);
    return s;
  };
  const State a = run(), b = run();
  EXPECT_TRUE(a.x == b.x);
  EXPECT_TRUE(a.v == b.v);
  EXPECT_TRUE(a.lambda == b.lambda);
  EXPECT_EQ(a.time, b.time);
  EXPECT_EQ(a.step, b.step);
}

// A state changed between steps (here: set back to an earlier one) restarts the integration
// from it: the result is what a fresh solver gives from that state.
TEST(RefDae, RestartsFromAStateItDidNotWrite) {
  const Scene scene = chain(3, Vec3(1.0, 0.0, 0.0));
  auto fresh = make_solver(dae_options(1e-8, 1e-10), scene.model);
  auto reused = make_solver(dae_options(1e-8, 1e-10), scene.model);
  State other = scene.initial;
  for (int k = 0; k < 37; ++k) reused->step(scene.model, other, 0.01);
  State a = scene.initial, b = scene.initial;
  for (int k = 0; k < 50; ++k) {
    fresh->step(scene.model, a, 0.01);
    reused->step(scene.model, b, 0.01);
  }
  EXPECT_TRUE(a.x == b.x);
  EXPECT_TRUE(a.v == b.v);
  EXPECT_TRUE(a.lambda == b.lambda);
}

TEST(RefDae, ReportIsFilled) {
  const Scene scene = pendulum(1.0);
  auto solver = make_solver(dae_options(1e-8, 1e-10), scene.model);
  EXPECT_EQ(solver->name(), "ref-dae");
  State state = scene.initial;
  long steps = 0, newton = 0, setups = 0, solves = 0;
  for (int k = 0; k < 20; ++k) {
    const StepReport r = solver->step(scene.model, state, 0.05);
    EXPECT_GE(r.ref_steps, 0);
    EXPECT_GE(r.error_test_failures, 0);
    EXPECT_GE(r.convergence_failures, 0);
    EXPECT_TRUE(std::isfinite(r.constraint_drift));
    EXPECT_GE(r.constraint_drift, 0.0);
    EXPECT_GE(r.time_linear, 0.0);
    EXPECT_TRUE(std::isnan(r.residual_g));
    // Each Newton iteration solves once with a factorisation.
    EXPECT_EQ(r.linear_solves, r.newton_iterations);
    steps += r.ref_steps;
    newton += r.newton_iterations;
    setups += r.linear_setups;
    solves += r.linear_solves;
  }
  EXPECT_GT(steps, 0);
  EXPECT_GE(newton, steps);
  EXPECT_GT(setups, 0);
  EXPECT_GT(solves, 0);
  EXPECT_EQ(state.step, 20);
  EXPECT_NEAR(state.time, 1.0, 1e-15);
}

}  // namespace
}  // namespace pbdbench
