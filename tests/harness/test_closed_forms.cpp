// Closed forms that whole scenes touch, run through the catalog scenario, the solver and the
// same step loop as every run (references.md, "Closed forms for validation").
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "solver_api/solver.hpp"

using namespace pbdbench;

namespace {

// Complete elliptic integral of the first kind K(k) = pi / (2 AGM(1, sqrt(1 - k^2))).
double elliptic_k(double k) {
  double a = 1.0, b = std::sqrt(1.0 - k * k);
  for (int i = 0; i < 60 && std::abs(a - b) > 1e-16 * a; ++i) {
    const double an = 0.5 * (a + b);
    b = std::sqrt(a * b);
    a = an;
  }
  return std::numbers::pi / (2.0 * a);
}

// Period of a rigid pendulum of length L released from rest at amplitude theta0 (references.md 3).
double pendulum_period(double L, double g, double theta0) {
  return 4.0 * std::sqrt(L / g) * elliptic_k(std::sin(theta0 / 2.0));
}

struct PeriodError {
  double max_rel = 0.0;  // max over measured periods of |T_measured / T(amplitude) - 1|
  int periods = 0;
};

// Runs the catalog pendulum with the given solver and substeps; measures each full period from
// successive upward zero crossings of the angle (linear interpolation) and compares it with the
// elliptic-integral period at the amplitude measured during that period (the integrator may
// damp, references.md 3).
PeriodError measure_pendulum(const std::string& solver, int substeps, double dt) {
  const config::Config cfg = config::load(
      "pendulum", {{"solver.name", "\"" + solver + "\""},
                   {"solver.substeps", std::to_string(substeps)},
                   {"time.dt", std::to_string(dt)}});
  Scene scene = config::build_scene(cfg);
  const Model& model = scene.model;
  State state = scene.initial;
  auto s = make_solver(config::solver_options(cfg), model);
  const double L = cfg.get_double("scene.length");
  const double g = model.gravity.norm();
  const Vec3 pivot = cfg.get_vec3("scene.pivot");
  const int bob = model.particle_count() - 1;
  const long steps = config::run_options(cfg).steps();

  auto angle = [&](const State& st) {
    const Vec3 r = Vec3(st.x.row(bob)) - pivot;
    return std::atan2(r.x(), -r.y());  // 0 hanging down, positive towards +x
  };
  std::vector<double> crossings;  // times of upward zero crossings
  std::vector<double> amplitudes; // max |angle| between crossings
  double prev = angle(state), prev_t = state.time, amp = std::abs(prev);
  for (long k = 0; k < steps; ++k) {
    s->step(model, state, dt);
    const double a = angle(state);
    amp = std::max(amp, std::abs(a));
    if (prev < 0.0 && a >= 0.0) {
      crossings.push_back(prev_t + (state.time - prev_t) * (-prev) / (a - prev));
      amplitudes.push_back(amp);
      amp = 0.0;
    }
    prev = a;
    prev_t = state.time;
  }
  PeriodError e;
  for (size_t i = 1; i < crossings.size(); ++i) {
    const double measured = crossings[i] - crossings[i - 1];
    const double expected = pendulum_period(L, g, amplitudes[i]);
    e.max_rel = std::max(e.max_rel, std::abs(measured / expected - 1.0));
    ++e.periods;
  }
  return e;
}

}  // namespace

TEST(ClosedForms, EllipticPeriodRatios) {
  // references.md 3: T/T0 = 1.0174 at 30 deg, 1.1803 at 90 deg, 1.7622 at 150 deg.
  const double T0 = 2.0 * std::numbers::pi;  // L = g
  EXPECT_NEAR(pendulum_period(1.0, 1.0, 30.0 * std::numbers::pi / 180.0) / T0, 1.0174, 5e-5);
  EXPECT_NEAR(pendulum_period(1.0, 1.0, 90.0 * std::numbers::pi / 180.0) / T0, 1.1803, 5e-5);
  EXPECT_NEAR(pendulum_period(1.0, 1.0, 150.0 * std::numbers::pi / 180.0) / T0, 1.7622, 5e-5);
}

// The catalog pendulum (90 degrees, rigid link) with XPBD: the period at the measured amplitude
// matches the elliptic integral, and the error shrinks as the substep shrinks (first-order
// method: halving h should at least roughly halve it).
TEST(ClosedForms, PendulumPeriodMatchesEllipticIntegral) {
  const PeriodError coarse = measure_pendulum("xpbd", 10, 0.01);  // h = 1e-3 s
  const PeriodError fine = measure_pendulum("xpbd", 40, 0.01);    // h = 2.5e-4 s
  ASSERT_GE(coarse.periods, 3);
  ASSERT_GE(fine.periods, 3);
  std::printf("pendulum period error: h = 1e-3 s: %.3g, h = 2.5e-4 s: %.3g\n", coarse.max_rel, fine.max_rel);
  EXPECT_LT(fine.max_rel, coarse.max_rel / 2.0);
  EXPECT_LT(fine.max_rel, 1e-3);
}
