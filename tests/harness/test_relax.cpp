// harness/relax.hpp: the rest values an initial state has, and their blend towards the model's.
#include "harness/relax.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/constraint_functions.hpp"

namespace pbdbench {
namespace {

// A unit tet (0,0,0), (1,0,0), (0,1,0), (0,0,1) with a distance constraint on its edge 0-1, a
// volume constraint, and a bending constraint on the hinge 0-1 with wings 2 and 3 (a right angle).
Model tet_model() {
  Model m;
  m.rest_positions.resize(4, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.inv_mass.assign(4, 1.0);
  m.radius.assign(4, 0.01);
  m.group_names = {"all"};
  Constraint d;
  d.kind = ConstraintKind::Distance;
  d.particles = {0, 1, -1, -1};
  d.rest = 0.75;
  Constraint v;
  v.kind = ConstraintKind::Volume;
  v.particles = {0, 1, 2, 3};
  v.rest = 0.5;
  Constraint b;
  b.kind = ConstraintKind::Bending;
  b.particles = {0, 1, 2, 3};
  b.rest = std::numbers::pi;
  Constraint f;
  f.kind = ConstraintKind::FemHydrostatic;
  f.particles = {0, 1, 2, 3};
  f.rest = 1.25;
  m.constraints = {d, v, b, f};
  return m;
}

TEST(Relax, InitialRestValuesAreWhatTheStateSatisfies) {
  const Model m = tet_model();
  Points x = m.rest_positions;
  x(1, 0) = 2.0;  // edge 0-1 of length 2; the tet's volume doubles to 1/3
  const std::vector<double> start = initial_rest_values(m, x);
  ASSERT_EQ(start.size(), 4u);
  EXPECT_DOUBLE_EQ(start[0], 2.0);
  EXPECT_DOUBLE_EQ(start[1], 1.0 / 3.0);
  EXPECT_NEAR(start[2], std::numbers::pi / 2.0, 1e-12);  // the wings are at a right angle
  EXPECT_EQ(start[3], 1.25);  // an FEM kind keeps its own rest: an energy term, not a target
  // A state that satisfies the model gives the model's rest values back.
  Model satisfied = m;
  for (size_t j = 0; j < 3; ++j) satisfied.constraints[j].rest = start[j];
  for (size_t j = 0; j < 3; ++j)
    EXPECT_NEAR(eval_constraint(satisfied.constraints[j], x).C, 0.0, 1e-12) << j;
}

TEST(Relax, BlendGoesLinearlyAndEndsExactlyOnTheModel) {
  const Model m = tet_model();
  const std::vector<double> start = {2.0, 1.0, 0.5, 1.25};
  Model working = m;
  blend_rest_values(m, start, 0.0, working);
  for (size_t j = 0; j < 4; ++j) EXPECT_EQ(working.constraints[j].rest, start[j]) << j;
  blend_rest_values(m, start, 0.25, working);
  EXPECT_DOUBLE_EQ(working.constraints[0].rest, 0.75 * 2.0 + 0.25 * 0.75);
  EXPECT_DOUBLE_EQ(working.constraints[1].rest, 0.75 * 1.0 + 0.25 * 0.5);
  blend_rest_values(m, start, 1.0, working);
  for (size_t j = 0; j < 4; ++j) EXPECT_EQ(working.constraints[j].rest, m.constraints[j].rest) << j;
}

TEST(Relax, SolversThatReadTheModelEveryStep) {
  EXPECT_TRUE(solver_supports_relaxation("pbd"));
  EXPECT_TRUE(solver_supports_relaxation("xpbd"));
  EXPECT_TRUE(solver_supports_relaxation("pbd-seed"));
  EXPECT_FALSE(solver_supports_relaxation("global-cholmod"));
  EXPECT_FALSE(solver_supports_relaxation("ref-bdf"));
}

}  // namespace
}  // namespace pbdbench
