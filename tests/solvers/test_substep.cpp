// Tests of solvers/substep.cpp: the substep pbd and xpbd share, and its precision
// (solver.precision): "double" pinned bit for bit on this build; "float" computes in float32 and
// stores every value of the state as a float.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "solver_test_util.hpp"
#include "solvers/step_common.hpp"

namespace pbdbench::test {
namespace {

// FNV-1a over the bits of x, v and lambda, continuing from h.
std::uint64_t state_hash(const State& s, std::uint64_t h) {
  auto eat = [&](const double* p, size_t n) {
    const auto* b = reinterpret_cast<const unsigned char*>(p);
    for (size_t i = 0; i < sizeof(double) * n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  };
  eat(s.x.data(), static_cast<size_t>(s.x.size()));
  eat(s.v.data(), static_cast<size_t>(s.v.size()));
  eat(s.lambda.data(), s.lambda.size());
  return h;
}

// 40 steps of 1/60 s (5 iterations, 2 substeps, contact margin 0.01 m) from a moving start; the
// hash of the states after every step.
std::uint64_t hash_run(const SolverOptions& o) {
  const Model m = mixed_scene();
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  for (int i = 0; i < m.particle_count(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      s.v.row(i) = Vec3(0.3, -0.5 - 0.1 * i, 0.2).transpose();
  std::uint64_t h = 1469598103934665603ull;
  long active = 0;
  for (int k = 0; k < 40; ++k) {
    active += sv->step(m, s, 1.0 / 60.0).active_contacts;
    h = state_hash(s, h);
  }
  // The run must reach the contacts and stay finite, or its hash would pin little.
  EXPECT_GT(active, 0) << to_string(o.order);
  EXPECT_TRUE(s.x.allFinite() && s.v.allFinite()) << to_string(o.order);
  return h;
}

SolverOptions hash_options(const std::string& name, ProjectionOrder order, int variant) {
  SolverOptions o = options_for(name, 5, 2);
  o.order = order;
  o.contact_margin = 0.01;
  if (variant == 1) {
    o.pbd_stiffness_correction = true;
    o.pbd_velocity_damping = 0.1;
    o.jacobi_relaxation = 0.7;
    o.jacobi_averaging = false;
  }
  return o;
}

TEST(Substep, DoublePrecisionBitsArePinned) {
  // The bits of 40 steps of the mixed scene in every order, recorded by this build's flags
  // (Release, -ffp-contract=off, g++ 12) with the compiled projections (their kernels and the
  // acos-free bending round differently from the per-item reference path, which
  // is compared with them in test_compiled_projection.cpp). The results do not depend on the
  // processor's vector width or the thread count. Variant 1 turns on pbd's stiffness correction
  // and velocity damping and unaveraged, relaxed Jacobi.
  const std::vector<std::string> names = {"pbd", "xpbd"};
  const std::uint64_t expected[2][2][kProjectionOrderCount] = {
      {{0xb12ef486b7fd3b9full, 0xffbb146ddd785d15ull, 0xeb4deeec6cb2aee1ull, 0x790c85496c8ed195ull,
        0x5e33dd6397842d8bull, 0xbd76308367c471c8ull, 0xaf7c16c8e01ea50aull},
       {0x42ee49ab2d988416ull, 0x9440ab5fcec5580eull, 0xb02a1b0a4382a8b1ull, 0x03c67e155581bc13ull,
        0xe9dbe461671ba9c9ull, 0xc86e5471d88ec4fbull, 0x5324435dd2ca3951ull}},
      {{0x037ef9d6f11ac729ull, 0xafe7e51b80328162ull, 0x1c704bb10a773cd7ull, 0xcd5825ec7d926b99ull,
        0x37d6a0a1e6092a16ull, 0x86fd7b7ed31c32a2ull, 0x769096ef6e082189ull},
       {0x037ef9d6f11ac729ull, 0xafe7e51b80328162ull, 0x1c704bb10a773cd7ull, 0xcd5825ec7d926b99ull,
        0x978aa428911baac3ull, 0x86fd7b7ed31c32a2ull, 0x769096ef6e082189ull}}};
  for (size_t n = 0; n < names.size(); ++n)
    for (int variant = 0; variant < 2; ++variant)
      for (int k = 0; k < kProjectionOrderCount; ++k) {
        const SolverOptions o = hash_options(names[n], static_cast<ProjectionOrder>(k), variant);
        const std::uint64_t got = hash_run(o);
        EXPECT_EQ(got, expected[n][static_cast<size_t>(variant)][k])
            << names[n] << " variant " << variant << " " << to_string(o.order);
      }
}

// The spacing of floats at |value|: 2^-23 |value| rounded down to a power of two.
double float_ulp(double value) {
  const float f = std::abs(static_cast<float>(value));
  return static_cast<double>(std::nextafter(f, std::numeric_limits<float>::infinity()) - f);
}

bool all_floats(const Points& p) {
  for (Eigen::Index i = 0; i < p.size(); ++i)
    if (round_to_float(p.data()[i]) != p.data()[i]) return false;
  return true;
}

TEST(Substep, PrecisionNames) {
  Precision p = Precision::Float;
  EXPECT_TRUE(parse_precision("double", p));
  EXPECT_EQ(p, Precision::Double);
  EXPECT_TRUE(parse_precision("float", p));
  EXPECT_EQ(p, Precision::Float);
  EXPECT_FALSE(parse_precision("single", p));
  EXPECT_EQ(p, Precision::Float);  // unchanged
  EXPECT_STREQ(to_string(Precision::Double), "double");
  EXPECT_STREQ(to_string(Precision::Float), "float");
  EXPECT_EQ(SolverOptions{}.precision, Precision::Double);
}

TEST(Substep, RoundToFloat) {
  EXPECT_EQ(round_to_float(0.1), static_cast<double>(0.1f));
  EXPECT_NE(round_to_float(0.1), 0.1);
  EXPECT_EQ(round_to_float(0.5), 0.5);
  EXPECT_EQ(round_to_float(1.0 + 0x1.0p-24), 1.0);                  // a tie: to even
  EXPECT_EQ(round_to_float(1.0 + 0x1.8p-24), 1.0 + 0x1.0p-23);      // above the tie: up
  EXPECT_EQ(float_ulp(10.0), 0x1.0p-20);
  Points p(2, 3);
  p << 0.1, -0.2, 0.3, 1e-3, 10.0, -1.0 / 3.0;
  round_to_float(p);
  EXPECT_TRUE(all_floats(p));
  EXPECT_EQ(p(1, 2), static_cast<double>(-1.0f / 3.0f));
}

TEST(Substep, FloatStoresEveryValueAsAFloatAndDiffersFromDouble) {
  // The scene with contacts, friction, restitution, a kinematic particle and a moving sphere, in
  // every order: after every step each position and velocity is a float, and the run is not the
  // double one. With dt = 1/64 s and 2 substeps, h^2 = 2^-14 s^2, so xpbd's forces lambda / h^2
  // are floats exactly when its multipliers lambda are.
  const Model m = mixed_scene();
  for (const std::string name : {"pbd", "xpbd"})
    for (int variant = 0; variant < 2; ++variant)
      for (int k = 0; k < kProjectionOrderCount; ++k) {
        SolverOptions od = hash_options(name, static_cast<ProjectionOrder>(k), variant);
        SolverOptions of = od;
        of.precision = Precision::Float;
        SCOPED_TRACE(name + " variant " + std::to_string(variant) + " " + to_string(od.order));
        auto sd = make_solver(od, m);
        auto sf = make_solver(of, m);
        State a = rest_state(m);
        for (int i = 0; i < m.particle_count(); ++i)
          if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
            a.v.row(i) = Vec3(0.3, -0.5 - 0.1 * i, 0.2).transpose();
        State b = a;
        long active = 0;
        for (int n = 0; n < 40; ++n) {
          sd->step(m, a, 1.0 / 64.0);
          active += sf->step(m, b, 1.0 / 64.0).active_contacts;
          ASSERT_TRUE(all_floats(b.x)) << "step " << n;
          ASSERT_TRUE(all_floats(b.v)) << "step " << n;
          if (name == "xpbd") {
            for (double l : b.lambda) ASSERT_EQ(round_to_float(l), l) << "step " << n;
          }
        }
        EXPECT_GT(active, 0);
        EXPECT_TRUE(b.x.allFinite() && b.v.allFinite());
        EXPECT_GT((a.x - b.x).cwiseAbs().maxCoeff(), 0.0);
        EXPECT_FALSE(all_floats(a.x));  // the double run is not secretly float
      }
}

TEST(Substep, FloatStaysWithinAFewUlpsPerSubstepOfDouble) {
  // A swinging chain of 10 links (top at 2 m, released 0.5 rad from the vertical), both runs
  // from the same float start. Each substep rounds the predicted and projected positions to
  // float, an error of about ulp(|x|) that the velocity (p - x) / h carries into every later
  // substep: after k substeps the positions may differ by k^2 ulps and the velocities by k ulps
  // / h (the largest ulp of the state, 2^-22 m here). Measured, the largest over both solvers
  // and 1, 5, 20 iterations: 0.62 ulp after one substep, 32 ulps after 20 (10 steps of 2
  // substeps) and 723 after 100 (10 steps of 10; the bound is 1e4), with the projections in float
  // (solvers/compiled_projection.hpp).
  for (const std::string name : {"pbd", "xpbd"})
    for (int substeps : {1, 2, 10})
      for (int iterations : {1, 5, 20}) {
        SCOPED_TRACE(name + " substeps " + std::to_string(substeps) + " iterations " +
                     std::to_string(iterations));
        const Model m = chain_model(10, 0.1, 1.0, Vec3(0, -9.81, 0), 1.0, 1e-6, Vec3(0, 2, 0),
                                    Vec3(std::sin(0.5), -std::cos(0.5), 0));
        SolverOptions od = options_for(name, iterations, substeps);
        SolverOptions of = od;
        of.precision = Precision::Float;
        auto sd = make_solver(od, m);
        auto sf = make_solver(of, m);
        State a = rest_state(m);
        round_to_float(a.x);
        State b = a;
        const double dt = 1.0 / 60.0, h = dt / substeps;
        double largest = 0.0;
        for (int n = 1; n <= 10; ++n) {
          sd->step(m, a, dt);
          sf->step(m, b, dt);
          const double u = float_ulp(a.x.cwiseAbs().maxCoeff());
          const double k = static_cast<double>(n) * substeps;
          const double dx = (a.x - b.x).cwiseAbs().maxCoeff();
          const double dv = (a.v - b.v).cwiseAbs().maxCoeff();
          ASSERT_LE(dx, k * k * u) << "step " << n;
          ASSERT_LE(dv, 2.0 * k * u / h) << "step " << n;
          largest = std::max(largest, dx);
        }
        EXPECT_GT(largest, 0.0);
      }
}

// Free fall 10 m from the origin, thrown up at 4.905 m/s for 0.5 s (30 steps of 1/60 s): y stays
// in [10, 12.5), where floats are 2^-20 m apart. Returns the largest errors of x and v against
// the discrete closed form x_n = x0 + v0 t + G t^2 / 2 + G h t / 2, v_n = v0 + G t.
struct FreeFallError {
  double x = 0.0, v = 0.0;
  std::vector<double> vy;  // v_y after each step
};
FreeFallError free_fall_far(const std::string& name, Precision precision, int substeps) {
  const Vec3 G(0.0, -9.81, 0.0), x0(0.0, 10.0, 0.0), v0(0.0, 4.905, 0.0);
  Model m = empty_model(G);
  add_particle(m, x0, 1.0);
  SolverOptions o = options_for(name, 1, substeps);
  o.precision = precision;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  s.v.row(0) = v0.transpose();
  const double dt = 1.0 / 60.0, h = dt / substeps;
  FreeFallError e;
  for (int n = 1; n <= 30; ++n) {
    sv->step(m, s, dt);
    const double t = n * dt;
    const Vec3 x = x0 + v0 * t + 0.5 * G * t * t + 0.5 * G * h * t;
    const Vec3 v = v0 + G * t;
    e.x = std::max(e.x, (Vec3(s.x.row(0)) - x).norm());
    e.v = std::max(e.v, (Vec3(s.v.row(0)) - v).norm());
    e.vy.push_back(s.v(0, 1));
  }
  return e;
}

TEST(Substep, FloatFreeFallFarFromTheOriginLosesGravity) {
  // Each substep rounds p = x + h v to the float grid, 2^-20 m apart at 10 m: the rebuilt
  // velocity (p - x) / h is a multiple of 2^-20 / h, off by up to 2^-21 / h, and that error is
  // kept. Over k substeps the velocity error is at most k 2^-21 / h (plus the rounding of v
  // itself, 2^-22 m/s twice a substep), and it grows with the substeps. Once g h^2 < 2^-21 m
  // (h < 2.2e-4 s: 100 substeps of 1/60 s and more) a substep's gravity g h^2 rounds away: the
  // velocity never changes again, and the error is all of gravity's, g t (4.9 m/s at 0.5 s).
  // Double stays at round-off. Measured (pbd and xpbd alike), the largest velocity error over
  // the run at 1, 10, 100, 1000 substeps: float 6.3e-4, 7.3e-2, 4.90, 4.92 m/s; double 2.1e-13,
  // 8.6e-11, 9.8e-9, 1.2e-6 m/s.
  const double u = 0x1.0p-20;  // float spacing in [8, 16) m
  for (const std::string name : {"pbd", "xpbd"}) {
    SCOPED_TRACE(name);
    double previous_x = 0.0, previous_v = 0.0;
    for (int substeps : {1, 10, 100, 1000}) {
      SCOPED_TRACE("substeps " + std::to_string(substeps));
      const double dt = 1.0 / 60.0, h = dt / substeps;
      const double k = 30.0 * substeps;
      const FreeFallError d = free_fall_far(name, Precision::Double, substeps);
      const FreeFallError f = free_fall_far(name, Precision::Float, substeps);
      std::cout << "[ measured ] " << name << " " << substeps << " substeps: float " << f.v << " m/s, "
                << f.x << " m; double " << d.v << " m/s, " << d.x << " m\n";
      // Double: the round-off bound of Pbd.FreeFallIsDiscreteExact, eps k^2 (1 + |x|).
      EXPECT_LE(d.x, k * k * 2.2e-16 * 13.0);
      EXPECT_LE(d.v, k * k * 2.2e-16 * 13.0 / h);
      // Float: at least an ulp of |x| (a velocity error of u / h over the run), at most u/2 a
      // substep, and growing with the substeps.
      EXPECT_GE(f.x, u);
      EXPECT_GE(f.v, u / h);
      EXPECT_LE(f.v, k * (0.5 * u / h + 2.0 * 0x1.0p-22));
      EXPECT_GT(f.x, 1e3 * d.x);
      EXPECT_GE(f.x, previous_x);
      EXPECT_GE(f.v, previous_v);
      previous_x = f.x;
      previous_v = f.v;
      if (9.81 * h * h < 0.5 * u) {
        // Gravity lost: v_y is the same after every step, a multiple of u / h rounded to float.
        for (double vy : f.vy) ASSERT_EQ(vy, f.vy.front());
        const double multiple = std::round(f.vy.front() * h / u);
        EXPECT_EQ(f.vy.front(), round_to_float(multiple * u / h));
        EXPECT_GT(f.v, 0.95 * 9.81 * 0.5);  // all of gravity's g t, and the quantisation
      }
    }
  }
}

}  // namespace
}  // namespace pbdbench::test
