// Tests of core/constraint_functions: gradients against central differences over random
// configurations, the momentum properties of the gradients, and closed-form values.
#include "core/constraint_functions.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

#include <numbers>

#include "core/constraint_values_packed.hpp"
#include "core/fem.hpp"
#include "core/generators.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using test::Config4;
using test::Random;

constexpr int kConfigurations = 400;  // random configurations per constraint kind
// At most this fraction of random configurations may have an undefined gradient (valid = false).
// Random points in a cube almost never land on a singular configuration.
constexpr double kMaxSkippedFraction = 0.01;

using Eval = std::function<ConstraintEval(const Config4&)>;

// Runs the gradient and momentum checks over random configurations drawn by `draw`.
void check_kind(const char* name, const Eval& eval, int arity,
                const std::function<Config4(Random&)>& draw, std::uint64_t seed) {
  Random rng(seed);
  int skipped = 0, failures = 0;
  for (int n = 0; n < kConfigurations; ++n) {
    const Config4 x = draw(rng);
    const ConstraintEval e = eval(x);
    if (!e.valid) {
      ++skipped;
      continue;
    }
    const std::string grad = test::check_gradient(eval, x, arity);
    const std::string momentum = test::check_momentum(e, x, arity);
    if (!grad.empty() || !momentum.empty()) {
      ADD_FAILURE() << name << ", configuration " << n << " (seed " << seed << "): " << grad
                    << (grad.empty() || momentum.empty() ? "" : "; ") << momentum;
      if (++failures >= 5) return;  // enough to diagnose
    }
  }
  EXPECT_LE(skipped, kMaxSkippedFraction * kConfigurations) << name << ": too many invalid configurations";
}

Config4 random_points(Random& rng) {
  return {rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1), rng.vec(-1, 1)};
}

TEST(ConstraintFunctions, DistanceGradientMatchesFiniteDifferences) {
  Random rest_rng(11);
  // The rest length does not change the gradient, but vary it so C takes both signs.
  const Eval eval = [&](const Config4& x) { return eval_distance(x[0], x[1], 0.7); };
  check_kind("distance", eval, 2, random_points, 1);
  for (int n = 0; n < 50; ++n) {
    const double rest = rest_rng.uniform(0.0, 2.0);
    const Config4 x = random_points(rest_rng);
    const ConstraintEval e = eval_distance(x[0], x[1], rest);
    EXPECT_TRUE(test::near(e.C, (x[1] - x[0]).norm() - rest, test::kRoundoff));
  }
}

TEST(ConstraintFunctions, VolumeGradientMatchesFiniteDifferences) {
  const Eval eval = [](const Config4& x) { return eval_volume(x[0], x[1], x[2], x[3], 0.05); };
  check_kind("volume", eval, 4, random_points, 2);
}

TEST(ConstraintFunctions, BendingGradientMatchesFiniteDifferences) {
  const Eval eval = [](const Config4& x) { return eval_bending(x[0], x[1], x[2], x[3], 2.0); };
  check_kind("bending", eval, 4, random_points, 3);
}

TEST(ConstraintFunctions, BendingGradientNearlyFlatMatchesFiniteDifferences) {
  // Near a flat sheet (angle close to pi, the cloth's rest state) but not at it: the wing x3 is
  // lifted by 1e-2 to 1e-1 out of the plane. These are the configurations a cloth solver sees.
  const Eval eval = [](const Config4& x) { return eval_bending(x[0], x[1], x[2], x[3], std::numbers::pi); };
  const auto draw = [](Random& rng) {
    const Vec3 x0 = rng.vec(-1, 1), x1 = x0 + Vec3(1.0, 0.0, 0.0) + rng.vec(-0.1, 0.1);
    const Vec3 x2 = x0 + Vec3(0.5, 0.0, 0.8) + rng.vec(-0.1, 0.1);
    Vec3 x3 = x0 + Vec3(0.5, 0.0, -0.8) + rng.vec(-0.1, 0.1);
    const double lift = rng.uniform(1e-2, 1e-1) * (rng.uniform() < 0.5 ? -1.0 : 1.0);
    x3.y() = x0.y() + lift;
    return Config4{x0, x1, x2, x3};
  };
  check_kind("bending near flat", eval, 4, draw, 4);
}

TEST(ConstraintFunctions, GradientCheckerDetectsAWrongGradient) {
  // The checker itself must be able to fail: a distance gradient with a flipped sign.
  const Eval wrong = [](const Config4& x) {
    ConstraintEval e = eval_distance(x[0], x[1], 0.0);
    e.grad[1] = -e.grad[1];
    return e;
  };
  Random rng(5);
  EXPECT_NE(test::check_gradient(wrong, random_points(rng), 2), "");
  const Eval scaled = [](const Config4& x) {
    ConstraintEval e = eval_volume(x[0], x[1], x[2], x[3], 0.0);
    for (Vec3& g : e.grad) g *= 1.001;
    return e;
  };
  EXPECT_NE(test::check_gradient(scaled, random_points(rng), 4), "");
  ConstraintEval unbalanced = eval_distance(Vec3::Zero(), Vec3::UnitX(), 0.0);
  unbalanced.grad[0] *= 0.5;
  EXPECT_NE(test::check_momentum(unbalanced, {Vec3::Zero(), Vec3::UnitX(), Vec3::Zero(), Vec3::Zero()}, 2), "");
}

TEST(ConstraintFunctions, UnitRightTetHasVolumeOneSixth) {
  const Vec3 o = Vec3::Zero(), ex = Vec3::UnitX(), ey = Vec3::UnitY(), ez = Vec3::UnitZ();
  EXPECT_TRUE(test::near(tet_signed_volume(o, ex, ey, ez), 1.0 / 6.0, test::kRoundoff));
  // Swapping two vertices flips the sign; translating and scaling by 2 multiplies it by 8.
  EXPECT_TRUE(test::near(tet_signed_volume(o, ey, ex, ez), -1.0 / 6.0, test::kRoundoff));
  const Vec3 t(0.3, -2.0, 5.0);
  EXPECT_TRUE(test::near(tet_signed_volume(t, t + 2 * ex, t + 2 * ey, t + 2 * ez), 8.0 / 6.0, test::kRoundoff));
  const ConstraintEval e = eval_volume(o, ex, ey, ez, 0.1);
  EXPECT_TRUE(test::near(e.C, 1.0 / 6.0 - 0.1, test::kRoundoff));
  // grad_1 = (1/6) e2 x e3 = ex / 6 for the unit right tet.
  EXPECT_TRUE(test::near(e.grad[1], ex / 6.0, test::kRoundoff));
  EXPECT_TRUE(test::near(e.grad[0], -(ex + ey + ez) / 6.0, test::kRoundoff));
}

TEST(ConstraintFunctions, DihedralAngleOfKnownConfigurations) {
  // Edge along z; wings along x and y: the normals are +y and -x, 90 degrees apart.
  const Vec3 x0 = Vec3::Zero(), x1 = Vec3::UnitZ();
  EXPECT_TRUE(test::near(dihedral_angle(x0, x1, Vec3::UnitX(), Vec3::UnitY()), std::numbers::pi / 2,
                         test::kRoundoff));
  // Wings at 60 degrees about the edge: (1, 0, 0) and (cos 60, sin 60, 0).
  const Vec3 w(0.5, std::sqrt(3.0) / 2.0, 0.0);
  EXPECT_TRUE(test::near(dihedral_angle(x0, x1, Vec3::UnitX(), w), std::numbers::pi / 3, test::kRoundoff));
  // Flat and unfolded: the wings on opposite sides make pi.
  EXPECT_TRUE(test::near(dihedral_angle(x0, x1, Vec3::UnitX(), -Vec3::UnitX()), std::numbers::pi, test::kRoundoff));
  // The bending constraint at 90 degrees, rest 1: C = pi/2 - 1, gradient defined.
  const ConstraintEval e = eval_bending(x0, x1, Vec3::UnitX(), Vec3::UnitY(), 1.0);
  EXPECT_TRUE(e.valid);
  EXPECT_TRUE(test::near(e.C, std::numbers::pi / 2 - 1.0, test::kRoundoff));
  // Turning a wing about the edge changes the angle at the rate 1 / (its distance to the edge):
  // x2 = (1, 0, 0), at distance 1, moved along +y turns towards x3 = (0, 1, 0) and closes the
  // angle, so dC/dx2 = (0, -1, 0).
  EXPECT_TRUE(test::near(e.grad[2], Vec3(0.0, -1.0, 0.0), test::kRoundoff));
}

TEST(ConstraintFunctions, BendingIsInvalidAtExactlyFlatOrFolded) {
  const Vec3 x0 = Vec3::Zero(), x1 = Vec3::UnitZ();
  const ConstraintEval flat = eval_bending(x0, x1, Vec3::UnitX(), -Vec3::UnitX(), std::numbers::pi);
  EXPECT_FALSE(flat.valid);
  EXPECT_TRUE(test::near(flat.C, 0.0, test::kRoundoff));
  const ConstraintEval folded = eval_bending(x0, x1, Vec3::UnitX(), 2.0 * Vec3::UnitX(), 0.0);
  EXPECT_FALSE(folded.valid);
  // A degenerate wing (on the edge line) has no normal.
  EXPECT_FALSE(eval_bending(x0, x1, 0.5 * Vec3::UnitZ(), Vec3::UnitX(), 1.0).valid);
  // Coincident distance endpoints have no direction.
  EXPECT_FALSE(eval_distance(Vec3::Ones(), Vec3::Ones(), 1.0).valid);
}

TEST(ConstraintFunctions, EvalConstraintDispatchesOnTheModelIndices) {
  Points x(6, 3);
  Random rng(6);
  for (int i = 0; i < 6; ++i) x.row(i) = rng.vec(-1, 1).transpose();
  const auto row = [&](int i) { return Vec3(x.row(i)); };
  Constraint d;
  d.kind = ConstraintKind::Distance;
  d.particles = {4, 1, -1, -1};
  d.rest = 0.3;
  EXPECT_EQ(eval_constraint(d, x).C, eval_distance(row(4), row(1), 0.3).C);
  Constraint v;
  v.kind = ConstraintKind::Volume;
  v.particles = {5, 0, 3, 2};
  v.rest = -0.01;
  EXPECT_EQ(eval_constraint(v, x).C, eval_volume(row(5), row(0), row(3), row(2), -0.01).C);
  Constraint b;
  b.kind = ConstraintKind::Bending;
  b.particles = {2, 3, 0, 5};
  b.rest = 1.0;
  const ConstraintEval eb = eval_constraint(b, x), direct = eval_bending(row(2), row(3), row(0), row(5), 1.0);
  EXPECT_EQ(eb.C, direct.C);
  for (int k = 0; k < 4; ++k) EXPECT_EQ(eb.grad[static_cast<size_t>(k)], direct.grad[static_cast<size_t>(k)]);
}

TEST(ConstraintFunctions, ConstraintValuesAreEvalConstraintBitForBit) {
  // A cloth (distance, bending) and a tet block with FEM elements (distance, volume, the FEM
  // kinds), moved at random: constraint_values gives each C that eval_constraint gives, the same
  // bits, whether it evaluates a constraint alone or beside neighbours of its kind, in the
  // widest packs this processor has and in 16-byte packs.
  Model m;
  ClothSpec cloth;
  cloth.nx = cloth.ny = 9;
  add_cloth(m, cloth);
  TetBlockSpec block;
  block.origin = Vec3(0.0, 2.0, 0.0);
  const int first_tet = static_cast<int>(m.tets.size());
  add_tet_block(m, block);
  std::vector<std::array<int, 4>> tets(m.tets.begin() + first_tet, m.tets.end());
  fem::add_fem_elements(m, tets, Material::StableNeoHookean, 1e6, 0.3);
  Random rng(31);
  Points x = m.rest_positions;
  for (Eigen::Index i = 0; i < x.rows(); ++i) x.row(i) += 0.02 * rng.vec(-1, 1).transpose();
  std::vector<double> values;
  constraint_values(m, x, values);
  ASSERT_EQ(values.size(), m.constraints.size());
  int kinds = 0;
  for (size_t j = 0; j < m.constraints.size(); ++j) {
    EXPECT_EQ(values[j], eval_constraint(m, m.constraints[j], x).C) << "constraint " << j;
    kinds |= 1 << static_cast<int>(m.constraints[j].kind);
  }
  EXPECT_EQ(kinds, 31);  // all five kinds were compared
  std::vector<double> narrow;
  constraint_values_sse2(m, x, narrow);
  ASSERT_EQ(narrow.size(), values.size());
  for (size_t j = 0; j < values.size(); ++j) EXPECT_EQ(narrow[j], values[j]) << "constraint " << j;
  // Runs of every length from 1 to 9 (a kind changes after each), so that every width meets
  // runs shorter than, equal to and longer than its packs.
  Model runs = m;
  runs.constraints.clear();
  size_t next_distance = 0, next_bending = 0;
  std::vector<const Constraint*> distances, bendings;
  for (const Constraint& c : m.constraints) {
    if (c.kind == ConstraintKind::Distance) distances.push_back(&c);
    if (c.kind == ConstraintKind::Bending) bendings.push_back(&c);
  }
  for (int length = 1; length <= 9; ++length)
    for (int k = 0; k < length; ++k) {
      runs.constraints.push_back(*distances[next_distance++ % distances.size()]);
      if (k + 1 == length) runs.constraints.push_back(*bendings[next_bending++ % bendings.size()]);
    }
  constraint_values(runs, x, values);
  constraint_values_sse2(runs, x, narrow);
  // Runs built once give the same values; runs of another model are refused.
  const ConstraintRuns built = constraint_runs(runs);
  EXPECT_EQ(built.runs.size(), 18u);  // 9 runs of distance constraints, each followed by one bending
  std::vector<double> from_built;
  constraint_values(built, runs, x, from_built);
  EXPECT_EQ(from_built, values);
  EXPECT_THROW(constraint_values(built, m, x, from_built), std::invalid_argument);
  for (size_t j = 0; j < runs.constraints.size(); ++j) {
    EXPECT_EQ(values[j], eval_constraint(runs, runs.constraints[j], x).C) << "run constraint " << j;
    EXPECT_EQ(narrow[j], values[j]) << "run constraint " << j;
  }
  // Each width called directly, 32- and 64-byte packs too (the compiler lowers them where the
  // processor lacks them, so the gathering of every width is checked on any processor): the
  // same bits as eval_constraint, alone and in the runs of every length.
  for (const Model* model : {&m, &runs}) {
    const ConstraintRuns cr = constraint_runs(*model);
    detail::RunsView view;
    view.runs = cr.runs.data();
    view.count = cr.runs.size();
    for (size_t i = 0; i < 4; ++i) view.particle[i] = cr.particle[i].data();
    view.rest = cr.rest.data();
    view.constraints = model->constraints.data();
    const size_t count = model->constraints.size();
    std::vector<double> w2(count, -1.0), w4(count, -1.0), w8(count, -1.0);
    detail::constraint_values_packed<Pack<double, 16>>(*model, x, x.data(), view, w2.data());
    detail::constraint_values_packed<Pack<double, 32>>(*model, x, x.data(), view, w4.data());
    detail::constraint_values_packed<Pack<double, 64>>(*model, x, x.data(), view, w8.data());
    for (size_t j = 0; j < count; ++j) {
      const double C = eval_constraint(*model, model->constraints[j], x).C;
      EXPECT_EQ(w2[j], C) << "2 lanes, constraint " << j;
      EXPECT_EQ(w4[j], C) << "4 lanes, constraint " << j;
      EXPECT_EQ(w8[j], C) << "8 lanes, constraint " << j;
    }
  }
}

TEST(ConstraintFunctions, NormalizedErrorIsRelativeForLengthsAndVolumes) {
  Constraint d;
  d.kind = ConstraintKind::Distance;
  d.rest = 2.0;
  EXPECT_TRUE(test::near(normalized_error(d, -0.1), 0.05, test::kRoundoff));
  d.rest = 0.0;
  EXPECT_TRUE(test::near(normalized_error(d, -0.1), 0.1, test::kRoundoff));
  Constraint v;
  v.kind = ConstraintKind::Volume;
  v.rest = -0.5;  // an inverted rest volume still normalises by its magnitude
  EXPECT_TRUE(test::near(normalized_error(v, 0.1), 0.2, test::kRoundoff));
  Constraint b;
  b.kind = ConstraintKind::Bending;
  b.rest = std::numbers::pi;
  EXPECT_TRUE(test::near(normalized_error(b, -0.25), 0.25, test::kRoundoff));
  EXPECT_STREQ(to_string(ConstraintKind::Distance), "distance");
  EXPECT_STREQ(to_string(ConstraintKind::Volume), "volume");
  EXPECT_STREQ(to_string(ConstraintKind::Bending), "bending");
  EXPECT_EQ(arity(ConstraintKind::Distance), 2);
  EXPECT_EQ(arity(ConstraintKind::Volume), 4);
  EXPECT_EQ(arity(ConstraintKind::Bending), 4);
}

}  // namespace
}  // namespace pbdbench
