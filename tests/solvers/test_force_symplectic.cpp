// Tests of solvers/force_symplectic.cpp: explicit symplectic Euler with springs and penalty
// contacts, against the closed forms of the linear spring (period, invariant, stability limit,
// damping), a resting contact, momentum, FEM energy gradients and determinism.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "core/fem.hpp"
#include "metrics/metrics.hpp"
#include "solver_test_util.hpp"
#include "solvers/force_symplectic.hpp"

namespace pbdbench::test {
namespace {

Scene catalog_scene(const std::string& name, const std::vector<std::string>& sets = {}) {
  std::vector<config::Override> o;
  for (const std::string& s : sets) o.push_back(config::parse_override(s));
  return config::build_scene(config::load(name, o));
}

SolverOptions force_options(int substeps = 1) {
  return options_for("force-symplectic", 10, substeps);
}

// The catalog spring (scenarios/spring.toml): a 1 kg particle on a link of compliance 1e-3 m/N
// along +x from a pinned anchor at the origin, rest 1 m, released at rest at 1.5 m, no gravity.
// C = x - 1 exactly (the link stays on the +x axis), so the motion is the linear oscillator
// u'' = -omega^2 u, u = x - 1, omega = 1 / sqrt(m alpha).
struct SpringRun {
  std::vector<double> t, u, v;  // per step, from the initial state on
};
SpringRun run_spring(const Scene& scene, double dt, int steps, int substeps = 1) {
  SpringRun r;
  State s = scene.initial;
  auto sv = make_solver(force_options(substeps), scene.model);
  const double rest = scene.model.constraints[0].rest;
  r.t.push_back(s.time);
  r.u.push_back(s.x(1, 0) - rest);
  r.v.push_back(s.v(1, 0));
  for (int k = 0; k < steps; ++k) {
    sv->step(scene.model, s, dt);
    r.t.push_back(s.time);
    r.u.push_back(s.x(1, 0) - rest);
    r.v.push_back(s.v(1, 0));
  }
  return r;
}

double spring_omega(const Scene& scene) {
  return 1.0 / std::sqrt(scene.model.constraints[0].compliance / scene.model.inv_mass[1]);
}

// Period from the zero crossings of u, interpolated linearly between steps: twice the mean time
// between successive crossings.
double measured_period(const SpringRun& r) {
  std::vector<double> crossings;
  for (size_t k = 0; k + 1 < r.u.size(); ++k)
    if ((r.u[k] > 0.0) != (r.u[k + 1] > 0.0))
      crossings.push_back(r.t[k] + (r.t[k + 1] - r.t[k]) * r.u[k] / (r.u[k] - r.u[k + 1]));
  if (crossings.size() < 3) return std::nan("");
  return 2.0 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
}

TEST(ForceSymplectic, SpringFollowsTheSymplecticEulerRecurrenceAndKeepsItsInvariant) {
  // Symplectic Euler on u'' = -omega^2 u: v' = v - h omega^2 u, u' = u + h v'. It keeps
  // I = v^2 + omega^2 u^2 - h omega^2 u v exactly (I(u', v') = omega^2 u^2 + v v' = I(u, v)),
  // so the energy E = (m v^2 + u^2 / alpha) / 2 = m (v^2 + omega^2 u^2) / 2 never drifts: it
  // differs from m I / 2 by m h omega^2 u v / 2, at most omega h / 2 of E; released at rest
  // (E0 = m I / 2), |E - E0| <= (omega h / 2) / (1 - omega h / 2) E0.
  const Scene scene = catalog_scene("spring");
  const double omega = spring_omega(scene), h = 1.0 / 60.0, m = 1.0 / scene.model.inv_mass[1];
  const SpringRun r = run_spring(scene, h, 600);  // 10 s, 50 periods
  double u = r.u[0], v = r.v[0];
  const double I0 = v * v + omega * omega * u * u - h * omega * omega * u * v;
  const double E0 = 0.5 * m * (v * v + omega * omega * u * u);
  double max_dE = 0.0;
  for (size_t k = 1; k < r.u.size(); ++k) {
    v -= h * omega * omega * u;
    u += h * v;
    // kRoundoff on u (order 1): the recurrence and the solver round differently (the solver
    // carries x = 1 + u); 1e-10 on v = O(omega u) = 16 m/s.
    ASSERT_NEAR(r.u[k], u, 1e-11) << "step " << k;
    ASSERT_NEAR(r.v[k], v, 1e-10) << "step " << k;
    const double I = r.v[k] * r.v[k] + omega * omega * r.u[k] * r.u[k] -
                     h * omega * omega * r.u[k] * r.v[k];
    ASSERT_NEAR(I, I0, 1e-11 * I0) << "step " << k;
    const double E = 0.5 * m * (r.v[k] * r.v[k] + omega * omega * r.u[k] * r.u[k]);
    max_dE = std::max(max_dE, std::abs(E - E0));
  }
  const double bound = 0.5 * omega * h / (1.0 - 0.5 * omega * h) * E0;
  EXPECT_LE(max_dE, bound * (1.0 + 1e-12));
  EXPECT_GT(max_dE, 0.9 * bound);  // and the energy does swing that far, every period
}

TEST(ForceSymplectic, SpringPeriodIsTheClosedFormToSecondOrder) {
  // The discrete solution is u_n = R cos(w n h + phi) with cos(w h) = 1 - (omega h)^2 / 2, i.e.
  // w = (2/h) asin(omega h / 2) > omega: the period 2 pi / w falls short of 2 pi sqrt(m alpha)
  // by (omega h)^2 / 24 relative, to leading order. Halving h quarters the error.
  const Scene scene = catalog_scene("spring");
  const double omega = spring_omega(scene);
  const double exact = 2.0 * M_PI / omega;  // 2 pi sqrt(m alpha) = 0.19869 s
  EXPECT_NEAR(exact, 2.0 * M_PI * std::sqrt(1e-3 * 1.0), 1e-15);
  std::vector<double> errors;
  for (double h : {1.0 / 60.0, 1.0 / 120.0, 1.0 / 240.0}) {
    const SpringRun r = run_spring(scene, h, static_cast<int>(std::lround(5.0 / h)));
    const double period = measured_period(r);
    const double discrete = 2.0 * M_PI / ((2.0 / h) * std::asin(omega * h / 2.0));
    // Linear interpolation of a zero crossing errs by O(h (omega h)^2) per crossing, not
    // accumulated: 2e-4 s at 1/60 s, over 50 crossings 8e-6 s of the period.
    EXPECT_NEAR(period, discrete, 1e-4 * exact) << "h = " << h;
    const double relative = (period - exact) / exact;
    EXPECT_NEAR(relative, -(omega * h) * (omega * h) / 24.0, 0.1 * (omega * h) * (omega * h) / 24.0)
        << "h = " << h;
    errors.push_back(relative);
  }
  EXPECT_NEAR(errors[0] / errors[1], 4.0, 0.2);
  EXPECT_NEAR(errors[1] / errors[2], 4.0, 0.2);
}

// Steps until the run counts as exploded under the default limits (metrics/metrics.hpp), or -1.
int steps_to_explosion(const Scene& scene, double dt, int steps, double* max_u = nullptr) {
  State s = scene.initial;
  auto sv = make_solver(force_options(), scene.model);
  const MetricsBaseline baseline = measure_baseline(scene.model, s);
  const ExplosionLimits limits;
  if (max_u) *max_u = 0.0;
  for (int k = 1; k <= steps; ++k) {
    sv->step(scene.model, s, dt);
    if (max_u) *max_u = std::max(*max_u, std::abs(s.x(1, 0) - scene.model.constraints[0].rest));
    const Sample sample = measure(scene.model, s, baseline);
    if (!explosion_reason(scene.model, s, sample, limits, baseline).empty()) return k;
  }
  return -1;
}

TEST(ForceSymplectic, ExplicitStabilityLimitIsOmegaHEqualsTwo) {
  // The step matrix of symplectic Euler on the oscillator has trace 2 - (omega h)^2 and
  // determinant 1: its eigenvalues leave the unit circle when omega h > 2. Below the limit the
  // invariant I bounds |u| by u0 / sqrt(1 - (omega h / 2)^2).
  const Scene scene = catalog_scene("spring");
  const double omega = spring_omega(scene), u0 = 0.5;
  for (double wh : {2.05, 2.5}) {
    const int k = steps_to_explosion(scene, wh / omega, 2000);
    EXPECT_GT(k, 0) << "omega h = " << wh << " should explode";
  }
  // (Not omega h = 1: there w h = pi / 3, the samples repeat every 6 steps and never pass u0.)
  for (double wh : {1.1, 1.5}) {
    const double dt = wh / omega;
    double max_u = 0.0;
    EXPECT_EQ(steps_to_explosion(scene, dt, static_cast<int>(10.0 / dt), &max_u), -1)
        << "omega h = " << wh;
    const double bound = u0 / std::sqrt(1.0 - wh * wh / 4.0);
    EXPECT_LE(max_u, bound * (1.0 + 1e-12)) << "omega h = " << wh;
    EXPECT_GT(max_u, u0 + 0.9 * (bound - u0)) << "omega h = " << wh;  // the orbit's width
  }
  // Substeps split dt: omega dt = 2.5 with 2 substeps is omega h = 1.25, stable.
  {
    State s = scene.initial;
    auto sv = make_solver(force_options(2), scene.model);
    for (int k = 0; k < 400; ++k) sv->step(scene.model, s, 2.5 / omega);
    EXPECT_LE(std::abs(s.x(1, 0) - 1.0), u0 / std::sqrt(1.0 - 1.25 * 1.25 / 4.0) * (1.0 + 1e-12));
  }
}

// A particle of mass m on a distance link of compliance alpha and damping beta to an anchor at
// the origin, along +x, released at rest at 1 + u0 (rest 1), no gravity.
Model spring_model(double mass, double compliance, double damping) {
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(1.0, 0, 0), mass);
  add_distance(m, 0, 1, 1.0, 1.0, compliance, damping);
  return m;
}

TEST(ForceSymplectic, DampingIsXpbdsDamper) {
  // beta is a damper of coefficient c = beta on dC/dt (N s/m), as xpbd's continuous model
  // (docs/solvers.md): the amplitude decays as exp(-beta t / (2 m)). The step's determinant is
  // 1 - h beta / m, so the discrete decay differs by O(h): at omega h = 0.03, beta h / m = 5e-4,
  // the extrema after 2 s are within 1e-3 of the closed form. Without damping, no decay.
  const double mass = 1.0, alpha = 1e-3, u0 = 0.5, h = 1e-3;
  for (double beta : {0.0, 0.5, 2.0}) {
    const Model m = spring_model(mass, alpha, beta);
    State s = rest_state(m);
    s.x(1, 0) = 1.0 + u0;
    auto sv = make_solver(force_options(), m);
    std::vector<double> u = {u0};
    for (int k = 0; k < 2000; ++k) {
      sv->step(m, s, h);
      u.push_back(s.x(1, 0) - 1.0);
    }
    int checked = 0;
    for (size_t k = 1; k + 1 < u.size(); ++k) {
      const double a = std::abs(u[k - 1]), b = std::abs(u[k]), c = std::abs(u[k + 1]);
      if (!(b >= a && b > c)) continue;
      // The extremum of the parabola through the three samples.
      const double denom = a - 2.0 * b + c;
      const double shift = 0.5 * (a - c) / denom;
      const double peak = b - 0.25 * (a - c) * shift;
      const double t = (static_cast<double>(k) + shift) * h;
      if (t < 1.0) continue;
      EXPECT_NEAR(peak / u0, std::exp(-beta * t / (2.0 * mass)), 1e-3)
          << "beta " << beta << " t " << t;
      ++checked;
    }
    EXPECT_GE(checked, 9);  // the extrema of |u| from 1 s to 2 s, two a period of 0.2 s
  }
}

TEST(ForceSymplectic, DampingTightensTheStabilityLimit) {
  // With a damper, the step matrix has trace 2 - (omega h)^2 - h beta/m and determinant
  // 1 - h beta/m; both eigenvalues stay inside the unit circle iff 0 < h beta/m < 2 and
  // (omega h)^2 + 2 h beta/m < 4. At omega h = 1.9 (stable undamped), h beta/m = 0.15 is stable
  // and 0.25 is not: explicit damping lowers the step the springs allow.
  // The spectral radius is 0.922 a step for 0.15 and 1.269 for 0.25: after 40 steps from a
  // stretch u0, the largest |u| of the last 10 steps is below u0 in the first case and above
  // 100 u0 in the second (u0 1.27^40 = 0.014 m, far below the 1 m rest length: the spring stays
  // linear).
  const double mass = 1.0, alpha = 1e-3, u0 = 1e-6;
  const double omega = 1.0 / std::sqrt(mass * alpha), h = 1.9 / omega;
  for (double b : {0.15, 0.25}) {
    const Model m = spring_model(mass, alpha, b * mass / h);
    State s = rest_state(m);
    s.x(1, 0) = 1.0 + u0;
    auto sv = make_solver(force_options(), m);
    double late = 0.0;
    for (int k = 1; k <= 40; ++k) {
      sv->step(m, s, h);
      if (k > 30) late = std::max(late, std::abs(s.x(1, 0) - 1.0));
    }
    if (b < 0.2) {
      EXPECT_LT(late, u0) << "h beta / m = " << b;
    } else {
      EXPECT_GT(late, 100.0 * u0) << "h beta / m = " << b;
    }
  }
}

TEST(ForceSymplectic, LambdaIsTheConstraintForce) {
  // A particle hanging at its static equilibrium (stretch m g alpha) stays there, and lambda is
  // the force per unit of C (State::lambda's convention): -m g along grad C = (0, -1, 0), so the
  // force on the particle, grad C lambda, is m g up.
  const double mass = 2.0, alpha = 1e-4, g = 9.81;
  Model m = empty_model(Vec3(0, -g, 0));
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(0, -1.0, 0), mass);
  add_distance(m, 0, 1, 1.0, 1.0, alpha, 0.3);
  for (int substeps : {1, 4}) {
    State s = rest_state(m);
    s.x(1, 1) = -(1.0 + mass * g * alpha);
    auto sv = make_solver(force_options(substeps), m);
    for (int i = 0; i < 10; ++i) sv->step(m, s, 0.01);
    ASSERT_EQ(s.lambda.size(), 1u);
    EXPECT_NEAR(s.lambda[0], -mass * g, 1e-9 * mass * g) << substeps << " substeps";
    EXPECT_NEAR(s.x(1, 1), -(1.0 + mass * g * alpha), kRoundoff) << substeps << " substeps";
  }
}

// A particle of mass `mass` and radius 0.01 m above the plane y = 0.
Model particle_on_plane(double mass) {
  Model m = empty_model(Vec3(0, -9.81, 0));
  test::add_particle(m, Vec3(0.0, 0.01, 0.0), mass, 0.01);
  m.planes.push_back({Vec3::UnitY(), 0.0, 0.0, 0.0});
  return m;
}

TEST(ForceSymplectic, PenaltyContactRestsAtDepthMgOverK) {
  // At rest the contact force balances gravity: k_c (-C) = m g, C = -m g / k_c. Critically damped
  // (d_c = 2 sqrt(k_c m)), the particle released touching the plane settles there.
  const double mass = 0.1, g = 9.81;
  for (double k : {1e3, 1e4, 1e5}) {
    const Model m = particle_on_plane(mass);
    SolverOptions o = force_options();
    o.force_contact_stiffness = k;
    o.force_contact_damping = 2.0 * std::sqrt(k * mass);
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    StepReport r;
    for (int i = 0; i < 20000; ++i) r = sv->step(m, s, 1e-4);
    const double C = s.x(0, 1) - 0.01;
    EXPECT_NEAR(C, -mass * g / k, 1e-10 * mass * g / k) << "k_c = " << k;
    EXPECT_NEAR(s.v(0, 1), 0.0, 1e-12) << "k_c = " << k;
    EXPECT_EQ(r.contacts, 1);
    EXPECT_EQ(r.active_contacts, 1);
    EXPECT_EQ(r.iterations, 0);
  }
}

TEST(ForceSymplectic, ContactForceClosedFormAndNeverPulls) {
  // F = max(0, k_c (-C) - d_c v_n): pushing while approaching; zero, not negative, when the
  // damper would pull a fast-separating particle back.
  const double mass = 0.1, g = 9.81, k = 1e4, d = 1e3, depth = 1e-4, h = 1e-3;
  const Model m = particle_on_plane(mass);
  for (double vy : {-1.0, 1.0}) {
    SolverOptions o = force_options();
    o.force_contact_stiffness = k;
    o.force_contact_damping = d;
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    s.x(0, 1) = 0.01 - depth;
    s.v(0, 1) = vy;
    const double F = std::max(0.0, k * depth - d * vy);
    sv->step(m, s, h);
    EXPECT_NEAR(s.v(0, 1), vy + h * (-g + F / mass), kRoundoff) << "v_n = " << vy;
  }
}

TEST(ForceSymplectic, InternalForcesConserveLinearAndAngularMomentum) {
  // Springs, dampers and particle contacts are internal and torque-free (sum_i x_i x grad_i C = 0
  // for every rotation-invariant C; contact forces act along x_a - x_b). Symplectic Euler changes
  // L by h sum_i x_i x f_i (x at the start of the step), so both momenta are kept to round-off,
  // relative to sum m |v| (before or after, the larger).
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Random rng(seed);
    Model m = random_internal_model(rng);
    for (Constraint& c : m.constraints) c.compliance = std::max(c.compliance, 1e-5);
    for (double& r : m.radius) r = 0.3;
    m.particle_contact = true;
    State s = random_velocities(m, rng);
    const Vec3 p0 = linear_momentum(m, s), l0 = angular_momentum(m, s);
    const double scale0 = momentum_scale(m, s);
    auto sv = make_solver(force_options(3), m);
    StepReport r = sv->step(m, s, 1e-3);
    const double scale = std::max(scale0, momentum_scale(m, s));
    EXPECT_LT((linear_momentum(m, s) - p0).norm(), kRoundoff * scale) << "seed " << seed;
    EXPECT_LT((angular_momentum(m, s) - l0).norm(), kRoundoff * scale) << "seed " << seed;
    if (seed == 1) {
      EXPECT_GT(r.active_contacts, 0);  // particle contacts did act
    }
  }
}

TEST(ForceSymplectic, FemForcesAreTheElementEnergyGradient) {
  // A stable neo-Hookean element acts through its constraint pair, C_D^2/(2 alpha_D) +
  // C_H^2/(2 alpha_H) = V0 Psi + const, a corotated one through core/fem.hpp's gradient: in both
  // cases one step from rest velocities changes v_i by -h w_i dE/dx_i.
  for (Material material : {Material::StableNeoHookean, Material::Corotated}) {
    Model m = empty_model();
    add_particle(m, Vec3(0, 0, 0), 1.0);
    add_particle(m, Vec3(0.1, 0, 0), 2.0);
    add_particle(m, Vec3(0, 0.1, 0), 1.5);
    add_particle(m, Vec3(0, 0, 0.1), 0.5);
    fem::add_fem_elements(m, {{0, 1, 2, 3}}, material, 1e4, 0.3);
    State s = rest_state(m);
    s.x(1, 0) += 0.02;
    s.x(2, 2) -= 0.01;
    s.x(3, 1) += 0.015;
    const Points x0 = s.x;
    const double h = 1e-4;
    const fem::Vec12 grad = fem::element_gradient(m.elements[0], x0);
    make_solver(force_options(), m)->step(m, s, h);
    for (int i = 0; i < 4; ++i) {
      const Vec3 expected = -h * m.inv_mass[static_cast<size_t>(i)] * grad.segment<3>(3 * i);
      EXPECT_LT((Vec3(s.v.row(i)) - expected).norm(), 1e-9 * grad.norm() * h)
          << to_string(material) << " particle " << i;
    }
  }
}

TEST(ForceSymplectic, RigidConstraintsAreRefusedByKind) {
  const Model chain = chain_model(3, 0.1, 1.0, Vec3(0, -9.81, 0));  // compliance 0
  try {
    make_solver(force_options(), chain);
    ADD_FAILURE() << "a rigid distance constraint was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("constraint 0 (distance"), std::string::npos) << what;
    EXPECT_NE(what.find("needs a compliance"), std::string::npos) << what;
  }
  Model bend = chain_model(3, 0.1, 1.0, Vec3::Zero(), 1.0, 1e-6);
  add_bending(bend, 1, 2, 0, 3, 1.0, 1.0, 0.0);
  try {
    make_solver(force_options(), bend);
    ADD_FAILURE() << "a rigid bending constraint was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("constraint 3 (bending"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(make_solver(force_options(), chain_model(3, 0.1, 1.0, Vec3::Zero(), 1.0, 1e-6)));
}

TEST(ForceSymplectic, BadContactOptionsNameTheField) {
  const Model m = particle_on_plane(1.0);
  SolverOptions o = force_options();
  o.force_contact_stiffness = 0.0;
  EXPECT_THROW(
      {
        try {
          make_solver(o, m);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("solver.force.contact_stiffness"),
                    std::string::npos);
          throw;
        }
      },
      std::invalid_argument);
  o = force_options();
  o.force_contact_damping = -1.0;
  EXPECT_THROW(
      {
        try {
          make_solver(o, m);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("solver.force.contact_damping"), std::string::npos);
          throw;
        }
      },
      std::invalid_argument);
}

TEST(ForceSymplectic, KinematicParticlesFollowTheirTargets) {
  // A particle hanging from a kinematic one moving in a circle: the kinematic particle is at its
  // target at the end of every step, with the motion's velocity.
  Model m = empty_model(Vec3(0, -9.81, 0));
  const int k = add_particle(m, Vec3(0, 1, 0), 0.0);
  add_particle(m, Vec3(0, 0.8, 0), 0.1);
  add_rest_distance(m, k, 1, 1.0, 1e-3);
  Motion circle;
  circle.kind = MotionKind::Circle;
  circle.radius = 0.2;
  circle.frequency = 0.5;
  m.motions.push_back(circle);
  m.attachments.back().motion = 0;
  auto sv = make_solver(force_options(3), m);
  State s = rest_state(m);
  for (int i = 0; i < 30; ++i) {
    sv->step(m, s, 0.01);
    // (the last substep ends at time + 3 (dt / 3), within an ulp of the step's end)
    EXPECT_LT((Vec3(s.x.row(k)) - attachment_target(m, m.attachments[0], s.time)).norm(),
              kRoundoff);
    EXPECT_LT((Vec3(s.v.row(k)) - motion_velocity(m.motions[0], s.time)).norm(), kRoundoff);
  }
  EXPECT_TRUE(s.x.allFinite());
  EXPECT_GT((Vec3(s.x.row(1)) - Vec3(0, 0.8, 0)).norm(), 1e-3);  // the hanging particle moved
}

TEST(ForceSymplectic, RunsAreBitForBitRepeatable) {
  // The catalog bowl (125 balls, particle and bowl contacts) for 30 steps, twice.
  const Scene scene = catalog_scene("balls_in_bowl");
  State runs[2];
  int active = 0;
  for (State& s : runs) {
    s = scene.initial;
    auto sv = make_solver(force_options(4), scene.model);
    for (int i = 0; i < 30; ++i) active += sv->step(scene.model, s, 1.0 / 60.0).active_contacts;
  }
  EXPECT_GT(active, 0);
  EXPECT_TRUE(runs[0].x.allFinite());
  EXPECT_EQ(std::memcmp(runs[0].x.data(), runs[1].x.data(), sizeof(double) * runs[0].x.size()), 0);
  EXPECT_EQ(std::memcmp(runs[0].v.data(), runs[1].v.data(), sizeof(double) * runs[0].v.size()), 0);
}

TEST(ForceSymplectic, IsRegisteredAndReportsItsStep) {
  bool listed = false;
  for (const SolverEntry& info : solver_catalog())
    listed = listed || (info.name == "force-symplectic" && !info.doc.empty());
  EXPECT_TRUE(listed);
  const Scene scene = catalog_scene("hanging_chain");  // compliance 1e-8 m/N: accepted
  auto sv = make_solver(force_options(5), scene.model);
  EXPECT_EQ(sv->name(), "force-symplectic");
  State s = scene.initial;
  const StepReport r = sv->step(scene.model, s, 1e-4);
  EXPECT_EQ(r.substeps, 5);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_TRUE(std::isnan(r.residual_g));
  EXPECT_EQ(static_cast<int>(s.lambda.size()), scene.model.constraint_count());
  EXPECT_EQ(s.step, 1);
  EXPECT_NEAR(s.time, 1e-4, 1e-18);
}

}  // namespace
}  // namespace pbdbench::test
