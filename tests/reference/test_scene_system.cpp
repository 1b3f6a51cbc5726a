// Tests of reference/scene_system: force, stiffness, damping and potential consistent with one
// another by finite differences, the time dependence through the kinematic particles, and the
// gather/scatter round trip with the constraint forces in State::lambda.
#include "reference/scene_system.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/constraint_functions.hpp"
#include "tests/reference/energy_fixtures.hpp"

namespace pbdbench {
namespace {

using test::Random;

constexpr int kRandomModels = 15;
constexpr double kTime = 0.61;  // s

Eigen::VectorXd random_u(Random& rng, int n) {
  Eigen::VectorXd u(n);
  for (Eigen::Index i = 0; i < u.size(); ++i) u(i) = rng.uniform(-1, 1);
  return u;
}

TEST(SceneSystem, StiffnessIsMinusForceJacobianWithoutDamping) {
  Random rng(1);
  double worst = 0.0;
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const SceneSystem sys(m);
    ASSERT_FALSE(sys.has_damping());
    const Eigen::VectorXd q = test::random_q(rng, sys.energy(), m);
    const Eigen::VectorXd u = random_u(rng, sys.dofs());
    std::vector<double> values;
    sys.stiffness(kTime, q, u, values);
    const Eigen::MatrixXd K = test::dense(sys.pattern(), values);
    const Eigen::MatrixXd minus_df = -test::fd_jacobian(
        [&](const Eigen::VectorXd& y) {
          Eigen::VectorXd f;
          sys.force(kTime, y, u, f);
          return f;
        },
        q);
    const std::string what = test::compare(K, minus_df, test::kDofTol, &worst);
    EXPECT_TRUE(what.empty()) << "model " << n << ": " << what << "; " << test::str(q);
    // Without damping D is zero and f does not depend on u.
    sys.damping(kTime, q, u, values);
    EXPECT_EQ(test::dense(sys.pattern(), values).cwiseAbs().maxCoeff(), 0.0);
    Eigen::VectorXd f1, f2;
    sys.force(kTime, q, u, f1);
    sys.force(kTime, q, Eigen::VectorXd::Zero(sys.dofs()), f2);
    EXPECT_EQ(f1, f2);
  }
  std::printf("[ measured ] largest |analytic - central difference| / tolerance: %.3g\n", worst);
}

TEST(SceneSystem, ForceIsMinusPotentialGradientWithoutDamping) {
  Random rng(2);
  double worst = 0.0;
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const SceneSystem sys(m);
    const Eigen::VectorXd q = test::random_q(rng, sys.energy(), m);
    Eigen::VectorXd f;
    sys.force(kTime, q, Eigen::VectorXd::Zero(sys.dofs()), f);
    const Eigen::VectorXd minus_grad =
        -test::fd_gradient([&](const Eigen::VectorXd& y) { return sys.potential(kTime, y); }, q);
    const std::string what = test::compare(f, minus_grad, test::kDofTol, &worst);
    EXPECT_TRUE(what.empty()) << "model " << n << ": " << what << "; " << test::str(q);
  }
  std::printf("[ measured ] largest |analytic - central difference| / tolerance: %.3g\n", worst);
}

TEST(SceneSystem, DampingIsMinusForceJacobianInVelocity) {
  Random rng(3);
  double worst = 0.0;
  for (int n = 0; n < kRandomModels; ++n) {
    test::RandomModelOptions o;
    o.damping = true;
    const Model m = test::random_model(rng, o);
    const SceneSystem sys(m);
    ASSERT_TRUE(sys.has_damping());
    const Eigen::VectorXd q = test::random_q(rng, sys.energy(), m);
    const Eigen::VectorXd u = random_u(rng, sys.dofs());
    std::vector<double> values;
    sys.damping(kTime, q, u, values);
    const Eigen::MatrixXd D = test::dense(sys.pattern(), values);
    const Eigen::MatrixXd minus_df = -test::fd_jacobian(
        [&](const Eigen::VectorXd& y) {
          Eigen::VectorXd f;
          sys.force(kTime, q, y, f);
          return f;
        },
        u);
    const std::string what = test::compare(D, minus_df, test::kDofTol, &worst);
    EXPECT_TRUE(what.empty()) << "model " << n << ": " << what;
    // K is the Hessian of U whatever the damping (its q-derivative is left out, as documented).
    std::vector<double> k_values, h_values;
    sys.stiffness(kTime, q, u, k_values);
    Points x;
    sys.energy().positions(q, kTime, x);
    sys.energy().hessian(x, h_values);
    EXPECT_EQ(k_values, h_values);
  }
  std::printf("[ measured ] largest |analytic - central difference| / tolerance: %.3g\n", worst);
}

TEST(SceneSystem, ForceDependsOnTimeThroughTheKinematicTargets) {
  Random rng(4);
  const Model m = test::random_model(rng);
  const SceneSystem sys(m);
  const Eigen::VectorXd q = test::random_q(rng, sys.energy(), m);
  const Eigen::VectorXd u = Eigen::VectorXd::Zero(sys.dofs());
  for (double t : {0.0, 0.25, kTime}) {
    Eigen::VectorXd f, g;
    sys.force(t, q, u, f);
    Points x;
    sys.energy().positions(q, t, x);
    sys.energy().gradient(x, g);
    EXPECT_EQ(f, -g) << "t = " << t;
    EXPECT_EQ(sys.potential(t, q), sys.energy().energy(x)) << "t = " << t;
  }
  Eigen::VectorXd f0, f1;
  sys.force(0.0, q, u, f0);
  sys.force(kTime, q, u, f1);
  EXPECT_GT((f1 - f0).norm(), 0.0) << "the kinematic particles move: f must change with t";
}

TEST(SceneSystem, GatherScatterRoundTrip) {
  Random rng(5);
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const SceneSystem sys(m);
    EXPECT_EQ(sys.dofs(), sys.energy().dofs());
    EXPECT_EQ(&sys.mass(), &sys.energy().mass());
    EXPECT_EQ(&sys.pattern(), &sys.energy().hessian_pattern());
    const Eigen::VectorXd q = test::random_q(rng, sys.energy(), m);
    const Eigen::VectorXd u = random_u(rng, sys.dofs());
    const double sentinel = -777.0;
    State s;
    s.time = 3.0;
    s.step = 42;
    s.lambda.assign(static_cast<size_t>(m.constraint_count()), sentinel);
    sys.scatter(q, u, kTime, s);
    ASSERT_EQ(s.x.rows(), m.particle_count());
    ASSERT_EQ(s.v.rows(), m.particle_count());
    EXPECT_EQ(s.time, 3.0);
    EXPECT_EQ(s.step, 42);
    for (const Attachment& a : m.attachments)
      EXPECT_EQ(Vec3(s.x.row(a.particle)), attachment_target(m, a, kTime));
    Eigen::VectorXd q2, u2;
    sys.gather(s, q2, u2);
    EXPECT_EQ(q2, q);
    EXPECT_EQ(u2, u);
    for (int j = 0; j < m.constraint_count(); ++j) {
      const Constraint& c = m.constraints[static_cast<size_t>(j)];
      const double l = s.lambda[static_cast<size_t>(j)];
      if (is_fem_kind(c.kind) || c.compliance == 0.0) {
        EXPECT_EQ(l, sentinel) << "constraint " << j << " was touched";
      } else {
        const double expected = -eval_constraint(c, s.x).C / c.compliance;
        EXPECT_NEAR(l, expected, 1e-12 * std::abs(expected)) << "constraint " << j;
      }
    }
    // A state whose lambda is empty gets one entry per constraint.
    State fresh;
    sys.scatter(q, u, kTime, fresh);
    EXPECT_EQ(static_cast<int>(fresh.lambda.size()), m.constraint_count());
  }
}

}  // namespace
}  // namespace pbdbench
