// Tests of solvers/pbd_seed.cpp: the seed article's listing to the letter, and each of its
// departures from Mueller et al. 2007 switched alone (docs/seed-departures.md).
#include <gtest/gtest.h>

#include <cmath>

#include "core/constraint_functions.hpp"
#include "solver_test_util.hpp"

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
