// Tests of core/fem_constraints.cpp: Lame parameters, the deformation gradient, the gradients of
// the two XPBD constraints of the stable neo-Hookean material against central differences, the
// constraint form against the energy it stands for, and the element builder (counts, rest values,
// refusals); the strain-vector constraint of StVK and linear elements (tets and triangles): its
// gradients against central differences, C^T alpha^-1 C / 2 against the element energy, the block
// update, and the triangle builder.
//
// The energy density Psi_snh is written out here (stable_neo_hookean_density below) so that these
// tests do not depend on core/fem.cpp: the check is that the constraint form of
// Macklin and Mueller 2021 is the material of core/model.hpp, whatever computes its stress.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <functional>
#include <vector>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "core/fem.hpp"
#include "core/generators.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using test::Config4;
using test::Random;

constexpr int kConfigurations = 400;  // random configurations per check

// Moduli of a soft solid, E = 1e5 Pa, nu = 0.3: mu = 38461.5 Pa, lambda = 57692.3 Pa.
constexpr double kYoung = 1e5;
constexpr double kPoisson = 0.3;

// A model of the four points of `rest` (unit masses) with one element of `material`.
Model one_tet_model(const Config4& rest, Material material = Material::StableNeoHookean,
                    double young = kYoung, double poisson = kPoisson) {
  Model m;
  m.rest_positions.resize(4, 3);
  for (int i = 0; i < 4; ++i) m.rest_positions.row(i) = rest[static_cast<size_t>(i)].transpose();
  m.inv_mass.assign(4, 1.0);
  m.radius.assign(4, 0.01);
  m.tets = {{0, 1, 2, 3}};
  fem::add_fem_elements(m, m.tets, material, young, poisson);
  return m;
}

Points points(const Config4& x) {
  Points p(4, 3);
  for (int i = 0; i < 4; ++i) p.row(i) = x[static_cast<size_t>(i)].transpose();
  return p;
}

// A positively oriented rest tet of edge about 1 m: the unit right tet, each vertex moved by up
// to 0.2 m (never degenerate: its volume stays near 1/6 m^3).
Config4 random_rest_tet(Random& rng) {
  return {rng.vec(-0.2, 0.2), Vec3::UnitX() + rng.vec(-0.2, 0.2), Vec3::UnitY() + rng.vec(-0.2, 0.2),
          Vec3::UnitZ() + rng.vec(-0.2, 0.2)};
}

// A deformed configuration: a random linear map with entries in [-1.5, 1.5] (stretches,
// shears, rotations and inversions alike) applied to the rest tet, then translated.
Config4 random_deformation(Random& rng, const Config4& rest) {
  Mat3 A;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A(r, c) = rng.uniform(-1.5, 1.5);
  const Vec3 t = rng.vec(-1, 1);
  Config4 x;
  for (size_t i = 0; i < 4; ++i) x[i] = A * rest[i] + t + rng.vec(-0.05, 0.05);
  return x;
}

// Psi_snh(F) = mu/2 (I_C - 3) + ls/2 (J - 1 - mu/ls)^2, ls = lambda + mu (core/model.hpp,
// Material::StableNeoHookean), and its first Piola-Kirchhoff stress
// P = mu F + ls (J - 1 - mu/ls) cof F.
double stable_neo_hookean_density(double mu, double lambda, const Mat3& F) {
  const double ls = lambda + mu;
  const double s = F.determinant() - 1.0 - mu / ls;
  return 0.5 * mu * ((F.transpose() * F).trace() - 3.0) + 0.5 * ls * s * s;
}
Mat3 stable_neo_hookean_stress(double mu, double lambda, const Mat3& F) {
  const double ls = lambda + mu;
  Mat3 cof;
  cof.col(0) = F.col(1).cross(F.col(2));
  cof.col(1) = F.col(2).cross(F.col(0));
  cof.col(2) = F.col(0).cross(F.col(1));
  return mu * F + ls * (F.determinant() - 1.0 - mu / ls) * cof;
}

// F from the definition, without fem::deformation_gradient: Ds Dm^-1.
Mat3 reference_f(const Config4& rest, const Config4& x) {
  Mat3 Dm, Ds;
  for (int k = 0; k < 3; ++k) {
    Dm.col(k) = rest[static_cast<size_t>(k + 1)] - rest[0];
    Ds.col(k) = x[static_cast<size_t>(k + 1)] - x[0];
  }
  return Ds * Dm.inverse();
}

// ---------------------------------------------------------------------------------------------

TEST(FemConstraints, LameParameters) {
  const fem::Lame l = fem::lame(kYoung, kPoisson);
  // mu = 1e5 / 2.6, lambda = 3e4 / (1.3 * 0.4).
  EXPECT_TRUE(test::near(l.mu, 1e5 / 2.6, test::kRoundoff));
  EXPECT_TRUE(test::near(l.lambda, 3e4 / 0.52, test::kRoundoff));
  EXPECT_TRUE(test::near(fem::snh_lambda(l.mu, l.lambda), 1e5 / 2.6 + 3e4 / 0.52, test::kRoundoff));
  // nu = 0: no coupling between the axes; lambda = 0 and mu = E / 2.
  const fem::Lame zero = fem::lame(2.0, 0.0);
  EXPECT_EQ(zero.lambda, 0.0);
  EXPECT_TRUE(test::near(zero.mu, 1.0, test::kRoundoff));
}

TEST(FemConstraints, DeformationGradientOfAnAffineMapIsItsMatrix) {
  Random rng(21);
  for (int n = 0; n < 50; ++n) {
    const Config4 rest = random_rest_tet(rng);
    const Model m = one_tet_model(rest);
    Mat3 A;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) A(r, c) = rng.uniform(-2, 2);
    const Vec3 b = rng.vec(-3, 3);
    Config4 x;
    for (size_t i = 0; i < 4; ++i) x[i] = A * rest[i] + b;
    const Mat3 F = fem::deformation_gradient(m.elements[0], points(x));
    // F = Ds Dm^-1 with |Dm^-1| about 1: a few dozen ulps of |A|.
    EXPECT_LE((F - A).norm(), 1e-12 * A.norm()) << "configuration " << n;
  }
  // At rest F = I.
  const Config4 rest = random_rest_tet(rng);
  const Model m = one_tet_model(rest);
  EXPECT_LE((fem::deformation_gradient(m.elements[0], points(rest)) - Mat3::Identity()).norm(), 1e-14);
}

// The gradient and momentum checks of tests/core/test_support.hpp over random rest shapes and
// deformations (inverted ones included).
void check_fem_gradients(const char* name, bool hydrostatic, std::uint64_t seed) {
  Random rng(seed);
  int failures = 0, skipped = 0;
  for (int n = 0; n < kConfigurations; ++n) {
    const Config4 rest = random_rest_tet(rng);
    const Model m = one_tet_model(rest);
    const FemElement& e = m.elements[0];
    const double rest_value = hydrostatic ? m.constraints[1].rest : 0.0;
    const auto eval = [&](const Config4& y) {
      return hydrostatic ? fem::eval_hydrostatic(e, points(y), rest_value) : fem::eval_deviatoric(e, points(y));
    };
    const Config4 x = random_deformation(rng, rest);
    const ConstraintEval c = eval(x);
    if (!c.valid) {
      ++skipped;
      continue;
    }
    const std::string grad = test::check_gradient(eval, x, 4);
    const std::string momentum = test::check_momentum(c, x, 4);
    if (!grad.empty() || !momentum.empty()) {
      ADD_FAILURE() << name << ", configuration " << n << " (seed " << seed << "): " << grad << " "
                    << momentum;
      if (++failures >= 5) return;
    }
  }
  EXPECT_EQ(skipped, 0) << name << ": random deformations should never make F = 0";
}

TEST(FemConstraints, DeviatoricGradientMatchesFiniteDifferences) {
  check_fem_gradients("deviatoric", false, 31);
}

TEST(FemConstraints, HydrostaticGradientMatchesFiniteDifferences) {
  check_fem_gradients("hydrostatic", true, 32);
}

TEST(FemConstraints, ValuesAgainstTheDefinitions) {
  Random rng(33);
  for (int n = 0; n < 100; ++n) {
    const Config4 rest = random_rest_tet(rng);
    const Model m = one_tet_model(rest);
    const Config4 x = random_deformation(rng, rest);
    const Mat3 F = reference_f(rest, x);
    const ConstraintEval d = fem::eval_deviatoric(m.elements[0], points(x));
    const ConstraintEval h = fem::eval_hydrostatic(m.elements[0], points(x), 0.25);
    EXPECT_TRUE(test::near(d.C, std::sqrt((F.transpose() * F).trace()), test::kRoundoff));
    EXPECT_TRUE(test::near(h.C, F.determinant() - 0.25, test::kRoundoff));
  }
  // A uniform stretch by s: C_D = sqrt(3) s, det F = s^3; the deviatoric gradient pushes the
  // vertices outward from the centroid.
  const Config4 rest = {Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  const Model m = one_tet_model(rest);
  Config4 x = rest;
  for (Vec3& p : x) p *= 2.0;
  EXPECT_TRUE(test::near(fem::eval_deviatoric(m.elements[0], points(x)).C, 2.0 * std::sqrt(3.0), test::kRoundoff));
  EXPECT_TRUE(test::near(fem::eval_hydrostatic(m.elements[0], points(x), 1.0).C, 7.0, test::kRoundoff));
  // The deviatoric constraint is undefined at F = 0 (all four vertices at one point).
  const Config4 collapsed = {Vec3::Ones(), Vec3::Ones(), Vec3::Ones(), Vec3::Ones()};
  EXPECT_FALSE(fem::eval_deviatoric(m.elements[0], points(collapsed)).valid);
  EXPECT_FALSE(fem::eval_hydrostatic(m.elements[0], points(collapsed), 1.0).valid);
}

// The heart of the XPBD form (Macklin and Mueller 2021): for the two constraints of an element,
//   U_c(x) = C_D^2 / (2 alpha_D) + C_H^2 / (2 alpha_H) = V0 Psi_snh(F) + 3 mu V0 / 2,
// a constant offset (with alpha_D = 1/(mu V0): C_D^2/(2 alpha_D) = V0 mu/2 I_C, which is V0 times
// the first term of Psi plus V0 3 mu/2; with alpha_H = 1/(ls V0) and rest 1 + mu/ls the second
// terms are equal). The gradients agree too: sum_j C_j grad C_j / alpha_j = V0 P b_v.
TEST(FemConstraints, ConstraintEnergyIsTheStableNeoHookeanEnergyPlusAConstant) {
  Random rng(34);
  double worst_constant = 0.0;  // max |U_c - V0 Psi - 3 mu V0 / 2| / (U_c + V0 |Psi|)
  double worst_gradient = 0.0;  // max over components |grad U_c - grad V0 Psi| / |grad V0 Psi|_inf
  double worst_fd = 0.0;        // the test's own stress against central differences of V0 Psi
  int inverted = 0;
  for (int n = 0; n < kConfigurations; ++n) {
    const Config4 rest = random_rest_tet(rng);
    // Moduli from soft to stiff, nu from 0 to nearly incompressible.
    const double young = std::pow(10.0, rng.uniform(3.0, 8.0));
    const double poisson = rng.uniform(0.0, 0.49);
    const Model m = one_tet_model(rest, Material::StableNeoHookean, young, poisson);
    ASSERT_EQ(m.constraints.size(), 2u);
    const FemElement& e = m.elements[0];
    const Config4 x = random_deformation(rng, rest);
    const Points px = points(x);
    const Mat3 F = reference_f(rest, x);
    if (F.determinant() < 0.0) ++inverted;

    double U = 0.0;
    std::array<Vec3, 4> grad_U{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    for (const Constraint& c : m.constraints) {
      const ConstraintEval ev = eval_constraint(m, c, px);
      ASSERT_TRUE(ev.valid);
      U += ev.C * ev.C / (2.0 * c.compliance);
      for (size_t i = 0; i < 4; ++i) grad_U[i] += (ev.C / c.compliance) * ev.grad[i];
    }
    const double V0 = e.rest_volume;
    const double W = V0 * stable_neo_hookean_density(e.mu, e.lambda, F);
    const double constant = 1.5 * e.mu * V0;
    const double scale = std::abs(U) + std::abs(W);
    const double mismatch = std::abs(U - W - constant) / scale;
    worst_constant = std::max(worst_constant, mismatch);
    // Both sides are sums of a few terms of size `scale`, each with a few ulps of round-off.
    EXPECT_LE(mismatch, 1e-12) << "configuration " << n << ": U_c = " << U << " J, V0 Psi = " << W
                               << " J, 3 mu V0 / 2 = " << constant << " J";

    // Gradient of V0 Psi(F(x)): vertex k+1 gets V0 P Dm^-T e_k, vertex 0 minus their sum.
    const Mat3 G = V0 * stable_neo_hookean_stress(e.mu, e.lambda, F) * e.rest_inverse.transpose();
    std::array<Vec3, 4> grad_W{-(G.col(0) + G.col(1) + G.col(2)), G.col(0), G.col(1), G.col(2)};
    double gmax = 0.0;
    for (const Vec3& g : grad_W) gmax = std::max(gmax, g.cwiseAbs().maxCoeff());
    // The gradient vanishes only at rest-like configurations, which random maps never hit; mu V0
    // is the stress scale that keeps the ratio meaningful if one came close.
    const double gscale = std::max(gmax, e.mu * V0);
    for (size_t i = 0; i < 4; ++i) {
      const double d = (grad_U[i] - grad_W[i]).cwiseAbs().maxCoeff() / gscale;
      worst_gradient = std::max(worst_gradient, d);
      EXPECT_LE(d, 1e-12) << "configuration " << n << ", vertex " << i;
    }
    // The test's own stress is the derivative of its density (so the comparison above is not
    // two copies of one mistake): central differences of V0 Psi(F(x)).
    const auto energy = [&](const Config4& y) {
      return V0 * stable_neo_hookean_density(e.mu, e.lambda, reference_f(rest, y));
    };
    for (int i = 0; i < 4; ++i) {
      const Vec3 fd = test::fd_gradient(energy, x, i);
      // Central differences with h = 1e-6 m on an energy of size `scale`: round-off about
      // 1e-16 scale / h, truncation about h^2 |Psi'''| ~ 1e-12 gscale.
      const double d = (fd - grad_W[static_cast<size_t>(i)]).cwiseAbs().maxCoeff() / gscale;
      worst_fd = std::max(worst_fd, d);
      EXPECT_LE(d, 1e-6) << "configuration " << n << ", vertex " << i;
    }
  }
  EXPECT_GT(inverted, kConfigurations / 10) << "the draw should include inverted elements";
  std::printf("[ measured ] U_c - V0 Psi_snh - 3 mu V0/2: max relative deviation %.3g; gradient "
              "mismatch (relative to max |grad|) %.3g; the test's stress vs central differences "
              "%.3g; %d of %d configurations inverted\n",
              worst_constant, worst_gradient, worst_fd, inverted, kConfigurations);
}

// The check above must be able to fail: a hydrostatic rest of 1 (the textbook neo-Hookean
// volume term, not the stable one) makes U_c - V0 Psi depend on J.
TEST(FemConstraints, EnergyCheckDetectsAWrongRestValue) {
  Random rng(35);
  const Config4 rest = random_rest_tet(rng);
  Model m = one_tet_model(rest);
  m.constraints[1].rest = 1.0;
  const FemElement& e = m.elements[0];
  double lo = 1e300, hi = -1e300;
  for (int n = 0; n < 20; ++n) {
    const Config4 x = random_deformation(rng, rest);
    double U = 0.0;
    for (const Constraint& c : m.constraints) {
      const double C = eval_constraint(m, c, points(x)).C;
      U += C * C / (2.0 * c.compliance);
    }
    const double offset = U - e.rest_volume * stable_neo_hookean_density(e.mu, e.lambda, reference_f(rest, x));
    lo = std::min(lo, offset);
    hi = std::max(hi, offset);
  }
  EXPECT_GT(hi - lo, 1e-3 * e.mu * e.rest_volume);
}

// ---------------------------------------------------------------------------------------------
// add_fem_elements

TEST(FemConstraints, AddFemElementsCountsRestValuesAndGroups) {
  Model m;
  TetBlockSpec spec;
  spec.cells = {3, 2, 1};
  spec.size = Vec3(0.3, 0.2, 0.1);
  spec.edges = false;
  spec.volumes = false;
  add_tet_block(m, spec);
  const size_t K = m.tets.size();
  ASSERT_EQ(K, 36u);
  ASSERT_TRUE(m.constraints.empty());
  fem::add_fem_elements(m, m.tets, Material::StableNeoHookean, kYoung, kPoisson);
  ASSERT_EQ(m.elements.size(), K);
  ASSERT_EQ(m.constraints.size(), 2 * K);
  ASSERT_EQ(m.group_names, (std::vector<std::string>{"fem_deviatoric", "fem_hydrostatic"}));
  const fem::Lame l = fem::lame(kYoung, kPoisson);
  const double ls = fem::snh_lambda(l.mu, l.lambda);
  double total = 0.0;
  for (size_t k = 0; k < K; ++k) {
    SCOPED_TRACE("element " + std::to_string(k));
    const FemElement& e = m.elements[k];
    EXPECT_EQ(e.particles, m.tets[k]);
    EXPECT_EQ(e.material, Material::StableNeoHookean);
    EXPECT_EQ(e.mu, l.mu);
    EXPECT_EQ(e.lambda, l.lambda);
    const double v = tet_signed_volume(m.rest_positions.row(e.particles[0]), m.rest_positions.row(e.particles[1]),
                                       m.rest_positions.row(e.particles[2]), m.rest_positions.row(e.particles[3]));
    EXPECT_TRUE(test::near(e.rest_volume, v, test::kRoundoff));
    total += e.rest_volume;
    const Constraint& d = m.constraints[2 * k];
    const Constraint& h = m.constraints[2 * k + 1];
    EXPECT_EQ(d.kind, ConstraintKind::FemDeviatoric);
    EXPECT_EQ(h.kind, ConstraintKind::FemHydrostatic);
    for (const Constraint* c : {&d, &h}) {
      EXPECT_EQ(c->element, static_cast<int>(k));
      EXPECT_EQ(c->particles, e.particles);
      EXPECT_EQ(c->stiffness, 1.0);
      EXPECT_EQ(c->damping, 0.0);
    }
    EXPECT_EQ(m.group_names[d.group], "fem_deviatoric");
    EXPECT_EQ(m.group_names[h.group], "fem_hydrostatic");
    EXPECT_EQ(d.rest, 0.0);
    EXPECT_TRUE(test::near(h.rest, 1.0 + l.mu / ls, test::kRoundoff));
    EXPECT_TRUE(test::near(d.compliance, 1.0 / (l.mu * e.rest_volume), test::kRoundoff));
    EXPECT_TRUE(test::near(h.compliance, 1.0 / (ls * e.rest_volume), test::kRoundoff));
    // At rest F = I: C_D = sqrt(3), C_H = 1 - rest = -mu/ls.
    EXPECT_TRUE(test::near(eval_constraint(m, d, m.rest_positions).C, std::sqrt(3.0), test::kRoundoff));
    EXPECT_TRUE(test::near(eval_constraint(m, h, m.rest_positions).C, -l.mu / ls, test::kRoundoff));
  }
  EXPECT_TRUE(test::near(total, 0.3 * 0.2 * 0.1, test::kRoundoff));

  // A second call appends: element indices continue, the groups are shared.
  fem::add_fem_elements(m, {m.tets[0]}, Material::StableNeoHookean, 2 * kYoung, kPoisson);
  ASSERT_EQ(m.elements.size(), K + 1);
  EXPECT_EQ(m.constraints.back().element, static_cast<int>(K));
  EXPECT_EQ(m.group_names.size(), 2u);
}

TEST(FemConstraints, CorotatedElementsHaveNoConstraints) {
  const Config4 rest = {Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  const Model m = one_tet_model(rest, Material::Corotated);
  ASSERT_EQ(m.elements.size(), 1u);
  EXPECT_EQ(m.elements[0].material, Material::Corotated);
  EXPECT_TRUE(test::near(m.elements[0].rest_volume, 1.0 / 6.0, test::kRoundoff));
  EXPECT_TRUE(m.constraints.empty());
  EXPECT_TRUE(m.group_names.empty());
}

std::string refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(FemConstraints, NegativeOrDegenerateTetsAreRefusedByName) {
  Model m;
  m.rest_positions.resize(5, 3);
  m.rest_positions << 0, 0, 0,  //
      1, 0, 0,                  //
      0, 1, 0,                  //
      0, 0, 1,                  //
      1, 1, 0;                  // coplanar with 0, 1, 2
  m.inv_mass.assign(5, 1.0);
  m.radius.assign(5, 0.01);
  const std::vector<std::array<int, 4>> negative = {{0, 1, 2, 3}, {0, 2, 1, 3}};
  std::string what = refusal([&] { fem::add_fem_elements(m, negative, Material::StableNeoHookean, kYoung, kPoisson); });
  EXPECT_NE(what.find("tet 1 (particles 0 2 1 3) is negatively oriented"), std::string::npos) << what;
  // A refusal leaves the model as it was (the first, good tet is not added either).
  EXPECT_TRUE(m.elements.empty());
  EXPECT_TRUE(m.constraints.empty());
  EXPECT_TRUE(m.group_names.empty());
  what = refusal([&] { fem::add_fem_elements(m, {{0, 1, 2, 4}}, Material::Corotated, kYoung, kPoisson); });
  EXPECT_NE(what.find("tet 0 (particles 0 1 2 4) is degenerate"), std::string::npos) << what;
  what = refusal([&] { fem::add_fem_elements(m, {{0, 1, 2, 7}}, Material::Corotated, kYoung, kPoisson); });
  EXPECT_NE(what.find("tet 0 (particles 0 1 2 7): particle index 7 is out of range"), std::string::npos) << what;
  what = refusal([&] { fem::add_fem_elements(m, {{0, 1, 2, 3}}, Material::StableNeoHookean, 0.0, kPoisson); });
  EXPECT_NE(what.find("youngs_modulus = 0"), std::string::npos) << what;
  what = refusal([&] { fem::add_fem_elements(m, {{0, 1, 2, 3}}, Material::StableNeoHookean, kYoung, 0.5); });
  EXPECT_NE(what.find("poisson_ratio = 0.5"), std::string::npos) << what;
  EXPECT_TRUE(m.elements.empty());
}


// ---------------------------------------------------------------------------------------------
// The strain-vector constraint (StVK and linear; Macklin et al. 2016, sec. 6.3).

// A model of the three points of a random triangle in a plane z = const with one StVK element of
// thickness 0.1 m.
Model one_triangle_model(Random& rng) {
  Model m;
  for (;;) {
    m = Model{};
    m.rest_positions.resize(3, 3);
    const double z = rng.uniform(-1, 1);
    for (int i = 0; i < 3; ++i)
      m.rest_positions.row(i) = Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), z).transpose();
    const Vec3 e1 = m.rest_positions.row(1) - m.rest_positions.row(0);
    const Vec3 e2 = m.rest_positions.row(2) - m.rest_positions.row(0);
    if (0.5 * e1.cross(e2).norm() > 0.05) break;
  }
  m.inv_mass.assign(3, 1.0);
  m.radius.assign(3, 0.01);
  fem::add_fem_triangles(m, {{0, 1, 2}}, Material::StVK, kYoung, kPoisson, 0.1);
  return m;
}

// A random deformation of the first `count` rows of rest: a linear map with entries in
// [-1.5, 1.5], a translation and a small jitter.
Points deformed(Random& rng, const Points& rest) {
  Mat3 A;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A(r, c) = rng.uniform(-1.5, 1.5);
  const Vec3 t = rng.vec(-1, 1);
  Points x = rest;
  for (int i = 0; i < rest.rows(); ++i)
    x.row(i) = (A * rest.row(i).transpose() + t + rng.vec(-0.05, 0.05)).transpose();
  return x;
}

// The element models the strain checks run over: tets of StVK and linear, triangles of StVK.
std::vector<Model> strain_models(Random& rng, int count) {
  std::vector<Model> out;
  for (int n = 0; n < count; ++n) {
    out.push_back(one_tet_model(random_rest_tet(rng), Material::StVK));
    out.push_back(one_tet_model(random_rest_tet(rng), Material::Linear));
    out.push_back(one_triangle_model(rng));
  }
  return out;
}

TEST(FemStrain, GradientMatchesFiniteDifferences) {
  Random rng(41);
  int failures = 0;
  for (const Model& m : strain_models(rng, kConfigurations / 4)) {
    const FemElement& e = m.elements[0];
    const Points x = deformed(rng, m.rest_positions);
    const fem::StrainEval ev = fem::eval_strain(e, x);
    ASSERT_EQ(ev.components, e.vertices == 3 ? 3 : 6);
    for (int c = 0; c < ev.components && failures < 5; ++c)
      for (int v = 0; v < e.vertices; ++v)
        for (int a = 0; a < 3; ++a) {
          Points xp = x, xm = x;
          xp(v, a) += test::kFdStep;
          xm(v, a) -= test::kFdStep;
          const double fd = (fem::eval_strain(e, xp).C(c) - fem::eval_strain(e, xm).C(c)) / (2.0 * test::kFdStep);
          const double got = ev.grad[static_cast<size_t>(c)][static_cast<size_t>(v)](a);
          if (!test::near(got, fd, test::kFdTol)) {
            ADD_FAILURE() << to_string(e.material) << (e.vertices == 3 ? " triangle" : " tet")
                          << ": dC_" << c << "/dx_" << v << "(" << a << ") = " << got
                          << ", central difference " << fd;
            ++failures;
          }
        }
    // Translation invariance: the gradients of each component sum to zero over the vertices.
    for (int c = 0; c < ev.components; ++c) {
      Vec3 sum = Vec3::Zero();
      for (int v = 0; v < e.vertices; ++v) sum += ev.grad[static_cast<size_t>(c)][static_cast<size_t>(v)];
      EXPECT_LE(sum.norm(), 1e-12 * (1.0 + ev.grad[static_cast<size_t>(c)][0].norm()));
    }
  }
}

TEST(FemStrain, QuadraticFormOfTheComplianceIsTheElementEnergy) {
  // C^T alpha^-1 C / 2 = V0 Psi(F) for StVK (Green strain) and linear (small strain) elements,
  // tets and triangles: the constraint form is the material (Macklin et al. 2016, eqs. 5, 27, 28).
  Random rng(42);
  for (const Model& m : strain_models(rng, kConfigurations / 4)) {
    const FemElement& e = m.elements[0];
    const Points x = deformed(rng, m.rest_positions);
    const fem::StrainEval ev = fem::eval_strain(e, x);
    const int k = ev.components;
    const Eigen::MatrixXd alpha = fem::strain_compliance(e).topLeftCorner(k, k);
    const Eigen::VectorXd C = ev.C.head(k);
    const double form = 0.5 * C.dot(alpha.ldlt().solve(C));
    const double energy = fem::element_energy(e, x);
    EXPECT_NEAR(form, energy, 1e-9 * std::max(1.0, std::abs(energy)))
        << to_string(e.material) << (e.vertices == 3 ? " triangle" : " tet");
    // The rest of the compliance matrix is 0, and it is symmetric positive definite.
    const fem::Mat6 full = fem::strain_compliance(e);
    EXPECT_EQ((full - full.transpose()).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_TRUE(full.bottomRightCorner(6 - k, 6 - k).isZero());
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(alpha).eigenvalues().minCoeff(), 0.0);
  }
  // The deviatoric entry is 1 / (2 mu V0), as the constraint's scalar compliance says.
  const Model m = one_tet_model(random_rest_tet(rng), Material::StVK);
  EXPECT_TRUE(test::near(fem::strain_compliance(m.elements[0])(5, 5), m.constraints[0].compliance,
                         test::kRoundoff));
}

TEST(FemStrain, BlockUpdateSolvesTheLinearisedStepAndConservesMomentum) {
  // One update: (sum_v w_v J_v J_v^T + alpha~) dlambda = -C - alpha~ lambda, dx_v = w_v J_v^T
  // dlambda; the impulses sum to zero. Repeated updates of a single element are the quasi-Newton
  // steps of Macklin et al. 2016, eq. 15 (K = M, g assumed 0): they converge to h = C + alpha~
  // lambda = 0. (g = M (x - x~) - J^T lambda is not driven to 0: XPBD's fixed point, not the
  // minimiser of the step, as the paper says of its approximation.)
  Random rng(43);
  for (const Model& m : strain_models(rng, 40)) {
    const FemElement& e = m.elements[0];
    const int nv = e.vertices;
    std::array<double, 4> w{};
    for (int v = 0; v < nv; ++v) w[static_cast<size_t>(v)] = rng.uniform(0.5, 2.0);
    if (rng.uniform() < 0.3) w[0] = 0.0;  // a pinned vertex
    const double h = 1.0 / 60.0;
    const fem::Mat6 alpha_tilde = fem::strain_compliance(e) / (h * h) * 1e3;  // soft enough to settle
    const Points x_pred = m.rest_positions + 0.2 * (deformed(rng, m.rest_positions) - m.rest_positions);
    Points x = x_pred;
    fem::Vec6 lambda = fem::Vec6::Zero();
    for (int it = 0; it < 200; ++it) {
      const fem::StrainEval ev = fem::eval_strain(e, x);
      std::array<Vec3, 4> dx{};
      fem::Vec6 dl;
      ASSERT_TRUE(fem::xpbd_strain_update(ev, w, alpha_tilde, lambda, dx, dl));
      if (it == 0) {
        // The linear system holds, and the impulses J_v^T dlambda sum to zero.
        const int k = ev.components;
        Eigen::MatrixXd A = alpha_tilde.topLeftCorner(k, k);
        for (int v = 0; v < nv; ++v)
          for (int i = 0; i < k; ++i)
            for (int j = 0; j < k; ++j)
              A(i, j) += w[static_cast<size_t>(v)] * ev.grad[static_cast<size_t>(i)][static_cast<size_t>(v)].dot(
                                                         ev.grad[static_cast<size_t>(j)][static_cast<size_t>(v)]);
        const Eigen::VectorXd r = A * dl.head(k) + ev.C.head(k) + alpha_tilde.topLeftCorner(k, k) * lambda.head(k);
        EXPECT_LE(r.norm(), 1e-9 * (1.0 + ev.C.norm()));
        Vec3 impulse = Vec3::Zero();
        for (int v = 0; v < nv; ++v)
          for (int c = 0; c < k; ++c) impulse += dl(c) * ev.grad[static_cast<size_t>(c)][static_cast<size_t>(v)];
        EXPECT_LE(impulse.norm(), 1e-9 * (1.0 + dl.norm()));
      }
      for (int v = 0; v < nv; ++v) x.row(v) += dx[static_cast<size_t>(v)].transpose();
      lambda += dl;
    }
    const fem::StrainEval ev = fem::eval_strain(e, x);
    const fem::Vec6 hres = ev.C + alpha_tilde * lambda;  // 0 past the components
    EXPECT_LE(hres.norm(), 1e-9) << to_string(e.material);
  }
  // Every vertex pinned: nothing to move, the update refuses.
  const Model m = one_tet_model(random_rest_tet(rng), Material::StVK);
  std::array<Vec3, 4> dx{};
  fem::Vec6 dl;
  EXPECT_FALSE(fem::xpbd_strain_update(fem::eval_strain(m.elements[0], m.rest_positions),
                                       {0.0, 0.0, 0.0, 0.0}, fem::Mat6::Zero(), fem::Vec6::Zero(), dx, dl));
}

TEST(FemStrain, BuildersAddOneStrainConstraintPerElement) {
  Random rng(44);
  Model m = one_tet_model(random_rest_tet(rng), Material::Linear);
  ASSERT_EQ(m.constraints.size(), 1u);
  EXPECT_EQ(m.constraints[0].kind, ConstraintKind::FemStrainTet);
  EXPECT_EQ(m.group_names, (std::vector<std::string>{"fem_strain"}));
  // At rest the strain is 0; eval_constraint reports its norm, with no single gradient.
  const ConstraintEval rest = eval_constraint(m, m.constraints[0], m.rest_positions);
  EXPECT_FALSE(rest.valid);
  EXPECT_LE(rest.C, 1e-14);

  Model t = one_triangle_model(rng);
  ASSERT_EQ(t.elements.size(), 1u);
  EXPECT_EQ(t.elements[0].vertices, 3);
  EXPECT_EQ(t.elements[0].particles[3], -1);
  const Vec3 e1 = t.rest_positions.row(1) - t.rest_positions.row(0);
  const Vec3 e2 = t.rest_positions.row(2) - t.rest_positions.row(0);
  EXPECT_TRUE(test::near(t.elements[0].rest_volume, 0.5 * e1.cross(e2).norm() * 0.1, test::kRoundoff));
  ASSERT_EQ(t.constraints.size(), 1u);
  EXPECT_EQ(t.constraints[0].kind, ConstraintKind::FemStrainTriangle);
  EXPECT_EQ(arity(t.constraints[0].kind), 3);
  // At rest, and after a rotation in the plane, the Green strain is 0.
  EXPECT_LE(fem::eval_strain(t.elements[0], t.rest_positions).C.norm(), 1e-14);
  Points turned = t.rest_positions;
  const Mat3 Q = Eigen::AngleAxisd(0.7, Vec3::UnitZ()).toRotationMatrix();
  for (int i = 0; i < 3; ++i) turned.row(i) = (Q * t.rest_positions.row(i).transpose()).transpose();
  EXPECT_LE(fem::eval_strain(t.elements[0], turned).C.norm(), 1e-14);
  // Not in a plane z = const: refused.
  Model tilted = t;
  tilted.elements.clear();
  tilted.constraints.clear();
  tilted.rest_positions(2, 2) += 0.3;
  std::string tilt = refusal([&] {
    fem::add_fem_triangles(tilted, {{0, 1, 2}}, Material::StVK, kYoung, kPoisson, 0.1);
  });
  EXPECT_NE(tilt.find("does not lie in a plane z = const"), std::string::npos) << tilt;

  // Refusals: another material on triangles, a degenerate triangle, a bad thickness.
  std::string what = refusal([&] {
    fem::add_fem_triangles(t, {{0, 1, 2}}, Material::StableNeoHookean, kYoung, kPoisson, 0.1);
  });
  EXPECT_NE(what.find("only stvk has triangles"), std::string::npos) << what;
  Model line;
  line.rest_positions.resize(3, 3);
  line.rest_positions << 0, 0, 0, 1, 0, 0, 2, 0, 0;
  line.inv_mass.assign(3, 1.0);
  line.radius.assign(3, 0.01);
  what = refusal([&] { fem::add_fem_triangles(line, {{0, 1, 2}}, Material::StVK, kYoung, kPoisson, 0.1); });
  EXPECT_NE(what.find("triangle 0 (particles 0 1 2) is degenerate"), std::string::npos) << what;
  what = refusal([&] { fem::add_fem_triangles(t, {{0, 1, 2}}, Material::StVK, kYoung, kPoisson, 0.0); });
  EXPECT_NE(what.find("thickness = 0"), std::string::npos) << what;
  EXPECT_TRUE(fem::has_constraint_form(Material::StVK));
  EXPECT_TRUE(fem::has_constraint_form(Material::Linear));
  EXPECT_FALSE(fem::has_constraint_form(Material::Corotated));
}

}  // namespace
}  // namespace pbdbench
