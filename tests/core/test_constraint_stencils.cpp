// Tests of core/constraint_stencils.hpp: the angle without acos against std::atan2, the bending
// stencil against the acos kernel it replaced, and the float instantiation against the double one.
// (The double stencils' gradients are checked against finite differences through eval_* in
// test_constraint_functions.cpp and test_fem_constraints.cpp.)
#include "core/constraint_stencils.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/constraint_functions.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using test::Config4;
using test::Random;

V3<double> v3(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
V3<float> v3f(const Vec3& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

// The bending kernel as it was before the stencils (Mueller et al. 2007, appendix A): the angle
// from acos of the normals' dot product, the gradient -grad(n1 . n2) / sqrt(1 - (n1 . n2)^2).
ConstraintEval acos_bending(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                            double rest) {
  ConstraintEval e;
  const Vec3 edge = x1 - x0, a = x2 - x0, b = x3 - x0;
  const Vec3 c1 = edge.cross(a), c2 = edge.cross(b);
  const double l1 = c1.norm(), l2 = c2.norm();
  if (!(l1 > 0.0) || !(l2 > 0.0)) {
    e.C = -rest;
    e.valid = false;
    return e;
  }
  const Vec3 n1 = c1 / l1, n2 = c2 / l2;
  const double d_raw = n1.dot(n2);
  const double d = std::clamp(d_raw, -1.0, 1.0);
  e.C = std::acos(d) - rest;
  const double s2 = 1.0 - d * d;
  if (s2 < 1e-12) {
    e.valid = false;
    return e;
  }
  const Vec3 g1 = (n2 - n1 * d_raw) / l1;
  const Vec3 g2 = (n1 - n2 * d_raw) / l2;
  const double f = -1.0 / std::sqrt(s2);
  e.grad[2] = f * g1.cross(edge);
  e.grad[3] = f * g2.cross(edge);
  e.grad[1] = f * (a.cross(g1) + b.cross(g2));
  e.grad[0] = -(e.grad[1] + e.grad[2] + e.grad[3]);
  return e;
}

TEST(ConstraintStencils, AngleMatchesAtan2ToAFewUlps) {
  // Every octant, both signs of the cosine, and the ends of the range; the reference is glibc's
  // atan2 (correctly rounded or nearly so). The angle is in [0, pi]: a few ulps of pi is 1e-15.
  Random rng(21);
  double worst = 0.0;
  for (int n = 0; n < 200000; ++n) {
    const double theta = n < 100000 ? rng.uniform(0.0, std::numbers::pi)
                                    : (n % 2 ? rng.uniform(0.0, 1e-6) : std::numbers::pi - rng.uniform(0.0, 1e-6));
    const double r = std::exp(rng.uniform(-30.0, 30.0));
    const double s = r * std::sin(theta), c = r * std::cos(theta);
    const double got = angle_from_sin_cos(s, c), want = std::atan2(s, c);
    worst = std::max(worst, std::abs(got - want));
    ASSERT_LE(std::abs(got - want), 1e-15) << "s = " << s << ", c = " << c;
  }
  EXPECT_EQ(angle_from_sin_cos(0.0, 1.0), 0.0);
  EXPECT_EQ(angle_from_sin_cos(0.0, -1.0), std::numbers::pi);
  EXPECT_EQ(angle_from_sin_cos(1.0, 0.0), std::numbers::pi / 2);
  EXPECT_EQ(angle_from_sin_cos(0.0, 0.0), 0.0);
  EXPECT_EQ(angle_from_sin_cos(2.0, 2.0), std::numbers::pi / 4);
  RecordProperty("worst_abs_error", std::to_string(worst));
}

TEST(ConstraintStencils, FloatAngleMatchesAtan2ToAFewFloatUlps) {
  Random rng(22);
  for (int n = 0; n < 100000; ++n) {
    const double theta = rng.uniform(0.0, std::numbers::pi);
    const float s = static_cast<float>(std::sin(theta)), c = static_cast<float>(std::cos(theta));
    const float got = angle_from_sin_cos(s, c);
    const double want = std::atan2(static_cast<double>(s), static_cast<double>(c));
    // A few float ulps of pi (2.4e-7 each).
    ASSERT_LE(std::abs(static_cast<double>(got) - want), 1e-6) << "s = " << s << ", c = " << c;
  }
}

TEST(ConstraintStencils, BendingAgreesWithTheAcosKernelItReplaced) {
  // The same constraint function: C and the gradient agree with the acos kernel wherever both
  // are valid, to what acos itself can resolve (it loses digits as n1 . n2 nears +-1, where the
  // new angle does not).
  Random rng(23);
  int compared = 0;
  for (int n = 0; n < 2000; ++n) {
    Config4 x = {rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1)};
    if (n % 2) {  // near flat: the configurations a cloth solver sees
      x[1] = x[0] + Vec3(1.0, 0.0, 0.0) + rng.vec(-0.1, 0.1);
      x[2] = x[0] + Vec3(0.5, 0.0, 0.8) + rng.vec(-0.1, 0.1);
      x[3] = x[0] + Vec3(0.5, 0.0, -0.8) + rng.vec(-0.1, 0.1);
      x[3].y() = x[0].y() + rng.uniform(1e-3, 1e-1) * (rng.uniform() < 0.5 ? -1.0 : 1.0);
    }
    const double rest = rng.uniform(0.0, std::numbers::pi);
    const ConstraintEval now = eval_bending(x[0], x[1], x[2], x[3], rest);
    const ConstraintEval before = acos_bending(x[0], x[1], x[2], x[3], rest);
    ASSERT_EQ(now.valid, before.valid) << "configuration " << n;
    // acos(d) resolves the angle to eps / sin(theta) (d = cos(theta) is known to eps), and the
    // old gradient, divided by sqrt(1 - d^2), to eps / sin^2(theta) relative: the tolerances are
    // a hundred times those, and never below 1e-12.
    const double sin_theta = std::sin(now.C + rest);
    const double eps = std::numeric_limits<double>::epsilon();
    EXPECT_TRUE(test::near(now.C, before.C, {1e-12 + 100 * eps / sin_theta, 0.0}))
        << "configuration " << n << ", sin(theta) " << sin_theta;
    if (!now.valid) continue;
    ++compared;
    double scale = 0.0;
    for (const Vec3& g : before.grad) scale = std::max(scale, g.norm());
    const double grad_tol = (1e-12 + 100 * eps / (sin_theta * sin_theta)) * scale;
    for (int i = 0; i < 4; ++i)
      EXPECT_LE((now.grad[static_cast<size_t>(i)] - before.grad[static_cast<size_t>(i)]).norm(), grad_tol)
          << "configuration " << n << ", particle " << i << ", sin(theta) " << sin_theta;
  }
  EXPECT_GE(compared, 1950);
}

TEST(ConstraintStencils, BendingHasAFlatRestAngleOfExactlyPi) {
  // A flat sheet in a coordinate plane: V = 0 exactly, so the angle is exactly pi and a
  // constraint built on it (rest = dihedral_angle) has C = 0 at rest.
  const Vec3 x0(0.25, 1.0, 0.5), x1(0.5, 1.0, 0.5), x2(0.375, 1.0, 0.75), x3(0.375, 1.0, 0.25);
  EXPECT_EQ(dihedral_angle(x0, x1, x2, x3), std::numbers::pi);
  EXPECT_EQ(eval_bending(x0, x1, x2, x3, std::numbers::pi).C, 0.0);
}

TEST(ConstraintStencils, FloatStencilsAgreeWithDoubleToFloatPrecision) {
  // The float instantiation is the same function: relative to the size of the terms it agrees
  // with the double one to a few float ulps (1.2e-7 each), amplified by cancellation in C.
  Random rng(24);
  const auto close = [](float a, double b, double scale) {
    return std::abs(static_cast<double>(a) - b) <= 2e-5 * scale;
  };
  for (int n = 0; n < 500; ++n) {
    const Config4 x = {rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1)};
    const double rest = rng.uniform(0.5, 2.5);
    const StencilEval<double> d = bending_stencil(v3(x[0]), v3(x[1]), v3(x[2]), v3(x[3]), rest);
    const StencilEval<float> f = bending_stencil(v3f(x[0]), v3f(x[1]), v3f(x[2]), v3f(x[3]),
                                                 static_cast<float>(rest));
    if (!d.valid || !f.valid) continue;
    double scale = 0.0;
    for (const auto& g : d.grad) scale = std::max({scale, std::abs(g.x), std::abs(g.y), std::abs(g.z)});
    EXPECT_TRUE(close(f.C, d.C, 1.0)) << n;
    for (int i = 0; i < 4; ++i) {
      EXPECT_TRUE(close(f.grad[static_cast<size_t>(i)].x, d.grad[static_cast<size_t>(i)].x, scale)) << n;
      EXPECT_TRUE(close(f.grad[static_cast<size_t>(i)].y, d.grad[static_cast<size_t>(i)].y, scale)) << n;
      EXPECT_TRUE(close(f.grad[static_cast<size_t>(i)].z, d.grad[static_cast<size_t>(i)].z, scale)) << n;
    }
    const StencilEval<double> vd = volume_stencil(v3(x[0]), v3(x[1]), v3(x[2]), v3(x[3]), 0.01);
    const StencilEval<float> vf = volume_stencil(v3f(x[0]), v3f(x[1]), v3f(x[2]), v3f(x[3]), 0.01f);
    EXPECT_TRUE(close(vf.C, vd.C, 1.0)) << n;
  }
}

}  // namespace
}  // namespace pbdbench
