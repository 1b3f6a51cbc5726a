// Tests of the material part of core/fem (core/fem.cpp): stresses against finite differences of
// the energy density, stress derivatives against finite differences of the stress, element
// gradients and Hessians against finite differences, for every material over random deformation
// gradients (near identity, large rotations, stretch, compression, equal and nearly equal singular
// values); the rest state, rotation invariance (not for the linear material, which has none), the
// small-strain limit and the PSD projection; the same for the StVK triangle (a 3 x 2 F).
#include "core/fem.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <stdexcept>
#include <sstream>
#include <string>
#include <vector>

#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using fem::Mat12;
using fem::Mat9;
using fem::Vec12;
using test::Random;

// ---------------------------------------------------------------------------------------------
// Tolerances. A comparison of arrays passes when every entry satisfies
// |a - b| <= abs * scale + rel * |b|, b the finite-difference value and scale the magnitude named
// at each use (a modulus, or the largest entry of the analytic array).

// Central differences in F with step kFStep (F is dimensionless, of order 1): the truncation error
// h^2 |Psi'''| / 6 is ~1e-11 of the moduli, the round-off eps |Psi| / h up to ~1e-9 of them for the
// largest stretches drawn (|Psi| ~ 100 (mu + lambda)). 1e-7 of the moduli plus 1e-6 relative is
// two orders above both and far below any error of a wrong term.
constexpr double kFStep = 1e-5;
constexpr test::Tolerance kStressTol{1e-7, 1e-6};

// Element finite differences in positions (edges of order 1 m) with step kXStep, the same
// reasoning, with scale = the largest entry of the analytic gradient or Hessian.
constexpr double kXStep = 1e-6;
constexpr test::Tolerance kElementTol{1e-7, 1e-6};

// Computations that differ only by rounding (a rotated copy, the same product in another order):
// sums of a few dozen terms of order 1, relative to the scale given.
constexpr double kRoundoff = 1e-12;

constexpr int kRandomF = 300;  // random deformation gradients per category and material

const Material kMaterials[] = {Material::StableNeoHookean, Material::Corotated, Material::StVK,
                               Material::Linear};

// Moduli of a soft, a nearly incompressible and a compressible-leaning material (Pa is
// irrelevant to the checks: every tolerance scales with mu + lambda).
struct Moduli {
  double mu, lambda;
};
const Moduli kModuli[] = {{1.0, 1.5}, {3.4, 31.0}, {2.0, 0.2}};

std::string str(const Mat3& F) {
  std::ostringstream s;
  s.precision(17);
  s << "[" << F(0, 0) << ", " << F(0, 1) << ", " << F(0, 2) << "; " << F(1, 0) << ", " << F(1, 1)
    << ", " << F(1, 2) << "; " << F(2, 0) << ", " << F(2, 1) << ", " << F(2, 2) << "]";
  return s.str();
}

Mat3 random_rotation(Random& rng, double max_angle) {
  Vec3 axis = rng.vec(-1, 1);
  while (axis.norm() < 1e-3) axis = rng.vec(-1, 1);
  return Eigen::AngleAxisd(rng.uniform(-max_angle, max_angle), axis.normalized()).toRotationMatrix();
}

Mat3 random_matrix(Random& rng, double lo, double hi) {
  Mat3 m;
  for (int i = 0; i < 9; ++i) m(i) = rng.uniform(lo, hi);
  return m;
}

// Categories of deformation gradients, all with det F > 0.
enum class Category { NearIdentity, Rotated, Stretched, Compressed, Equal, NearlyEqual, General };
const Category kCategories[] = {Category::NearIdentity, Category::Rotated,   Category::Stretched,
                                Category::Compressed,   Category::Equal,     Category::NearlyEqual,
                                Category::General};

const char* name(Category c) {
  switch (c) {
    case Category::NearIdentity: return "near identity";
    case Category::Rotated: return "large rotation";
    case Category::Stretched: return "stretched";
    case Category::Compressed: return "compressed";
    case Category::Equal: return "equal singular values";
    case Category::NearlyEqual: return "nearly equal singular values";
    case Category::General: return "general";
  }
  return "";
}

Mat3 random_F(Random& rng, Category c) {
  switch (c) {
    case Category::NearIdentity: return Mat3::Identity() + random_matrix(rng, -1e-3, 1e-3);
    case Category::Rotated:
      return random_rotation(rng, std::numbers::pi) * (Mat3::Identity() + random_matrix(rng, -0.2, 0.2));
    case Category::Stretched: {
      const Vec3 s(rng.uniform(1.1, 2.5), rng.uniform(1.1, 2.5), rng.uniform(1.0, 2.0));
      return random_rotation(rng, std::numbers::pi) * s.asDiagonal() * random_rotation(rng, std::numbers::pi);
    }
    case Category::Compressed: {
      const Vec3 s(rng.uniform(0.3, 0.9), rng.uniform(0.3, 0.9), rng.uniform(0.2, 1.0));
      return random_rotation(rng, std::numbers::pi) * s.asDiagonal() * random_rotation(rng, std::numbers::pi);
    }
    case Category::Equal: {  // two or three singular values equal: U and V are not unique
      const double a = rng.uniform(0.5, 1.5);
      const Vec3 s(a, a, rng.uniform() < 0.5 ? a : rng.uniform(0.5, 1.5));
      return random_rotation(rng, std::numbers::pi) * s.asDiagonal() * random_rotation(rng, std::numbers::pi);
    }
    case Category::NearlyEqual: {
      const double a = rng.uniform(0.5, 1.5);
      const Vec3 s(a, a * (1.0 + 1e-9 * rng.uniform(-1, 1)), a * (1.0 + 1e-7 * rng.uniform(-1, 1)));
      return random_rotation(rng, std::numbers::pi) * s.asDiagonal() * random_rotation(rng, std::numbers::pi);
    }
    case Category::General: {
      Mat3 F = random_matrix(rng, -1.5, 1.5);
      while (std::abs(F.determinant()) < 0.05) F = random_matrix(rng, -1.5, 1.5);
      if (F.determinant() < 0.0) F.col(0) = -F.col(0);
      return F;
    }
  }
  return Mat3::Identity();
}

// Largest ratio |a - b| / (abs * scale + rel |b|) over the entries (<= 1: all pass), and where it
// happens. The largest ratio seen by a test is printed as "[ measured ]", to show the margin.
double g_worst_ratio = 0.0;

template <class A, class B>
double worst(const A& a, const B& b, test::Tolerance tol, double scale, Eigen::Index* at = nullptr) {
  double w = 0.0;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    const double ratio = std::abs(a(i) - b(i)) / (tol.abs * scale + tol.rel * std::abs(b(i)));
    if (!(ratio <= w)) {  // NaN counts as worst
      w = ratio;
      if (at) *at = i;
    }
  }
  if (!(w <= g_worst_ratio)) g_worst_ratio = w;
  return w;
}

void reset_measured() { g_worst_ratio = 0.0; }
void print_measured() {
  std::printf("[ measured ] largest |analytic - central difference| / tolerance: %.3g\n", g_worst_ratio);
}

// Central differences of a function of F, one entry (column-major index) at a time.
Mat3 fd_of_scalar(const std::function<double(const Mat3&)>& f, const Mat3& F) {
  Mat3 g;
  for (int i = 0; i < 9; ++i) {
    Mat3 Fp = F, Fm = F;
    Fp(i) += kFStep;
    Fm(i) -= kFStep;
    g(i) = (f(Fp) - f(Fm)) / (2.0 * kFStep);
  }
  return g;
}

Mat9 fd_of_matrix(const std::function<Mat3(const Mat3&)>& f, const Mat3& F) {
  Mat9 d;
  for (int j = 0; j < 9; ++j) {
    Mat3 Fp = F, Fm = F;
    Fp(j) += kFStep;
    Fm(j) -= kFStep;
    const Mat3 diff = (f(Fp) - f(Fm)) / (2.0 * kFStep);
    d.col(j) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(diff.data());
  }
  return d;
}

// Runs `check` over every material, moduli and category; it returns an empty string or a
// failure description. Stops after a few failures.
void for_each_F(std::uint64_t seed,
                const std::function<std::string(Material, Moduli, const Mat3&)>& check) {
  Random rng(seed);
  int failures = 0;
  for (Material material : kMaterials)
    for (const Moduli& m : kModuli)
      for (Category c : kCategories)
        for (int k = 0; k < kRandomF; ++k) {
          const Mat3 F = random_F(rng, c);
          const std::string what = check(material, m, F);
          if (!what.empty()) {
            ADD_FAILURE() << to_string(material) << ", mu = " << m.mu << ", lambda = " << m.lambda
                          << ", " << name(c) << " F #" << k << " = " << str(F) << ": " << what;
            if (++failures >= 5) return;
          }
        }
}

// ---------------------------------------------------------------------------------------------
// Materials.

TEST(FemMaterial, StressMatchesFiniteDifferencesOfEnergy) {
  reset_measured();
  for_each_F(1, [](Material material, Moduli m, const Mat3& F) -> std::string {
    const Mat3 P = fem::first_piola(material, m.mu, m.lambda, F);
    const Mat3 fd = fd_of_scalar(
        [&](const Mat3& G) { return fem::energy_density(material, m.mu, m.lambda, G); }, F);
    Eigen::Index at = 0;
    if (worst(P, fd, kStressTol, m.mu + m.lambda, &at) <= 1.0) return "";
    std::ostringstream s;
    s.precision(17);
    s << "P(" << at << ") = " << P(at) << ", central difference of Psi " << fd(at);
    return s.str();
  });
  print_measured();
}

TEST(FemMaterial, StressDerivativeMatchesFiniteDifferencesOfStress) {
  reset_measured();
  for_each_F(2, [](Material material, Moduli m, const Mat3& F) -> std::string {
    const Mat9 A = fem::stress_derivative(material, m.mu, m.lambda, F);
    const Mat9 fd = fd_of_matrix(
        [&](const Mat3& G) { return fem::first_piola(material, m.mu, m.lambda, G); }, F);
    Eigen::Index at = 0;
    if (worst(A, fd, kStressTol, m.mu + m.lambda, &at) <= 1.0) return "";
    std::ostringstream s;
    s.precision(17);
    s << "dP/dF(" << at % 9 << ", " << at / 9 << ") = " << A(at) << ", central difference of P "
      << fd(at);
    return s.str();
  });
  print_measured();
}

TEST(FemMaterial, StressDerivativeIsSymmetric) {
  // dP/dF is the Hessian of Psi: symmetric, to rounding.
  for_each_F(3, [](Material material, Moduli m, const Mat3& F) -> std::string {
    const Mat9 A = fem::stress_derivative(material, m.mu, m.lambda, F);
    const double asym = (A - A.transpose()).cwiseAbs().maxCoeff();
    if (asym <= kRoundoff * (m.mu + m.lambda) * std::max(1.0, A.cwiseAbs().maxCoeff()))
      return "";
    return "dP/dF - dP/dF^T has an entry " + std::to_string(asym);
  });
}

TEST(FemMaterial, RestStateIsStressFree) {
  for (Material material : kMaterials)
    for (const Moduli& m : kModuli) {
      const Mat3 P = fem::first_piola(material, m.mu, m.lambda, Mat3::Identity());
      EXPECT_LE(P.cwiseAbs().maxCoeff(), kRoundoff * (m.mu + m.lambda))
          << to_string(material) << ", mu = " << m.mu << ", lambda = " << m.lambda << ": P(I) = " << P;
    }
  // The rest energy density: mu^2 / (2 lambda_snh) for the stable neo-Hookean, 0 for the others.
  const double mu = 3.4, lambda = 31.0;
  EXPECT_EQ(fem::energy_density(Material::StVK, mu, lambda, Mat3::Identity()), 0.0);
  EXPECT_EQ(fem::energy_density(Material::Linear, mu, lambda, Mat3::Identity()), 0.0);
  EXPECT_NEAR(fem::energy_density(Material::StableNeoHookean, mu, lambda, Mat3::Identity()),
              mu * mu / (2.0 * (lambda + mu)), kRoundoff);
  EXPECT_EQ(fem::energy_density(Material::Corotated, mu, lambda, Mat3::Identity()), 0.0);
}

TEST(FemMaterial, EnergyIsRotationInvariantAndStressRotates) {
  // Psi(Q F) = Psi(F) and P(Q F) = Q P(F) for any rotation Q (frame indifference).
  Random rng(4);
  for_each_F(5, [&](Material material, Moduli m, const Mat3& F) -> std::string {
    const Mat3 Q = random_rotation(rng, std::numbers::pi);
    if (material == Material::Linear) return "";  // the small strain is not frame-indifferent
    const double psi = fem::energy_density(material, m.mu, m.lambda, F);
    const double psi_q = fem::energy_density(material, m.mu, m.lambda, Q * F);
    const double scale = (m.mu + m.lambda) * std::max(1.0, F.squaredNorm() * F.squaredNorm());
    if (std::abs(psi_q - psi) > 1e2 * kRoundoff * scale)
      return "Psi(QF) = " + std::to_string(psi_q) + ", Psi(F) = " + std::to_string(psi) +
             ", Q = " + str(Q);
    const Mat3 P = fem::first_piola(material, m.mu, m.lambda, F);
    const Mat3 Pq = fem::first_piola(material, m.mu, m.lambda, Q * F);
    if ((Pq - Q * P).cwiseAbs().maxCoeff() > 1e2 * kRoundoff * scale)
      return "P(QF) != Q P(F), Q = " + str(Q);
    return "";
  });
}

// Linear elasticity with (mu, lambda): sigma(H) = mu (H + H^T) + lambda tr(H) I.
Mat3 linear_stress(double mu, double lambda, const Mat3& H) {
  return mu * (H + H.transpose()) + lambda * H.trace() * Mat3::Identity();
}

TEST(FemMaterial, SmallStrainLimitIsLinearElasticity) {
  // P(I + eps H) = eps sigma(H) + O(eps^2): the error divided by eps^2 stays bounded and shrinks
  // by ~10 per decade of eps (second order), and dP/dF at I is exactly the elasticity tensor.
  Random rng(6);
  for (Material material : kMaterials)
    for (const Moduli& m : kModuli)
      for (int k = 0; k < 50; ++k) {
        const Mat3 H = random_matrix(rng, -1, 1);
        const double k_mod = m.mu + m.lambda;
        double err[2];
        const double eps[2] = {1e-3, 1e-4};
        for (int i = 0; i < 2; ++i)
          err[i] = (fem::first_piola(material, m.mu, m.lambda, Mat3::Identity() + eps[i] * H) -
                    eps[i] * linear_stress(m.mu, m.lambda, H))
                       .norm();
        // |O(eps^2)| <= (a few) (mu + lambda) |H|^2 eps^2 with the H drawn here (|H| <= 3).
        EXPECT_LE(err[0], 10.0 * k_mod * H.squaredNorm() * eps[0] * eps[0])
            << to_string(material) << ", mu = " << m.mu << ", lambda = " << m.lambda << ", H = " << str(H);
        // Second order: err(1e-4) / err(1e-3) ~ 1e-2; 3e-2 leaves room for rounding in err(1e-4).
        EXPECT_LE(err[1], 3e-2 * err[0] + 1e-13 * k_mod)
            << to_string(material) << ": not second order, H = " << str(H);
        const Mat9 A = fem::stress_derivative(material, m.mu, m.lambda, Mat3::Identity());
        const Eigen::Matrix<double, 9, 1> dP = A * Eigen::Map<const Eigen::Matrix<double, 9, 1>>(H.data());
        const Mat3 sigma = linear_stress(m.mu, m.lambda, H);
        EXPECT_LE((Eigen::Map<const Mat3>(dP.data()) - sigma).cwiseAbs().maxCoeff(),
                  kRoundoff * 10.0 * k_mod)
            << to_string(material) << ": dP/dF(I) H != sigma(H), H = " << str(H);
      }
}

TEST(FemMaterial, CorotatedStressDerivativeIsFiniteForCrushedElements) {
  // At F of rank 1 two singular values are 0: the polar rotation is not differentiable there and
  // the guard on sigma_i + sigma_j keeps dP/dF finite.
  const Mat3 F = Vec3(1.0, 1e-14, 0.0).asDiagonal();
  const Mat9 A = fem::stress_derivative(Material::Corotated, 1.0, 1.0, F);
  EXPECT_TRUE(A.allFinite()) << A;
  EXPECT_TRUE(fem::first_piola(Material::Corotated, 1.0, 1.0, F).allFinite());
}

// ---------------------------------------------------------------------------------------------
// Elements.

// A random positively oriented rest tet with edges of order 1 m (volume at least 1e-2 m^3) and
// the given material.
FemElement random_element(Random& rng, Material material, Moduli m, Points& rest) {
  rest.resize(4, 3);
  for (;;) {
    for (int i = 0; i < 4; ++i) rest.row(i) = rng.vec(-1, 1).transpose();
    Mat3 Dm;
    for (int k = 0; k < 3; ++k) Dm.col(k) = (rest.row(k + 1) - rest.row(0)).transpose();
    double det = Dm.determinant();
    if (std::abs(det) < 6e-2) continue;
    if (det < 0.0) {  // swap vertices 1 and 2
      rest.row(1).swap(rest.row(2));
      Dm.col(0).swap(Dm.col(1));
      det = -det;
    }
    FemElement e;
    e.particles = {0, 1, 2, 3};
    e.rest_inverse = Dm.inverse();
    e.rest_volume = det / 6.0;
    e.material = material;
    e.mu = m.mu;
    e.lambda = m.lambda;
    return e;
  }
}

// Current positions x = F X + b for a random F of the category (the element's F is then exactly
// F), plus translation.
Points deform(Random& rng, const Points& rest, Category c) {
  const Mat3 F = random_F(rng, c);
  const Vec3 b = rng.vec(-2, 2);
  Points x(4, 3);
  for (int i = 0; i < 4; ++i) x.row(i) = (F * rest.row(i).transpose() + b).transpose();
  return x;
}

constexpr int kRandomElements = 60;  // per category, material and moduli

// The five-point central difference of f along coordinate i of x (row i / 3, column i % 3):
// (-f(x + 2h) + 8 f(x + h) - 8 f(x - h) + f(x - 2h)) / (12 h), h = kXStep. Its truncation error
// h^4 f^(5) / 30 vanishes for the polynomial energies (StVK is quartic, linear quadratic), where the
// three-point difference's h^2 f''' / 6 reaches ~1e-8 on the skinniest random tets (|Dm^-1| ~ 20).
template <class F>
auto five_point(F&& f, const Points& x, int i) {
  auto at = [&](double step) {
    Points y = x;
    y(i / 3, i % 3) += step;
    return f(y);
  };
  return ((at(-2.0 * kXStep) - at(2.0 * kXStep)) + 8.0 * (at(kXStep) - at(-kXStep))) / (12.0 * kXStep);
}

void for_each_element(std::uint64_t seed,
                      const std::function<std::string(const FemElement&, const Points&)>& check) {
  Random rng(seed);
  int failures = 0;
  for (Material material : kMaterials)
    for (const Moduli& m : kModuli)
      for (Category c : kCategories)
        for (int k = 0; k < kRandomElements; ++k) {
          Points rest;
          const FemElement e = random_element(rng, material, m, rest);
          const Points x = deform(rng, rest, c);
          const std::string what = check(e, x);
          if (!what.empty()) {
            std::ostringstream s;
            s.precision(17);
            s << to_string(material) << ", mu = " << m.mu << ", lambda = " << m.lambda << ", "
              << name(c) << " #" << k << ": " << what << "; rest = [" << rest << "], x = [" << x << "]";
            ADD_FAILURE() << s.str();
            if (++failures >= 5) return;
          }
        }
}

TEST(FemElement, GradientMatchesFiniteDifferencesOfEnergy) {
  reset_measured();
  for_each_element(7, [](const FemElement& e, const Points& x) -> std::string {
    const Vec12 g = fem::element_gradient(e, x);
    Vec12 fd;
    for (int i = 0; i < 12; ++i)
      fd(i) = five_point([&](const Points& y) { return fem::element_energy(e, y); }, x, i);
    Eigen::Index at = 0;
    if (worst(g, fd, kElementTol, std::max(g.cwiseAbs().maxCoeff(), e.mu * e.rest_volume), &at) <= 1.0)
      return "";
    return "gradient(" + std::to_string(at) + ") = " + std::to_string(g(at)) +
           ", central difference " + std::to_string(fd(at));
  });
  print_measured();
}

TEST(FemElement, HessianMatchesFiniteDifferencesOfGradient) {
  reset_measured();
  for_each_element(8, [](const FemElement& e, const Points& x) -> std::string {
    const Mat12 H = fem::element_hessian(e, x);
    Mat12 fd;
    for (int j = 0; j < 12; ++j)
      fd.col(j) = five_point([&](const Points& y) { return fem::element_gradient(e, y); }, x, j);
    Eigen::Index at = 0;
    if (worst(H, fd, kElementTol, std::max(H.cwiseAbs().maxCoeff(), e.mu * e.rest_volume), &at) <= 1.0)
      return "";
    return "Hessian(" + std::to_string(at % 12) + ", " + std::to_string(at / 12) + ") = " +
           std::to_string(H(at)) + ", central difference " + std::to_string(fd(at));
  });
  print_measured();
}

TEST(FemElement, GradientConservesMomentum) {
  // An internal force: the vertex forces sum to zero, and so do their torques (not for linear
  // elasticity, whose stress is not frame-indifferent: its forces balance, their torques do not).
  for_each_element(9, [](const FemElement& e, const Points& x) -> std::string {
    const Vec12 g = fem::element_gradient(e, x);
    Vec3 force = Vec3::Zero(), torque = Vec3::Zero();
    double scale = 0.0;
    for (int i = 0; i < 4; ++i) {
      force += g.segment<3>(3 * i);
      torque += Vec3(x.row(i)).cross(g.segment<3>(3 * i));
      scale += g.segment<3>(3 * i).norm() * (1.0 + x.row(i).norm());
    }
    if (force.norm() > kRoundoff * 10.0 * scale) return "sum of forces " + test::str(force);
    if (e.material == Material::Linear) return "";
    if (torque.norm() > kRoundoff * 10.0 * scale) return "sum of torques " + test::str(torque);
    return "";
  });
}

TEST(FemElement, RestStateHasZeroEnergyAndForce) {
  Random rng(10);
  for (Material material : kMaterials)
    for (const Moduli& m : kModuli)
      for (int k = 0; k < 20; ++k) {
        Points rest;
        const FemElement e = random_element(rng, material, m, rest);
        // A rigid motion of the rest shape is a rest state too.
        const Mat3 Q = random_rotation(rng, std::numbers::pi);
        const Vec3 b = rng.vec(-2, 2);
        Points x(4, 3);
        for (int i = 0; i < 4; ++i) x.row(i) = (Q * rest.row(i).transpose() + b).transpose();
        const double scale = (m.mu + m.lambda) * e.rest_volume;
        EXPECT_LE(std::abs(fem::element_energy(e, rest)), kRoundoff * scale) << to_string(material);
        if (material == Material::Linear) {  // a translation only: the small strain sees rotations
          for (int i = 0; i < 4; ++i) x.row(i) = rest.row(i) + b.transpose();
        }
        EXPECT_LE(std::abs(fem::element_energy(e, x)), 1e2 * kRoundoff * scale) << to_string(material);
        EXPECT_LE(fem::element_gradient(e, x).cwiseAbs().maxCoeff(), 1e2 * kRoundoff * scale)
            << to_string(material);
      }
}

double min_eigenvalue(const Mat12& H) {
  return Eigen::SelfAdjointEigenSolver<Mat12>(H, Eigen::EigenvaluesOnly).eigenvalues()(0);
}

TEST(FemElement, ProjectedHessianIsPsdAndExactWhenPsd) {
  int indefinite = 0, definite = 0;
  for_each_element(11, [&](const FemElement& e, const Points& x) -> std::string {
    const Mat12 H = fem::element_hessian(e, x);
    const Mat12 Hp = fem::element_hessian(e, x, true);
    const double scale = H.cwiseAbs().maxCoeff();
    // Eigenvalues of a symmetric 12 x 12 to ~1e-14 of its largest entry.
    const double tiny = 1e-12 * scale;
    if (!(min_eigenvalue(Hp) >= -tiny)) return "projected Hessian has eigenvalue " + std::to_string(min_eigenvalue(Hp));
    // The projection only raises the negative eigenvalues: Hp - H is PSD, and Hp = H when H is.
    if (!(min_eigenvalue(Hp - H) >= -tiny)) return "Hp - H is not PSD";
    // Its eigenvalues are those of H clamped at 0 (both sorted in increasing order).
    const Vec12 clamped = Eigen::SelfAdjointEigenSolver<Mat12>(H, Eigen::EigenvaluesOnly).eigenvalues().cwiseMax(0.0);
    const Vec12 projected = Eigen::SelfAdjointEigenSolver<Mat12>(Hp, Eigen::EigenvaluesOnly).eigenvalues();
    if ((projected - clamped).cwiseAbs().maxCoeff() > 10.0 * tiny)
      return "the projection's eigenvalues are not those of H clamped at 0";
    if (min_eigenvalue(H) >= -tiny) {
      ++definite;
      if ((Hp - H).cwiseAbs().maxCoeff() > 10.0 * tiny) return "H is PSD but the projection changed it";
    } else {
      ++indefinite;
      if ((Hp - H).cwiseAbs().maxCoeff() <= 10.0 * tiny) return "H is indefinite but the projection left it";
    }
    return "";
  });
  // Both branches were exercised (compression makes the Hessian indefinite, rest states do not).
  EXPECT_GT(indefinite, 0);
  EXPECT_GT(definite, 0);
}

TEST(FemElement, RestHessianIsLinearElasticStiffness) {
  // At rest the Hessian is the linear-elastic stiffness V0 B^T C B: its quadratic form on a
  // displacement u = H X is V0 (mu |H + H^T|^2 / 2 + lambda tr(H)^2), for both materials.
  Random rng(12);
  for (Material material : kMaterials)
    for (const Moduli& m : kModuli)
      for (int k = 0; k < 20; ++k) {
        Points rest;
        const FemElement e = random_element(rng, material, m, rest);
        const Mat3 Hd = random_matrix(rng, -1, 1);
        Vec12 u;
        for (int i = 0; i < 4; ++i) u.segment<3>(3 * i) = Hd * rest.row(i).transpose();
        const double form = u.dot(fem::element_hessian(e, rest) * u);
        const double expected = e.rest_volume * (0.5 * m.mu * (Hd + Hd.transpose()).squaredNorm() +
                                                 m.lambda * Hd.trace() * Hd.trace());
        EXPECT_NEAR(form, expected, 1e-10 * (m.mu + m.lambda) * e.rest_volume * (1.0 + Hd.squaredNorm()))
            << to_string(material) << ", H = " << str(Hd);
      }
}

// ---------------------------------------------------------------------------------------------
// eval_constraint(model, c, x) (core/constraint_functions.hpp) reaches the FEM kinds through
// their element; tested here, beside the elements it needs.

TEST(FemConstraintEval, ModelOverloadHandlesEveryKind) {
  Random rng(13);
  Model m;
  m.rest_positions.resize(4, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.inv_mass.assign(4, 1.0);
  m.radius.assign(4, 0.01);
  fem::add_fem_elements(m, {{0, 1, 2, 3}}, Material::StableNeoHookean, 100.0, 0.3);
  ASSERT_EQ(m.constraint_count(), 2);
  Constraint dist;
  dist.kind = ConstraintKind::Distance;
  dist.particles = {0, 2, -1, -1};
  dist.rest = 0.5;
  m.constraints.push_back(dist);
  Points x = m.rest_positions;
  for (int p = 0; p < 4; ++p) x.row(p) += 0.2 * rng.vec(-1, 1).transpose();
  const FemElement& e = m.elements[0];
  for (const Constraint& c : m.constraints) {
    const ConstraintEval got = eval_constraint(m, c, x);
    ConstraintEval want;
    if (c.kind == ConstraintKind::FemDeviatoric) want = fem::eval_deviatoric(e, x);
    else if (c.kind == ConstraintKind::FemHydrostatic) want = fem::eval_hydrostatic(e, x, c.rest);
    else want = eval_constraint(c, x);
    EXPECT_TRUE(got.valid) << to_string(c.kind);
    EXPECT_EQ(got.C, want.C) << to_string(c.kind);
    for (int i = 0; i < arity(c.kind); ++i)
      EXPECT_EQ(got.grad[static_cast<size_t>(i)], want.grad[static_cast<size_t>(i)]) << to_string(c.kind);
  }
  // The old overload cannot evaluate the FEM kinds; an element index out of range is invalid.
  EXPECT_FALSE(eval_constraint(m.constraints[0], x).valid);
  Constraint bad = m.constraints[1];
  bad.element = 7;
  EXPECT_FALSE(eval_constraint(m, bad, x).valid);
}


// ---------------------------------------------------------------------------------------------
// The StVK triangle: a 2D element of the xy plane, F stored as 3 x 2 with a zero third row
// (plane strain).

using fem::Mat32;
using fem::Mat6;

// The 2D StVK density written from its definition: Psi = mu E : E + lambda/2 tr(E)^2 with
// E = (F^T F - I) / 2 (2 x 2).
double stvk_2d_density(double mu, double lambda, const Mat32& F) {
  const Eigen::Matrix2d E = 0.5 * (F.transpose() * F - Eigen::Matrix2d::Identity());
  return mu * E.squaredNorm() + 0.5 * lambda * E.trace() * E.trace();
}

Mat32 random_F32(Random& rng, Category c) {
  // The first two columns of a 3 x 3 F of the category: every stretch, rotation and shear of a
  // membrane in space.
  return random_F(rng, c).leftCols<2>();
}

// A random triangle element with edges of order 1 m (area at least 0.05 m^2) in the plane
// z = const, built by fem::add_fem_triangles; thickness 0.1 m.
FemElement random_triangle(Random& rng, Moduli m, Points& rest) {
  for (;;) {
    rest.resize(3, 3);
    const double z = rng.uniform(-1, 1);
    for (int i = 0; i < 3; ++i) rest.row(i) = Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), z).transpose();
    const double area = 0.5 * Vec3(rest.row(1) - rest.row(0)).cross(Vec3(rest.row(2) - rest.row(0))).norm();
    if (area < 0.05) continue;
    Model model;
    model.rest_positions = rest;
    model.inv_mass.assign(3, 1.0);
    model.radius.assign(3, 0.01);
    fem::add_fem_triangles(model, {{0, 1, 2}}, Material::StVK, 1.0, 0.3, 0.1);
    FemElement e = model.elements[0];
    e.mu = m.mu;  // the moduli under test
    e.lambda = m.lambda;
    return e;
  }
}

TEST(FemTriangle, StressAndDerivativeMatchFiniteDifferences) {
  reset_measured();
  Random rng(31);
  int failures = 0;
  for (const Moduli& m : kModuli)
    for (Category c : kCategories)
      for (int k = 0; k < kRandomF && failures < 5; ++k) {
        const Mat32 F = random_F32(rng, c);
        EXPECT_NEAR(fem::energy_density_2d(Material::StVK, m.mu, m.lambda, F),
                    stvk_2d_density(m.mu, m.lambda, F), kRoundoff * (m.mu + m.lambda) * 1e2);
        const Mat32 P = fem::first_piola_2d(Material::StVK, m.mu, m.lambda, F);
        const Mat6 A = fem::stress_derivative_2d(Material::StVK, m.mu, m.lambda, F);
        Mat32 fdP;
        Mat6 fdA;
        for (int i = 0; i < 6; ++i) {
          Mat32 Fp = F, Fm = F;
          Fp(i) += kFStep;
          Fm(i) -= kFStep;
          fdP(i) = (stvk_2d_density(m.mu, m.lambda, Fp) - stvk_2d_density(m.mu, m.lambda, Fm)) / (2.0 * kFStep);
          const Mat32 d = (fem::first_piola_2d(Material::StVK, m.mu, m.lambda, Fp) -
                           fem::first_piola_2d(Material::StVK, m.mu, m.lambda, Fm)) / (2.0 * kFStep);
          fdA.col(i) = Eigen::Map<const Eigen::Matrix<double, 6, 1>>(d.data());
        }
        const bool ok = worst(P, fdP, kStressTol, m.mu + m.lambda) <= 1.0 &&
                        worst(A, fdA, kStressTol, m.mu + m.lambda) <= 1.0;
        if (!ok) {
          ADD_FAILURE() << name(c) << " #" << k << ": P or dP/dF off its central difference, P = "
                        << P << ", fd " << fdP;
          ++failures;
        }
      }
  print_measured();
  EXPECT_THROW(fem::energy_density_2d(Material::StableNeoHookean, 1.0, 1.0, Mat32::Identity()),
               std::invalid_argument);
}

TEST(FemTriangle, ElementGradientAndHessianMatchFiniteDifferences) {
  reset_measured();
  Random rng(32);
  int failures = 0;
  for (const Moduli& m : kModuli)
    for (Category c : kCategories)
      for (int k = 0; k < kRandomElements && failures < 5; ++k) {
        Points rest;
        const FemElement e = random_triangle(rng, m, rest);
        // Any motion in space: the element reads x and y only, so its forces have no z.
        const Mat3 A = random_F(rng, c);
        const Vec3 b = rng.vec(-2, 2);
        Points x(3, 3);
        for (int i = 0; i < 3; ++i) x.row(i) = (A * rest.row(i).transpose() + b).transpose();
        const Vec12 g = fem::element_gradient(e, x);
        for (int i = 0; i < 3; ++i) EXPECT_EQ(g(3 * i + 2), 0.0);
        const Mat12 H = fem::element_hessian(e, x);
        Vec12 fdg = Vec12::Zero();
        Mat12 fdH = Mat12::Zero();
        for (int i = 0; i < 9; ++i) {
          fdg(i) = five_point([&](const Points& y) { return fem::element_energy(e, y); }, x, i);
          fdH.col(i) = five_point([&](const Points& y) { return fem::element_gradient(e, y); }, x, i);
        }
        const double scale_g = std::max(g.cwiseAbs().maxCoeff(), e.mu * e.rest_volume);
        const double scale_h = std::max(H.cwiseAbs().maxCoeff(), e.mu * e.rest_volume);
        // The absent fourth vertex: zero entries.
        const bool absent = g.tail<3>().isZero() && H.rightCols<3>().isZero() && H.bottomRows<3>().isZero();
        const double wg = worst(g, fdg, kElementTol, scale_g), wh = worst(H, fdH, kElementTol, scale_h);
        if (!absent || wg > 1.0 || wh > 1.0) {
          ADD_FAILURE() << name(c) << " #" << k << ": the gradient (" << wg << " of its tolerance) or "
                        << "Hessian (" << wh << ") of a triangle is off its central difference, or the "
                        << "fourth vertex is not 0 (" << absent << ")";
          ++failures;
        }
        // An internal force: zero sum, and zero torque about z (a 2D element: its forces balance
        // in the plane; it does not see rotations out of the plane).
        Vec3 force = Vec3::Zero(), torque = Vec3::Zero();
        double scale = 0.0;
        for (int i = 0; i < 3; ++i) {
          force += g.segment<3>(3 * i);
          torque += Vec3(x.row(i)).cross(g.segment<3>(3 * i));
          scale += g.segment<3>(3 * i).norm() * (1.0 + x.row(i).norm());
        }
        EXPECT_LE(force.norm(), 10.0 * kRoundoff * scale);
        EXPECT_LE(std::abs(torque.z()), 10.0 * kRoundoff * scale);
      }
  print_measured();
}

TEST(FemTriangle, RestAndRigidMotionsHaveNoEnergyAndTheRestHessianIsPlaneStrain) {
  Random rng(33);
  for (const Moduli& m : kModuli)
    for (int k = 0; k < 20; ++k) {
      Points rest;
      const FemElement e = random_triangle(rng, m, rest);
      // A rigid motion in the plane (and any shift in z, which the element does not see).
      const Mat3 Q = Eigen::AngleAxisd(rng.uniform(-std::numbers::pi, std::numbers::pi), Vec3::UnitZ())
                         .toRotationMatrix();
      const Vec3 b = rng.vec(-2, 2);
      Points x(3, 3);
      for (int i = 0; i < 3; ++i) x.row(i) = (Q * rest.row(i).transpose() + b).transpose();
      const double scale = (m.mu + m.lambda) * e.rest_volume;
      EXPECT_LE(std::abs(fem::element_energy(e, x)), 1e2 * kRoundoff * scale);
      EXPECT_LE(fem::element_gradient(e, x).cwiseAbs().maxCoeff(), 1e2 * kRoundoff * scale);
      // In-plane displacements u = H X (H in the rest plane's basis) have the plane-strain
      // quadratic form V0 (mu |H + H^T|^2 / 2 + lambda tr(H)^2).
      const Vec3 t1 = Vec3(rest.row(1) - rest.row(0)).normalized();
      const Vec3 n = Vec3(rest.row(1) - rest.row(0)).cross(Vec3(rest.row(2) - rest.row(0))).normalized();
      const Vec3 t2 = n.cross(t1);
      Eigen::Matrix2d Hd;
      Hd << rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1);
      Vec12 u = Vec12::Zero();
      for (int i = 0; i < 3; ++i) {
        const Vec3 X = rest.row(i).transpose();
        const Eigen::Vector2d local(t1.dot(X), t2.dot(X));
        const Eigen::Vector2d d = Hd * local;
        u.segment<3>(3 * i) = d(0) * t1 + d(1) * t2;
      }
      const double form = u.dot(fem::element_hessian(e, rest) * u);
      const double expected = e.rest_volume * (0.5 * m.mu * (Hd + Hd.transpose()).squaredNorm() +
                                               m.lambda * Hd.trace() * Hd.trace());
      EXPECT_NEAR(form, expected, 1e-10 * scale * (1.0 + Hd.squaredNorm()));
    }
}

}  // namespace
}  // namespace pbdbench
