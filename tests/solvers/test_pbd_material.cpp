// Tests of solvers/pbd_material.cpp: pbd's stiffness k derived from the scene's compliance by the
// effective-stiffness law of Mueller et al. 2007 (docs/solvers.md, "One material"), checked
// against closed forms: a spring under gravity stretches by m g alpha under pbd as under xpbd,
// and pbd's steps are xpbd's (backward Euler) on one linear constraint.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"
#include "solver_test_util.hpp"
#include "solvers/pbd_material.hpp"

namespace pbdbench::test {
namespace {

SolverOptions derived(const std::string& name, int iterations, int substeps = 1) {
  SolverOptions o = options_for(name, iterations, substeps);
  o.pbd_material = PbdMaterial::Compliance;
  return o;
}

TEST(PbdMaterial, StiffnessFromComplianceIsTheInverseOfTheEffectiveStiffnessLaw) {
  // Rigid or immovable: k = 1.
  EXPECT_EQ(pbd_stiffness_from_compliance(0.0, 2.0, 0.01, 10), 1.0);
  EXPECT_EQ(pbd_stiffness_from_compliance(1e-3, 0.0, 0.01, 10), 1.0);
  for (double alpha : {1e-9, 1e-4, 1e-2, 10.0})
    for (double S : {0.5, 2.0, 1e3})
      for (int n : {1, 4, 50})
        for (double h : {1.0 / 60.0, 1e-3}) {
          const double k = pbd_stiffness_from_compliance(alpha, S, h, n);
          ASSERT_GE(k, 0.0);
          ASSERT_LE(k, 1.0);
          // (1 - k)^n = 1 / (1 + h^2 S / alpha): the error after n projections is the error
          // after one backward Euler step of K = 1 / alpha on the mass 1 / S.
          const double kept = std::pow(1.0 - k, n), be = 1.0 / (1.0 + h * h * S / alpha);
          ASSERT_NEAR(kept, be, 1e-12 * std::max(1.0, be) + 1e-13) << alpha << " " << S << " " << n;
          // And back: the compliance of that k is alpha.
          ASSERT_NEAR(pbd_compliance_of_stiffness(k, S, h, n), alpha, 1e-7 * alpha) << alpha << " " << S << " " << n;
        }
  EXPECT_EQ(pbd_compliance_of_stiffness(1.0, 2.0, 0.01, 3), 0.0);
  EXPECT_TRUE(std::isinf(pbd_compliance_of_stiffness(0.0, 2.0, 0.01, 3)));
}

TEST(PbdMaterial, InverseMassSumsOfTheKinds) {
  Model m = empty_model();
  const int a = add_particle(m, Vec3(0, 0, 0), 2.0);
  const int b = add_particle(m, Vec3(1, 0, 0), 0.5);
  const int c = add_particle(m, Vec3(0, 1, 0), 0.0);  // pinned
  const int d = add_particle(m, Vec3(0, 0, 1), 1.0);
  add_distance(m, a, b, 1.0);
  add_distance(m, a, c, 1.0);
  // Distance: w0 + w1 (|grad C| = 1).
  EXPECT_DOUBLE_EQ(pbd_inverse_mass_sum(m, m.constraints[0]), 0.5 + 2.0);
  EXPECT_DOUBLE_EQ(pbd_inverse_mass_sum(m, m.constraints[1]), 0.5);
  // Volume of the unit right tet: grad_0 = -(1, 1, 1)/6, grad_i = e_i / 6.
  add_volume(m, a, b, c, d, 1.0 / 6.0);
  EXPECT_NEAR(pbd_inverse_mass_sum(m, m.constraints[2]), (0.5 * 3.0 + 2.0 + 0.0 + 1.0) / 36.0, 1e-15);
  // A negative inverse mass (a defect) counts by its magnitude.
  m.inv_mass[static_cast<size_t>(b)] = -2.0;
  EXPECT_DOUBLE_EQ(pbd_inverse_mass_sum(m, m.constraints[0]), 0.5 + 2.0);
}

// sum w_i |grad_i theta|^2 of the dihedral angle by central differences of dihedral_angle.
double bending_sum_by_differences(const Model& m, const Constraint& c) {
  double s = 0.0;
  const double eps = 1e-6;
  for (int i = 0; i < 4; ++i) {
    const int p = c.particles[static_cast<size_t>(i)];
    Vec3 g = Vec3::Zero();
    for (int axis = 0; axis < 3; ++axis) {
      Points plus = m.rest_positions, minus = m.rest_positions;
      plus(p, axis) += eps;
      minus(p, axis) -= eps;
      auto angle = [&](const Points& x) {
        return dihedral_angle(x.row(c.particles[0]), x.row(c.particles[1]), x.row(c.particles[2]),
                              x.row(c.particles[3]));
      };
      g[axis] = (angle(plus) - angle(minus)) / (2.0 * eps);
    }
    s += std::abs(m.inv_mass[static_cast<size_t>(p)]) * g.squaredNorm();
  }
  return s;
}

TEST(PbdMaterial, BendingInverseMassSumIsThatOfTheDihedralAngleGradient) {
  // A folded hinge (smooth there): the closed form against finite differences.
  for (double fold : {0.3, 1.2, 2.5}) {
    Model m = empty_model();
    add_particle(m, Vec3(0, 0, 0), 1.0);
    add_particle(m, Vec3(1.2, 0.1, 0), 0.5);
    add_particle(m, Vec3(0.4, 0.9, 0.1), 2.0);
    add_particle(m, Vec3(0.7, -0.8 * std::cos(fold), 0.8 * std::sin(fold)), 0.25);
    add_bending(m, 0, 1, 2, 3, 0.0);
    const double fd = bending_sum_by_differences(m, m.constraints[0]);
    EXPECT_NEAR(pbd_inverse_mass_sum(m, m.constraints[0]), fd, 1e-6 * fd) << "fold " << fold;
  }
  // Flat (C = acos(n1 . n2) has a kink there; |grad C| is the same from either side): a
  // symmetric hinge of unit heights has |grad| = 1 at each vertex, so S = 4 w.
  Model flat = empty_model();
  add_particle(flat, Vec3(0, 0, 0), 0.5);
  add_particle(flat, Vec3(1, 0, 0), 0.5);
  add_particle(flat, Vec3(0.5, 1, 0), 0.5);
  add_particle(flat, Vec3(0.5, -1, 0), 0.5);
  add_bending(flat, 0, 1, 2, 3, std::acos(-1.0));
  EXPECT_NEAR(pbd_inverse_mass_sum(flat, flat.constraints[0]), 4.0 * 2.0, 1e-12);
  // ... the limit of the folded values.
  Model near = flat;
  near.rest_positions.row(3) = Vec3(0.5, -std::cos(1e-3), std::sin(1e-3)).transpose();
  EXPECT_NEAR(bending_sum_by_differences(near, near.constraints[0]), 8.0, 1e-5);
}

// A particle of mass m hanging from a pinned anchor by one spring of compliance alpha, started at
// rest with the spring stretched by `stretch0`, after `steps` steps: its stretch.
double hang(const SolverOptions& o, double mass, double alpha, double k_explicit, double stretch0,
            int steps) {
  const double L = 1.0, g = 9.81, dt = 1.0 / 60.0;
  Model m = empty_model(Vec3(0, -g, 0));
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(0, -L, 0), mass);
  add_distance(m, 0, 1, L, k_explicit, alpha);
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  s.x(1, 1) = -L - stretch0;
  for (int i = 0; i < steps; ++i) sv->step(m, s, dt);
  return -s.x(1, 1) - L;
}

TEST(PbdMaterial, SpringStretchesByMGAlphaUnderPbdAsUnderXpbd) {
  // Static equilibrium of pbd: C = (1-k)^n (C + h^2 g), i.e. C = h^2 g / ((1-k)^-n - 1), which
  // the rule makes h^2 g m alpha / h^2 = m g alpha exactly; xpbd's is m g alpha too. Started
  // there at rest, the particle stays (to round-off); started at the rest length, pbd's motion
  // is xpbd's (the same step map) and settles there. With k = 1 (the old default, a rigid
  // link) the equilibrium is a stretch of 0: this test fails for it.
  const double g = 9.81;
  for (double mass : {0.1, 1.0, 3.0})
    for (double alpha : {1e-4, 1e-3, 1e-2})
      for (int n : {1, 5, 20})
        for (int substeps : {1, 4}) {
          SCOPED_TRACE("m " + std::to_string(mass) + " alpha " + std::to_string(alpha) + " n " +
                       std::to_string(n) + " substeps " + std::to_string(substeps));
          const double expected = mass * g * alpha;
          // Round-off: positions of order 1 m over 800 substeps, 1e-11 m (1e-7 of the smallest
          // stretch here).
          ASSERT_NEAR(hang(derived("pbd", n, substeps), mass, alpha, 1.0, expected, 200), expected, 1e-11);
          ASSERT_NEAR(hang(derived("xpbd", n, substeps), mass, alpha, 1.0, expected, 200), expected, 1e-11);
          const double p = hang(derived("pbd", n, substeps), mass, alpha, 1.0, 0.0, 3000);
          const double x = hang(derived("xpbd", n, substeps), mass, alpha, 1.0, 0.0, 3000);
          ASSERT_NEAR(p, x, 1e-9 * expected);
          // Settling as backward Euler does: its amplitude, `expected` at the start, shrinks by
          // (1 + omega^2 h^2)^(-1/2) a substep (omega^2 = 1 / (alpha m)).
          const double h = 1.0 / 60.0 / substeps, w2h2 = h * h / (alpha * mass);
          const double left = expected * std::pow(1.0 + w2h2, -0.5 * 3000 * substeps);
          ASSERT_NEAR(p, expected, 1.01 * left + 1e-11);
        }
  // The explicit override k = 1 is rigid: started at m g alpha, the spring snaps to its rest
  // length.
  EXPECT_LT(std::abs(hang(options_for("pbd", 5), 1.0, 1e-3, 1.0, 1.0 * g * 1e-3, 200)), 1e-9);
}

TEST(PbdMaterial, OnOneLinearConstraintPbdStepsAreXpbdSteps) {
  // The particle started stretched and moving along the spring: the constraint stays linear
  // (its gradient is the fixed vertical), and every step of pbd with the derived k is xpbd's
  // step (backward Euler on K = 1 / alpha): the same oscillation, period and damping included.
  for (int n : {1, 3, 10})
    for (double alpha : {1e-3, 0.05}) {
      const double mass = 0.7, L = 1.0, dt = 1.0 / 60.0;
      Model m = empty_model(Vec3(0, -9.81, 0));
      add_particle(m, Vec3::Zero(), 0.0);
      add_particle(m, Vec3(0, -L, 0), mass);
      add_distance(m, 0, 1, L, 1.0, alpha);
      auto pbd = make_solver(derived("pbd", n), m);
      auto xpbd = make_solver(derived("xpbd", n), m);
      State a = rest_state(m), b;
      a.x(1, 1) = -L - 0.2;
      a.v(1, 1) = 0.5;
      b = a;
      double lowest = 0.0, highest = -1e9;
      for (int step = 0; step < 200; ++step) {
        pbd->step(m, a, dt);
        xpbd->step(m, b, dt);
        ASSERT_NEAR(a.x(1, 1), b.x(1, 1), 1e-12) << "n " << n << " alpha " << alpha << " step " << step;
        ASSERT_NEAR(a.v(1, 1), b.v(1, 1), 1e-10) << "n " << n << " alpha " << alpha << " step " << step;
        lowest = std::min(lowest, a.x(1, 1));
        highest = std::max(highest, a.x(1, 1));
      }
      EXPECT_GT(highest - lowest, 0.01);  // it moved
    }
}

TEST(PbdMaterial, WithOneIterationPbdIsXpbdOnCoupledConstraints) {
  // n = 1: k = x / (1 + x), x = h^2 S / alpha, is the factor of xpbd's first projection from
  // lambda = 0, so a chain of coupled links (released sideways: the constraints are nonlinear)
  // runs the same under both, projection for projection.
  Model m = chain_model(8, 0.1, 0.5, Vec3(0, -9.81, 0), 1.0, 1e-4, Vec3::Zero(), Vec3(1, 0, 0));
  // The largest position difference between pbd and xpbd over 60 steps of 1/60 s.
  auto apart = [&](int n, int substeps) {
    auto pbd = make_solver(derived("pbd", n, substeps), m);
    auto xpbd = make_solver(derived("xpbd", n, substeps), m);
    State a = rest_state(m), b = a;
    double worst = 0.0;
    for (int step = 0; step < 60; ++step) {
      pbd->step(m, a, 1.0 / 60.0);
      xpbd->step(m, b, 1.0 / 60.0);
      worst = std::max(worst, max_abs_diff(a.x, b.x));
    }
    return worst;
  };
  EXPECT_LE(apart(1, 10), 1e-12);
  // With 10 iterations they differ (the rule is exact for one constraint only).
  EXPECT_GT(apart(10, 1), 1e-3);
}

TEST(PbdMaterial, TheStiffnessFollowsTheSubstep) {
  // The same compliance at 4 substeps is softer per projection than at 1: k is derived for h.
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(1, 0, 0), 1.0);
  add_distance(m, 0, 1, 1.0, 1.0, 1e-3);
  const std::vector<double> S = pbd_inverse_mass_sums(m);
  const double k1 = pbd_stiffness(m, derived("pbd", 5, 1), S, 0.02)[0];
  const double k4 = pbd_stiffness(m, derived("pbd", 5, 4), S, 0.005)[0];
  EXPECT_LT(k4, k1);
  EXPECT_NEAR(k1, pbd_stiffness_from_compliance(1e-3, 1.0, 0.02, 5), 0.0);
  // The explicit override ignores the compliance (and corrects k when asked).
  SolverOptions o = options_for("pbd", 5);
  m.constraints[0].stiffness = 0.3;
  EXPECT_EQ(pbd_stiffness(m, o, S, 0.02)[0], 0.3);
  o.pbd_stiffness_correction = true;
  EXPECT_NEAR(pbd_stiffness(m, o, S, 0.02)[0], 1.0 - std::pow(0.7, 0.2), 1e-15);
}

// Unit right-angled tets of 1 kg particles at x = 0, 2, 4, ... (one per entry of `count`), of
// stable neo-Hookean FEM elements (E = 1e5 Pa, nu = 0.3).
Model fem_tets(int count) {
  Model m = empty_model();
  for (int k = 0; k < count; ++k) {
    const Vec3 o(2.0 * k, 0, 0);
    const int a = add_particle(m, o, 1.0);
    for (const Vec3& d : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)}) add_particle(m, o + d, 1.0);
    m.tets.push_back({a, a + 1, a + 2, a + 3});
  }
  fem::add_fem_elements(m, m.tets, Material::StableNeoHookean, 1e5, 0.3);
  return m;
}

TEST(PbdMaterial, FemIsRefusedNamingTheKeyToSet) {
  const Model m = fem_tets(1);
  EXPECT_NE(pbd_material_problem(m).find("scene.material"), std::string::npos) << pbd_material_problem(m);
  try {
    make_solver(derived("pbd", 5), m);
    FAIL() << "pbd ran an FEM material";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("scene.material"), std::string::npos) << e.what();
  }
}

// The material text of FEM groups says what each solver uses: no k under pbd (it refuses), the
// compliances 1 / (mu V) and 1 / (lambda_snh V) under xpbd, the element's energy under a
// reference; values equal to the shown digits print once.
TEST(PbdMaterial, FemGroupsSayWhatEachSolverUses) {
  Model m = fem_tets(2);
  for (Constraint& c : m.constraints)
    if (c.element == 0) c.compliance *= 1.0 + 1e-12;  // the same to 4 digits as the other element's
  const std::string pbd = material_text(m, derived("pbd", 10), 0.01);
  EXPECT_NE(pbd.find("x fem_deviatoric): no k (pbd has no stiffness rule"), std::string::npos) << pbd;
  EXPECT_EQ(pbd.find("k ="), std::string::npos) << pbd;
  const std::string xpbd = material_text(m, derived("xpbd", 10), 0.01);
  const double mu = 1e5 / 2.6, V = 1.0 / 6.0;
  char dev[64];
  std::snprintf(dev, sizeof dev, "alpha = %.4g = 1 / (mu V)", 1.0 / (mu * V));
  EXPECT_NE(xpbd.find(dev), std::string::npos) << xpbd;
  EXPECT_NE(xpbd.find("= 1 / (lambda_snh V)"), std::string::npos) << xpbd;
  EXPECT_EQ(xpbd.find(" .. "), std::string::npos) << xpbd;
  const std::string ref = material_text(m, derived("ref-be", 10), 0.01);
  EXPECT_NE(ref.find("x fem_deviatoric): the element's energy V Psi(F), mu = 3.846e+04 Pa"), std::string::npos)
      << ref;
  EXPECT_NE(material_text(m, derived("pbd-seed", 10), 0.01).find("none (pbd-seed"), std::string::npos);
}

TEST(PbdMaterial, SummaryNamesTheRuleOrTheOverride) {
  Model m = chain_model(3, 0.5, 1.0, Vec3(0, -9.81, 0), 0.4, 1e-3);
  m.group_names = {"links"};
  const std::string rule = pbd_material_text(m, derived("pbd", 10), 0.01);
  EXPECT_NE(rule.find("links (3 x distance): k = "), std::string::npos) << rule;
  EXPECT_NE(rule.find("derived from alpha = 0.001"), std::string::npos) << rule;
  const double k = pbd_stiffness_from_compliance(1e-3, 1.0, 0.01, 10);  // the top link: one mass
  char shown[32];
  std::snprintf(shown, sizeof shown, "k = %.4g .. ", k);
  EXPECT_NE(rule.find(shown), std::string::npos) << rule;
  const std::string explicit_k = pbd_material_text(m, options_for("pbd", 10), 0.01);
  EXPECT_NE(explicit_k.find("k = 0.4 (explicit override"), std::string::npos) << explicit_k;
  EXPECT_NE(material_text(m, options_for("xpbd", 10), 0.01).find("alpha = 0.001"), std::string::npos);
  EXPECT_NE(material_text(m, options_for("pbd-seed", 10), 0.01).find("k = 0.4"), std::string::npos);
}

TEST(PbdMaterial, ElasticEnergyIsDefinedWhereTheRunSimulatesTheSceneMaterial) {
  Model soft = chain_model(2, 0.5, 1.0, Vec3(0, -9.81, 0), 1.0, 1e-3);
  Model rigid = chain_model(2, 0.5, 1.0, Vec3(0, -9.81, 0), 1.0, 0.0);
  Model rigid_soft_k = chain_model(2, 0.5, 1.0, Vec3(0, -9.81, 0), 0.5, 0.0);
  EXPECT_TRUE(elastic_energy_defined(soft, derived("xpbd", 5)));
  EXPECT_TRUE(elastic_energy_defined(soft, derived("pbd", 5)));
  EXPECT_FALSE(elastic_energy_defined(soft, options_for("pbd", 5)));  // explicit k
  EXPECT_TRUE(elastic_energy_defined(rigid, options_for("pbd", 5)));  // k = 1 of alpha = 0
  EXPECT_FALSE(elastic_energy_defined(rigid_soft_k, options_for("pbd", 5)));
  EXPECT_FALSE(elastic_energy_defined(soft, derived("pbd-seed", 5)));
  EXPECT_TRUE(elastic_energy_defined(rigid, derived("pbd-seed", 5)));
}

}  // namespace
}  // namespace pbdbench::test
