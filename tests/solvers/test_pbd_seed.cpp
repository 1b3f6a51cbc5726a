// Tests of solvers/pbd_seed.cpp: the seed article's listing to the letter, and each of its
// departures from Mueller et al. 2007 switched alone (docs/seed-departures.md).
#include <gtest/gtest.h>

#include <cmath>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_functions.hpp"
#include "solver_test_util.hpp"
#include "solvers/pbd_seed.hpp"

namespace pbdbench::test {
namespace {

SolverOptions seed(std::vector<std::string> fixes = {}, int iterations = 10, int substeps = 1) {
  SolverOptions o = options_for("pbd-seed", iterations, substeps);
  o.seed_fixes = std::move(fixes);
  return o;
}

const std::vector<std::string> kAllFixes = {"D1", "D2", "D3", "D4",  "D5", "D6",
                                            "D7", "D8", "D9", "D10", "D11"};

std::vector<std::string> all_fixes_but(const std::string& id) {
  std::vector<std::string> out;
  for (const std::string& f : kAllFixes)
    if (f != id) out.push_back(f);
  return out;
}

double distance(const State& s, int a, int b) { return (s.x.row(a) - s.x.row(b)).norm(); }

double tet_volume(const State& s) {
  return tet_signed_volume(s.x.row(0), s.x.row(1), s.x.row(2), s.x.row(3));
}

// ---------------------------------------------------------------------------------------------
// D1, D2: the main loop.

TEST(PbdSeed, D1GravityNeverActs) {
  // Step 2 advances with the old velocity, then adds g dt to a velocity that step 5 overwrites
  // with (pos - old_pos)/dt: a particle at rest stays at rest, to the bit (with alpha = 1: see
  // FloatBlendDrift for what alpha = 0.98 adds in float).
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3(0.1, 2.0, 0.3), 1.0);
  SolverOptions o = seed();
  o.seed_damping = 1.0;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  const Points x0 = s.x.cast<float>().cast<double>();  // the listing's float copy
  for (int i = 0; i < 50; ++i) sv->step(m, s, 1.0 / 60.0);
  EXPECT_EQ(max_abs_diff(s.x, x0), 0.0);
  EXPECT_EQ(s.v.norm(), 0.0);
}

TEST(PbdSeed, FloatBlendDrift) {
  // Step 4 in float: 0.98f + 0.02f = 1 + 1.9e-8, and each product is rounded, so
  // 0.98f * pos + 0.02f * old_pos != pos for a particle at rest. The error becomes a velocity in
  // step 5, which step 2 carries on: a resting particle creeps, by an amount that depends on
  // where it is (the blend is not translation invariant in float). Measured: after 1 min at
  // 60 Hz a particle at (0.1, 2, 0.3) m has moved by about 1 mm and creeps at ~1.6e-5 m/s;
  // in double (D10 fixed) it does not move. The test asks for more than a micrometre.
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3(0.1, 2.0, 0.3), 1.0);
  for (bool dbl : {false, true}) {
    auto sv =
        make_solver(seed(dbl ? std::vector<std::string>{"D10"} : std::vector<std::string>{}), m);
    State s = rest_state(m);
    const Points x0 = dbl ? s.x : Points(s.x.cast<float>().cast<double>());
    for (int i = 0; i < 3600; ++i) sv->step(m, s, 1.0 / 60.0);
    const double moved = max_abs_diff(s.x, x0);
    std::printf("listing at rest, %s: moved %.3e m in 60 s, speed %.3e m/s\n",
                dbl ? "double" : "float", moved, s.v.norm());
    if (dbl) {
      EXPECT_LT(moved, 1e-12);
    } else {
      EXPECT_GT(moved, 1e-6);
    }
  }
}

TEST(PbdSeed, D1AndD2FixedFallFreely) {
  // Fixed: symplectic Euler, x_n = x0 + v0 t + 1/2 G t^2 + 1/2 G h t (references.md, form 1).
  // The listing rebuilds v = (pos - old)/dt every substep, which loses up to ulp(|x|)/h of
  // speed; over k substeps that moves x by up to ~ k^2 ulp(|x|)/2. We allow k^2 eps (1 + |x|),
  // eps = 2^-23 in float (7e-3 m after 1 s of 120 substeps at 10 m: float is that coarse),
  // 2^-52 in double (D10 fixed).
  const Vec3 G(0.0, -9.81, 0.0);
  for (bool dbl : {false, true}) {
    Model m = empty_model(G);
    add_particle(m, Vec3(0.0, 10.0, 0.0), 1.0);
    std::vector<std::string> fixes = {"D1", "D2"};
    if (dbl) fixes.push_back("D10");
    auto sv = make_solver(seed(fixes, 5, 2), m);
    State s = rest_state(m);
    const double dt = 1.0 / 60.0, h = dt / 2;
    for (int n = 1; n <= 60; ++n) {
      sv->step(m, s, dt);
      const double t = n * dt;
      const Vec3 x = Vec3(0.0, 10.0, 0.0) + 0.5 * G * t * t + 0.5 * G * h * t;
      const double k = 2.0 * n;
      const double tol = k * k * (dbl ? 0x1.0p-52 : 0x1.0p-23) * (1.0 + x.norm());
      ASSERT_LE((Vec3(s.x.row(0)) - x).norm(), tol) << "n " << n << " double " << dbl;
    }
  }
}

TEST(PbdSeed, D1FixedAloneReachesATerminalVelocity) {
  // With gravity acting but the position damping of step 4 kept, v_{n+1} = alpha (v_n + g dt):
  // the fall speed saturates at alpha g dt / (1 - alpha) (0.98: 49 g dt = 8.0 m/s at dt = 1/60).
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3(0.0, 0.0, 0.0), 1.0);
  auto sv = make_solver(seed({"D1", "D10"}), m);
  State s = rest_state(m);
  const double dt = 1.0 / 60.0;
  for (int i = 0; i < 2000; ++i) sv->step(m, s, dt);
  EXPECT_NEAR(s.v(0, 1), -0.98 * 9.81 * dt / 0.02, 1e-9);
}

TEST(PbdSeed, D2DampsRigidMotion) {
  // A free particle gliding without gravity: the listing's position damping takes 2 % of its
  // velocity every step (v_n = 0.98^n v0), although nothing deforms. Mueller's damping (D2
  // fixed, k_damping = 1 - 0.98) leaves rigid motion alone.
  for (bool fixed : {false, true}) {
    Model m = empty_model();
    add_particle(m, Vec3::Zero(), 1.0);
    auto sv = make_solver(
        seed(fixed ? std::vector<std::string>{"D2", "D10"} : std::vector<std::string>{"D10"}), m);
    State s = rest_state(m);
    s.v(0, 0) = 1.0;
    for (int i = 0; i < 10; ++i) sv->step(m, s, 0.01);
    EXPECT_NEAR(s.v(0, 0), fixed ? 1.0 : std::pow(0.98, 10), kRoundoff) << "fixed " << fixed;
  }
}

TEST(PbdSeed, DampingRescaleAndGravityRescale) {
  // 4.4: alpha_eff = alpha^(dt/reference_dt); g_eff = g reference_dt / dt.
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3::Zero(), 1.0);
  SolverOptions o = seed({"D10"});
  o.seed_damping_rescale = true;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  s.v(0, 0) = 1.0;
  sv->step(m, s, 0.005);
  EXPECT_NEAR(s.v(0, 0), std::pow(0.98, 0.005 / 0.02), kRoundoff);
  // Gravity rescale with D1 fixed (else gravity never acts) and no damping: one step adds
  // g (reference_dt / dt) dt = g reference_dt to the velocity, whatever dt.
  SolverOptions og = seed({"D1", "D10"});
  og.seed_gravity_rescale = true;
  og.seed_damping = 1.0;
  auto sg = make_solver(og, m);
  State t = rest_state(m);
  sg->step(m, t, 0.005);
  EXPECT_NEAR(t.v(0, 1), -9.81 * 0.02, kRoundoff);
}

// ---------------------------------------------------------------------------------------------
// D3, D4: the distance listing.

TEST(PbdSeed, D3StretchedDistanceGrows) {
  // Two particles 1.2 apart on a link of rest length 1: the listing moves each by
  // (w/W) 0.5 (d - d0) AWAY from the other: 1.2 -> 1.3 after one projection. Fixed: 1.0.
  Model m = empty_model();
  add_particle(m, Vec3(0, 0, 0), 1.0);
  add_particle(m, Vec3(1.2, 0, 0), 1.0);
  add_distance(m, 0, 1, 1.0);
  for (bool fixed : {false, true}) {
    SolverOptions o = seed(fixed ? std::vector<std::string>{"D3"} : std::vector<std::string>{}, 1);
    o.seed_damping = 1.0;  // no step-4 blend, to read the projection alone
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    sv->step(m, s, 0.01);
    EXPECT_NEAR(distance(s, 0, 1), fixed ? 1.0 : 1.3, 1e-6) << "fixed " << fixed;
    // With more iterations the listing keeps pushing: the link grows further.
    if (!fixed) {
      auto sv10 = make_solver(seed({}, 10), m);
      State s10 = rest_state(m);
      sv10->step(m, s10, 0.01);
      EXPECT_GT(distance(s10, 0, 1), 1.3);
    }
  }
}

TEST(PbdSeed, D4StiffnessScalesDistanceOnly) {
  // A tet (volume) with k = 0.5: the listing ignores k outside the distance loop, so its
  // result equals the k = 1 run; with D4 fixed k scales the volume correction too.
  auto run = [](double k, bool d4) {
    Model m = empty_model();
    add_particle(m, Vec3(0, 0, 0), 1.0);
    add_particle(m, Vec3(1, 0, 0), 1.0);
    add_particle(m, Vec3(0, 1, 0), 1.0);
    add_particle(m, Vec3(0, 0, 1), 1.0);
    add_volume(m, 0, 1, 2, 3, 1.5 / 6.0, k);
    std::vector<std::string> fixes = {"D5", "D6", "D7", "D10"};
    if (d4) fixes.push_back("D4");
    SolverOptions o = seed(fixes, 1);
    o.seed_damping = 1.0;
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    sv->step(m, s, 0.01);
    return s;
  };
  EXPECT_EQ(max_abs_diff(run(0.5, false).x, run(1.0, false).x), 0.0);
  EXPECT_GT(max_abs_diff(run(0.5, true).x, run(1.0, true).x), 1e-3);
}

// ---------------------------------------------------------------------------------------------
// D5, D6, D7: the volume listing.

Model tet_model(double scale, double rest_factor) {
  Model m = empty_model();
  add_particle(m, scale * Vec3(0, 0, 0), 1.0);
  add_particle(m, scale * Vec3(1, 0, 0), 1.0);
  add_particle(m, scale * Vec3(0, 1, 0), 1.0);
  add_particle(m, scale * Vec3(0, 0, 1), 1.0);
  add_volume(m, 0, 1, 2, 3, rest_factor * scale * scale * scale / 6.0);
  return m;
}

TEST(PbdSeed, D6TetWithEqualMassesMovesRigidly) {
  // Equal inverse masses: every vertex moves by the same vector delta * w (a translation), so
  // the volume cannot change. With D5 fixed as well the shared vector is sum_i grad_i = 0: the
  // tet does not move at all.
  const Model m = tet_model(1.0, 1.5);
  SolverOptions o = seed({}, 5);
  o.seed_damping = 1.0;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  const double v0 = tet_volume(s);
  sv->step(m, s, 0.01);
  EXPECT_NEAR(tet_volume(s), v0, 1e-6);
  const Vec3 shift = s.x.row(0) - m.rest_positions.row(0);
  EXPECT_GT(shift.norm(), 1e-3);  // it moved ...
  for (int i = 1; i < 4; ++i)     // ... as a rigid translation
    EXPECT_LT((Vec3(s.x.row(i) - m.rest_positions.row(i)) - shift).norm(), 1e-6);

  SolverOptions o5 = seed({"D5"}, 5);
  o5.seed_damping = 1.0;
  State s5 = rest_state(m);
  make_solver(o5, m)->step(m, s5, 0.01);
  EXPECT_LT(max_abs_diff(s5.x, m.rest_positions), 1e-7);
}

TEST(PbdSeed, D5D6D7FixedCorrectTheVolume) {
  // Mueller's projection: the volume converges to its rest value. Without D7 the listing's
  // guard denom < 1e-6 (m^4/kg) skips a tet of 1 cm edges (denom ~ 1e-9): it is never projected.
  for (double scale : {1.0, 0.01}) {
    const Model m = tet_model(scale, 1.5);
    const double rest = m.constraints[0].rest;
    for (bool d7 : {false, true}) {
      std::vector<std::string> fixes = {"D5", "D6", "D10"};
      if (d7) fixes.push_back("D7");
      SolverOptions o = seed(fixes, 50);
      o.seed_damping = 1.0;
      auto sv = make_solver(o, m);
      State s = rest_state(m);
      const StepReport r = sv->step(m, s, 0.01);
      const bool projected = d7 || scale == 1.0;
      if (projected) {
        EXPECT_NEAR(tet_volume(s), rest, 1e-10 * scale * scale * scale) << "scale " << scale;
        EXPECT_EQ(r.skipped, 0);
      } else {
        EXPECT_EQ(max_abs_diff(s.x, m.rest_positions), 0.0) << "scale " << scale;
        EXPECT_EQ(r.skipped, 50);
      }
    }
  }
}

TEST(PbdSeed, D7DistanceGuard) {
  // Two particles 0.5 micrometre apart on a link of 1 mm: skipped by the listing's d < 1e-6.
  Model m = empty_model();
  add_particle(m, Vec3(0, 0, 0), 1.0);
  add_particle(m, Vec3(5e-7, 0, 0), 1.0);
  add_distance(m, 0, 1, 1e-3);
  for (bool d7 : {false, true}) {
    std::vector<std::string> fixes = {"D3", "D10"};
    if (d7) fixes.push_back("D7");
    SolverOptions o = seed(fixes, 1);
    o.seed_damping = 1.0;
    State s = rest_state(m);
    const StepReport r = make_solver(o, m)->step(m, s, 0.01);
    EXPECT_EQ(r.skipped, d7 ? 0 : 1);
    EXPECT_NEAR(distance(s, 0, 1), d7 ? 1e-3 : 5e-7, 1e-15);
  }
}

// ---------------------------------------------------------------------------------------------
// D8, D9, D11: the collision listing.

TEST(PbdSeed, D8RestitutionHasNoEffect) {
  // A particle falls (D1 fixed, so that gravity acts) onto a floor, with the listing's
  // restitution 0 or 1: the velocity write is overwritten by step 5, the runs are identical.
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3(0, 0.3, 0), 1.0, 0.05);
  m.planes.push_back({Vec3::UnitY(), 0.0, 0.8, 0.0});
  State runs[2];
  int active = 0;
  for (int i = 0; i < 2; ++i) {
    SolverOptions o = seed({"D1"}, 4);
    o.seed_damping = 1.0;
    o.seed_restitution = i == 0 ? 0.0 : 1.0;
    auto sv = make_solver(o, m);
    runs[i] = rest_state(m);
    for (int k = 0; k < 60; ++k) active += sv->step(m, runs[i], 1.0 / 60.0).active_contacts;
  }
  EXPECT_GT(active, 0);  // it did hit the floor
  EXPECT_EQ(max_abs_diff(runs[0].x, runs[1].x), 0.0);
  EXPECT_EQ(max_abs_diff(runs[0].v, runs[1].v), 0.0);
  EXPECT_LE(runs[0].v(0, 1), 0.0);  // no bounce
  // D8 fixed: the velocity pass bounces with the plane's e = 0.8.
  SolverOptions o = seed({"D1", "D8"}, 4);
  o.seed_damping = 1.0;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  double max_up = 0.0;
  for (int k = 0; k < 30; ++k) {
    sv->step(m, s, 1.0 / 60.0);
    max_up = std::max(max_up, s.v(0, 1));
  }
  EXPECT_GT(max_up, 1.0);  // it fell 0.25 m (2.2 m/s) and bounced up at ~0.8 of that
}

TEST(PbdSeed, D9NonUnitNormalScalesThePush) {
  // Plane normal (0, 2, 0), offset 0, radius 0.01, particle at y = -0.1: the listing's
  // dist = 2 y = -0.2 and correction = (r - dist) n = 0.21 * 2 = 0.42: y = 0.32, far above the
  // surface. With the unit normal (D9 fixed): y = r = 0.01.
  Model m = empty_model();
  add_particle(m, Vec3(0, -0.1, 0), 1.0, 0.01);
  m.planes.push_back({Vec3(0, 2, 0), 0.0, 0.0, 0.0});
  for (bool fixed : {false, true}) {
    SolverOptions o = seed(fixed ? std::vector<std::string>{"D9"} : std::vector<std::string>{}, 1);
    o.seed_damping = 1.0;
    State s = rest_state(m);
    make_solver(o, m)->step(m, s, 0.01);
    EXPECT_NEAR(s.x(0, 1), fixed ? 0.01 : 0.32, 1e-6) << "fixed " << fixed;
  }
}

TEST(PbdSeed, D11CollisionsTestedInEveryIteration) {
  // A particle 4 cm above the floor on a link (rest 0.5) to a pin 1 m below the floor: the
  // link pulls it through the floor. The listing tests the floor after the link in every
  // iteration and pushes it back out; with D11 fixed the contact is generated once from the
  // predicted positions (not in contact) and the particle ends below the floor.
  Model m = empty_model();
  add_particle(m, Vec3(0, 0.05, 0), 1.0, 0.01);
  add_particle(m, Vec3(0, -1.0, 0), 0.0);
  add_distance(m, 0, 1, 0.5);
  m.planes.push_back({Vec3::UnitY(), 0.0, 0.0, 0.0});
  for (bool fixed : {false, true}) {
    std::vector<std::string> fixes = {"D3", "D10"};
    if (fixed) fixes.push_back("D11");
    SolverOptions o = seed(fixes, 5);
    o.seed_damping = 1.0;
    State s = rest_state(m);
    make_solver(o, m)->step(m, s, 0.01);
    EXPECT_NEAR(s.x(0, 1), fixed ? -0.5 : 0.01, 1e-12) << "fixed " << fixed;
  }
}

TEST(PbdSeed, D10FloatState) {
  // The listing's state is float: after a step every coordinate is a float.
  Model m = chain_model(3, 0.1, 1.0, Vec3(0, -9.81, 0));
  for (bool fixed : {false, true}) {
    auto sv = make_solver(seed(fixed ? std::vector<std::string>{"D1", "D3", "D10"}
                                     : std::vector<std::string>{"D1", "D3"}),
                          m);
    State s = rest_state(m);
    s.x(3, 0) = 0.123456789012345;
    sv->step(m, s, 1.0 / 60.0);
    bool all_float = true;
    for (int i = 0; i < s.x.size(); ++i)
      all_float &= static_cast<double>(static_cast<float>(s.x.data()[i])) == s.x.data()[i];
    EXPECT_EQ(all_float, !fixed);
  }
}

// ---------------------------------------------------------------------------------------------
// Momentum.

TEST(PbdSeed, MomentumD3ConservesD5D6DoNot) {
  // Linear momentum of a step with internal constraints (no gravity, no pins, no contacts), in
  // double (D10 fixed) so that conservation is to round-off, no step-4 blend (damping 1).
  // - The listing's distance projection (D3) moves p1 by (w1/W) c and p2 by -(w2/W) c:
  //   m1 dp1 + m2 dp2 = 0, linear momentum is conserved although the link is pushed the wrong
  //   way; N1 (Mueller's bending) conserves it too.
  // - The volume listing's shared vector (D6) with grad_a = -grad_b (D5) moves the tet's
  //   centre of mass: momentum is created. With D5 and D6 fixed it is conserved again.
  // - The step-4 position damping (D2) scales the momentum of a step by alpha.
  Random rng(3);
  for (ProjectionOrder order : all_orders()) {
    for (int trial = 0; trial < 5; ++trial) {
      const Model dist_bend = random_internal_model(rng, {true, false, true, 10});
      const Model vol = random_internal_model(rng, {false, true, false, 10});
      auto run = [&](const Model& m, std::vector<std::string> fixes, double damping) {
        fixes.push_back("D10");
        SolverOptions o = seed(fixes, 3);
        o.order = order;
        o.seed_damping = damping;
        o.jacobi_averaging = false;  // averaging breaks momentum (test_pbd)
        o.jacobi_relaxation = 0.5;
        Random vr(100 + trial);
        State s = random_velocities(m, vr);
        const Vec3 p0 = linear_momentum(m, s);
        make_solver(o, m)->step(m, s, 0.01);
        return std::make_pair(p0, linear_momentum(m, s));
      };
      Random vr(100 + trial);
      const double scale = momentum_scale(dist_bend, random_velocities(dist_bend, vr)) + 100.0;
      auto [p0, p1] = run(dist_bend, {}, 1.0);
      EXPECT_LT((p1 - p0).norm(), kRoundoff * scale) << to_string(order) << " D3";
      auto [q0, q1] = run(vol, {}, 1.0);
      EXPECT_GT((q1 - q0).norm(), 1e-3) << to_string(order) << " D5/D6";
      auto [r0, r1] = run(vol, {"D5", "D6"}, 1.0);
      EXPECT_LT((r1 - r0).norm(), kRoundoff * scale) << to_string(order) << " D5+D6 fixed";
      auto [d0, d1] = run(dist_bend, {}, 0.98);
      EXPECT_LT((d1 - 0.98 * d0).norm(), kRoundoff * scale) << to_string(order) << " D2";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Everything fixed: pbd.

void expect_all_fixed_is_pbd(bool dbl, double velocity_damping) {
  // A small scene with every kind: a chain of distance constraints, a tet, a bending pair of
  // triangles, a floor with friction and restitution, gravity. The model lists its constraints
  // kind by kind, so the listing's kind-by-kind loops visit them in pbd's sequential order.
  Model m = chain_model(4, 0.15, 1.0, Vec3(0, -9.81, 0), 0.8);
  const int t0 = add_particle(m, Vec3(0.5, 0.2, 0.0), 1.0);
  add_particle(m, Vec3(0.8, 0.2, 0.0), 1.5);
  add_particle(m, Vec3(0.5, 0.5, 0.0), 0.7);
  add_particle(m, Vec3(0.5, 0.2, 0.3), 1.2);
  add_rest_distance(m, t0, t0 + 1);
  add_rest_distance(m, t0, t0 + 2);
  add_rest_distance(m, t0, t0 + 3);
  add_volume(m, t0, t0 + 1, t0 + 2, t0 + 3, 0.3 * 0.3 * 0.3 / 6.0 * 0.9, 0.9);
  add_bending(m, t0, t0 + 1, t0 + 2, t0 + 3, 1.4, 0.5);
  m.planes.push_back({Vec3::UnitY(), 0.3, 0.4, 0.3});
  SolverOptions o = seed(all_fixes_but(dbl ? "" : "D10"), 6, 2);
  o.seed_damping = 1.0 - velocity_damping;
  SolverOptions p = options_for("pbd", 6, 2);
  p.pbd_velocity_damping = velocity_damping;
  auto ss = make_solver(o, m);
  auto sp = make_solver(p, m);
  State a = rest_state(m), b = rest_state(m);
  a.v.row(1) = b.v.row(1) = Vec3(1.0, 0.0, 0.5).transpose();
  double worst = 0.0;
  int active = 0;
  for (int k = 0; k < 60; ++k) {
    ss->step(m, a, 1.0 / 60.0);
    active += sp->step(m, b, 1.0 / 60.0).active_contacts;
    worst = std::max(worst, max_abs_diff(a.x, b.x));
  }
  EXPECT_GT(active, 0);  // the tet reached the floor
  // Double: round-off accumulated over 60 steps of a chaotic-ish system, 1e-10. Float: the
  // states differ by float rounding from the first step on and the difference grows with the
  // dynamics; 1e-4 m over 1 s of motion of ~1 m (a few hundred float ulps) is float precision.
  EXPECT_LT(worst, dbl ? 1e-10 : 1e-4) << "double " << dbl;
}

TEST(PbdSeed, AllFixedIsPbd) {
  expect_all_fixed_is_pbd(true, 0.0);
  expect_all_fixed_is_pbd(false, 0.0);
  expect_all_fixed_is_pbd(true, 0.02);  // D2 fixed with alpha 0.98: Mueller's k_damping 0.02
}

// ---------------------------------------------------------------------------------------------
// The article's tuning options from sections 4 and 5 (solvers/pbd_seed.hpp).

// A scene that exercises every part of the listing: a 4 x 4 patch pinned at two corners, with
// stretch, shear and bending, a tet with volume, a plane, a sphere and particle contacts.
Model tuning_scene() {
  Model m = empty_model(Vec3(0, -9.81, 0));
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      add_particle(m, Vec3(0.1 * i, 0.3 + 0.01 * i * j, 0.1 * j),
                   (j == 0 && (i == 0 || i == 3)) ? 0.0 : 0.05 + 0.01 * i, 0.02);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      const int k = 4 * j + i;
      if (i + 1 < 4) add_rest_distance(m, k, k + 1, 0.9);
      if (j + 1 < 4) add_rest_distance(m, k, k + 4, 0.9);
      if (i + 1 < 4 && j + 1 < 4) add_rest_distance(m, k, k + 5, 0.5);
    }
  add_bending(m, 5, 6, 1, 10, 0.1, 0.3);
  const int t = add_particle(m, Vec3(0.5, 0.1, 0.5), 0.2);
  add_particle(m, Vec3(0.6, 0.1, 0.5), 0.2);
  add_particle(m, Vec3(0.5, 0.2, 0.5), 0.2);
  add_particle(m, Vec3(0.5, 0.1, 0.6), 0.2);
  add_volume(m, t, t + 1, t + 2, t + 3, 0.9 * 0.1 * 0.1 * 0.1 / 6.0);
  m.planes.push_back({Vec3::UnitY(), 0.0, 0.3, 0.2});
  m.spheres.push_back({Vec3(0.15, 0.2, 0.15), 0.1, SphereSide::Outside, 0.2, 0.3, -1});
  m.particle_contact = true;
  return m;
}

// FNV-1a over the bits of x and v, continuing from h.
std::uint64_t state_hash(const State& s, std::uint64_t h = 1469598103934665603ull) {
  auto eat = [&](const double* p, Eigen::Index n) {
    const auto* b = reinterpret_cast<const unsigned char*>(p);
    for (size_t i = 0; i < sizeof(double) * static_cast<size_t>(n); ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  };
  eat(s.x.data(), s.x.size());
  eat(s.v.data(), s.v.size());
  return h;
}

// 40 steps of pbd-seed (5 iterations, 2 substeps, contact margin 0.01 m) from a moving start;
// the hash of the states after every step (the listing goes non-finite on the way).
std::uint64_t tuning_run(const SolverOptions& o) {
  const Model m = tuning_scene();
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  for (int i = 0; i < m.particle_count(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0) s.v.row(i) = Vec3(0.3, -0.5 - 0.1 * i, 0.2).transpose();
  std::uint64_t h = 1469598103934665603ull;
  for (int k = 0; k < 40; ++k) {
    sv->step(m, s, 1.0 / 60.0);
    h = state_hash(s, h);
  }
  return h;
}

TEST(PbdSeed, TuningDefaultsAreTheListingBitForBit) {
  // The hashes were recorded with the solver as it was before the tuning options and the
  // grouped_shuffled / bottom_up orders existed (the same scene and options, this build's
  // flags); with their defaults the listing must not change a bit. The listing as published
  // (no fixes), with D1, D3 and D8 fixed, and with all but D4 and D10 fixed (still float), in
  // the five orders of that time.
  const std::vector<ProjectionOrder> orders = {ProjectionOrder::Sequential, ProjectionOrder::Reversed,
                                               ProjectionOrder::Shuffled, ProjectionOrder::Colored,
                                               ProjectionOrder::Jacobi};
  const std::vector<std::vector<std::string>> fixes = {
      {}, {"D1", "D3", "D8"}, {"D1", "D2", "D3", "D5", "D6", "D7", "D8", "D9", "D11"}};
  const std::uint64_t expected[3][5] = {
      {0x1930ac02b3e07cefull, 0x4ce80258b8a73900ull, 0xb4d54549ee8f07d3ull, 0xd4fd03fe573a5180ull,
       0xf6c476ce36144c2eull},
      {0x1704d08c17ab905aull, 0x56854a85889dbd0aull, 0x81ba8e5a6d97bbcfull, 0xcfaac08af02d5021ull,
       0x9fe12ef2541d4fa5ull},
      {0x061dd57148b93394ull, 0x1d5ecc1b575274fdull, 0x1749cdf09dba7fb4ull, 0x26070f2b4ef90edcull,
       0x05bcf375af7c752dull}};
  for (size_t f = 0; f < fixes.size(); ++f)
    for (size_t k = 0; k < orders.size(); ++k) {
      SolverOptions o = seed(fixes[f], 5, 2);
      o.order = orders[k];
      o.contact_margin = 0.01;
      EXPECT_EQ(tuning_run(o), expected[f][k]) << "fixes " << f << " " << to_string(orders[k]);
    }
}

TEST(PbdSeed, IterationSchedules) {
  SolverOptions o = seed({}, 7);
  EXPECT_EQ(seed_iterations(o, 0, 0.0), 7);
  EXPECT_EQ(seed_iterations(o, 5, 100.0), 7);
  o.seed_iteration_schedule = "dynamic";
  o.seed_fast_speed = 2.0;
  EXPECT_EQ(seed_iterations(o, 0, 0.0), 10);   // the first step: 10, fast or not
  EXPECT_EQ(seed_iterations(o, 0, 50.0), 10);
  EXPECT_EQ(seed_iterations(o, 1, 2.0), 3);    // not faster than fast_speed: 3
  EXPECT_EQ(seed_iterations(o, 1, 2.001), 5);  // faster: 5
  o.seed_iteration_schedule = "mixed";
  EXPECT_EQ(seed_iterations(o, 0, 2.0), 3);
  EXPECT_EQ(seed_iterations(o, 9, 2.001), 1);
}

TEST(PbdSeed, IterationScheduleIsWhatTheStepReports) {
  // A free particle (no constraints, no gravity acting: D1) at 0.5 m/s, then 1.5 m/s; fast_speed
  // 1 m/s; 2 substeps: the report counts sweeps summed over substeps.
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3::Zero(), 1.0);
  for (const std::string schedule : {"fixed", "dynamic", "mixed"}) {
    SolverOptions o = seed({}, 7, 2);
    o.seed_iteration_schedule = schedule;
    o.seed_damping = 1.0;
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    s.v(0, 0) = 0.5;
    const int first = sv->step(m, s, 0.01).iterations;
    const int slow = sv->step(m, s, 0.01).iterations;
    s.v(0, 0) = 1.5;
    const int fast = sv->step(m, s, 0.01).iterations;
    SCOPED_TRACE(schedule);
    if (schedule == "fixed") {
      EXPECT_EQ(first, 14);
      EXPECT_EQ(slow, 14);
      EXPECT_EQ(fast, 14);
    } else if (schedule == "dynamic") {
      EXPECT_EQ(first, 20);
      EXPECT_EQ(slow, 6);
      EXPECT_EQ(fast, 10);
    } else {
      EXPECT_EQ(first, 6);
      EXPECT_EQ(slow, 6);
      EXPECT_EQ(fast, 2);
    }
  }
}

TEST(PbdSeed, BackupAfterDampingZeroesEveryVelocity) {
  // 3.1a's warned-against placement: old_pos backed up after step 4, so step 5 computes
  // (pos - pos) / dt = 0. With gravity acting (D1 fixed), in double, without the blend
  // (alpha = 1): each step starts at rest and moves by g dt^2, a fall at the constant speed
  // g dt instead of x0 + g dt^2 n (n + 1) / 2.
  const double dt = 0.01;
  const Vec3 g(0, -9.81, 0);
  Model m = empty_model(g);
  add_particle(m, Vec3(0, 1, 0), 1.0);
  for (const std::string backup : {"before_forces", "after_damping"}) {
    SolverOptions o = seed({"D1", "D10"});
    o.seed_backup = backup;
    o.seed_damping = 1.0;
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    const int n = 20;
    for (int k = 0; k < n; ++k) sv->step(m, s, dt);
    SCOPED_TRACE(backup);
    if (backup == "after_damping") {
      EXPECT_EQ(s.v.norm(), 0.0);
      EXPECT_NEAR(s.x(0, 1), 1.0 + n * g.y() * dt * dt, 1e-12);
    } else {
      EXPECT_NEAR(s.v(0, 1), n * g.y() * dt, 1e-12);
      EXPECT_NEAR(s.x(0, 1), 1.0 + g.y() * dt * dt * n * (n + 1) / 2.0, 1e-12);
    }
  }
  // With the blend (alpha = 0.98): step 4 blends with this step's start, as the listing does,
  // so the move per step is 0.98 g dt^2.
  SolverOptions o = seed({"D1", "D10"});
  o.seed_backup = "after_damping";
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  for (int k = 0; k < 3; ++k) sv->step(m, s, dt);
  EXPECT_NEAR(s.x(0, 1), 1.0 + 3 * 0.98 * g.y() * dt * dt, 1e-12);
  EXPECT_EQ(s.v.norm(), 0.0);
}

TEST(PbdSeed, DynamicInverseMass) {
  // 4.2: 0.1 for a particle faster than fast_speed, else 0.3; pinned stay 0.
  Model m = chain_model(3, 0.1, 2.0, Vec3(0, -9.81, 0));
  Points v = Points::Zero(4, 3);
  v(1, 0) = 0.5;
  v(2, 1) = -1.5;
  v(3, 2) = 1.0;  // not faster than 1.0
  v(0, 0) = 5.0;  // pinned: stays 0 whatever its speed
  EXPECT_EQ(seed_dynamic_inverse_masses(m, v, 1.0), (std::vector<double>{0.0, 0.3, 0.1, 0.3}));
  // In a step: two particles on a link of rest length 1 stretched to 1.2 (D3 fixed, k = 1, one
  // iteration, D1 as listed so nothing else moves them, alpha = 1, double). The fast one
  // (w = 0.1) moves a quarter of the error, the slow one (w = 0.3) three quarters; without the
  // option (both w = 1/2 kg) each moves half.
  Model pair = empty_model();
  add_particle(pair, Vec3(0, 0, 0), 2.0);
  add_particle(pair, Vec3(1.2, 0, 0), 2.0);
  add_distance(pair, 0, 1, 1.0);
  for (bool dynamic : {false, true}) {
    SolverOptions o = seed({"D3", "D10"}, 1);
    o.seed_damping = 1.0;
    o.seed_dynamic_inverse_mass = dynamic;
    State s = rest_state(pair);
    s.v(0, 1) = 3.0;  // fast, along y (its step-2 move, with D1 listed, is v dt)
    make_solver(o, pair)->step(pair, s, 1e-4);
    const double moved0 = s.x(0, 0), moved1 = 1.2 - s.x(1, 0);
    EXPECT_NEAR(moved0 + moved1, 0.2, 1e-6) << dynamic;  // the link is restored (to O(dt^2))
    EXPECT_NEAR(moved0 / (moved0 + moved1), dynamic ? 0.25 : 0.5, 1e-4) << dynamic;
  }
}

TEST(PbdSeed, GradedInverseMass) {
  // A chain of 5 links pinned at the top: hop distances 0..5, d_c = 5/2, so
  // w = 0.3 min(1, d / 2.5) = 0, 0.12, 0.24, 0.3, 0.3, 0.3.
  const Model chain = chain_model(5, 0.1, 1.0, Vec3(0, -9.81, 0));
  const std::vector<double> w = seed_graded_inverse_masses(chain);
  const std::vector<double> expected = {0.0, 0.12, 0.24, 0.3, 0.3, 0.3};
  ASSERT_EQ(w.size(), expected.size());
  for (size_t i = 0; i < w.size(); ++i) EXPECT_NEAR(w[i], expected[i], kRoundoff) << i;
  // Pinned at both ends (a 4-link chain): distances 0 1 2 1 0, d_c = 1: 0, 0.3, 0.3, 0.3, 0.
  Model both = chain_model(4, 0.1, 1.0, Vec3(0, -9.81, 0));
  both.inv_mass[4] = 0.0;
  EXPECT_EQ(seed_graded_inverse_masses(both), (std::vector<double>{0.0, 0.3, 0.3, 0.3, 0.0}));
  // A tet's four particles are all neighbours: one hop from the pin; a particle that no pin
  // reaches keeps 0.3.
  Model tet = empty_model();
  add_particle(tet, Vec3(0, 0, 0), 0.0);
  add_particle(tet, Vec3(1, 0, 0), 1.0);
  add_particle(tet, Vec3(0, 1, 0), 1.0);
  add_particle(tet, Vec3(0, 0, 1), 1.0);
  add_particle(tet, Vec3(5, 5, 5), 1.0);
  add_volume(tet, 0, 1, 2, 3, 1.0 / 6.0);
  EXPECT_EQ(seed_graded_inverse_masses(tet), (std::vector<double>{0.0, 0.3, 0.3, 0.3, 0.3}));
  // No pin: refused, by the function and by make_solver.
  Model free = empty_model();
  add_particle(free, Vec3::Zero(), 1.0);
  EXPECT_THROW(seed_graded_inverse_masses(free), std::invalid_argument);
  SolverOptions o = seed();
  o.seed_graded_inverse_mass = true;
  EXPECT_THROW(make_solver(o, free), std::invalid_argument);
  // In a step (double, D3 fixed, alpha = 1, one sequential iteration, no gravity): a 4-link
  // chain, w = 0, 0.15, 0.3, 0.3, 0.3 (d_c = 2), its second link stretched by 0.06. Link 0 is
  // at rest; link 1 moves particle 1 by w1 / (w1 + w2) = 1/3 of the error, 0.02 (1/2 with the
  // model's equal masses), and no later link touches particle 1.
  const Model four = chain_model(4, 0.1, 1.0, Vec3::Zero());
  for (bool graded : {false, true}) {
    SolverOptions g = seed({"D3", "D10"}, 1);
    g.seed_damping = 1.0;
    g.seed_graded_inverse_mass = graded;
    State s = rest_state(four);
    for (int i = 2; i <= 4; ++i) s.x(i, 1) -= 0.06;
    make_solver(g, four)->step(four, s, 0.01);
    EXPECT_NEAR(s.x(1, 1), -0.1 - (graded ? 0.02 : 0.03), 1e-12) << graded;
  }
}

TEST(PbdSeed, TuningOptionsAreValidated) {
  SolverOptions o = seed();
  o.seed_iteration_schedule = "sometimes";
  EXPECT_NE(o.validate().find("solver.seed.iteration_schedule"), std::string::npos);
  o = seed();
  o.seed_fast_speed = 0.0;
  EXPECT_NE(o.validate().find("solver.seed.fast_speed"), std::string::npos);
  o = seed();
  o.seed_backup = "never";
  EXPECT_NE(o.validate().find("solver.seed.backup"), std::string::npos);
  o = seed();
  o.seed_dynamic_inverse_mass = o.seed_graded_inverse_mass = true;
  EXPECT_NE(o.validate().find("graded_inverse_mass"), std::string::npos);
}

TEST(PbdSeed, TheListingTearsARestingChainApart) {
  // A chain of 10 links pinned at one end, laid out at rest length along x, no velocity. The
  // rest lengths are doubles; the listing's positions are floats, so every link starts off by
  // ~1e-9 m. D3 pushes a stretched link further apart (and a compressed one further together)
  // by half its error per projection: the errors grow ~1.5x per iteration, 10 iterations a
  // step, and the chain tears within a fraction of a second although nothing moves in the
  // exact problem. With D3 fixed it stays at rest.
  const Model m =
      chain_model(10, 0.1, 0.1, Vec3(0, -9.81, 0), 1.0, 0.0, Vec3::Zero(), Vec3(1, 0, 0));
  for (bool fixed : {false, true}) {
    auto sv = make_solver(
        seed(fixed ? std::vector<std::string>{"D3"} : std::vector<std::string>{}, 10), m);
    State s = rest_state(m);
    int torn_at = -1;
    for (int i = 1; i <= 60 && torn_at < 0; ++i) {
      sv->step(m, s, 1.0 / 60.0);
      double worst = 0.0;
      for (const Constraint& c : m.constraints) {
        const double C = eval_constraint(c, s.x).C;
        worst = std::isfinite(C) ? std::max(worst, std::abs(C)) : INFINITY;
      }
      if (worst > 0.01) torn_at = i;  // a link off by 1 cm (10 %)
    }
    std::printf("listing chain at rest, D3 %s: %s\n", fixed ? "fixed" : "as listed",
                torn_at < 0 ? "intact after 60 steps"
                            : ("torn at step " + std::to_string(torn_at)).c_str());
    if (fixed) {
      EXPECT_EQ(torn_at, -1);
    } else {
      EXPECT_GT(torn_at, 0);
      EXPECT_LE(torn_at, 30);
    }
  }
}

}  // namespace
}  // namespace pbdbench::test
