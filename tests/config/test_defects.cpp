// [defects] and [relax] (config/scenes.cpp, apply_defects; config/schema.cpp): each defect does
// what its key says on the scene it is applied to, and every refusal names its key.
#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "core/constraint_functions.hpp"
#include "core/model_checks.hpp"
#include "tests/config/helpers.hpp"

namespace pbdbench::config {
namespace {

using testing::load_error;
using testing::sets;

// Rest lengths and positions from a few products of short decimals: a few ulps of the metre.
constexpr double kTol = 1e-12;

Scene build(const std::string& text, const std::vector<std::string>& overrides = {}) {
  return build_scene(load_text(text, "defects.toml", sets(overrides)));
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A horizontal chain of 4 links of 0.5 m, pinned at its top (particle 0).
const char* kChain = R"(
[scene]
kind = "chain"
top = [0.0, 1.0, 0.0]
links = 4
link_length = 0.5
angle_deg = 90.0
)";

// A 3 x 3 cloth (12 stretch, 8 shear, 8 dihedral bending constraints), pinned at its top corners.
const char* kCloth = R"(
[scene]
kind = "cloth"
resolution = [3, 3]
size = [1.0, 1.0]
pins = "top_corners"
)";

const char* kBlock = R"(
[scene]
kind = "tet_block"
cells = [2, 1, 1]
size = [0.2, 0.1, 0.1]
)";

TEST(Defects, NoneByDefault) {
  const Scene plain = build(kCloth);
  const Scene again = build(std::string(kCloth) + "\n[defects]\nrest_scale = 1.0\ninitial_scale = 1.0\n");
  ASSERT_EQ(plain.model.constraints.size(), again.model.constraints.size());
  for (std::size_t j = 0; j < plain.model.constraints.size(); ++j)
    EXPECT_EQ(plain.model.constraints[j].rest, again.model.constraints[j].rest);
  EXPECT_EQ(plain.initial.x, again.initial.x);
  EXPECT_EQ(plain.model.inv_mass, again.model.inv_mass);
}

TEST(Defects, ZeroRestLength) {
  const Scene s = build(kChain, {"defects.zero_rest_length=[1, 3]"});
  ASSERT_EQ(s.model.constraints.size(), 4u);
  EXPECT_EQ(s.model.constraints[0].rest, 0.5);
  EXPECT_EQ(s.model.constraints[1].rest, 0.0);
  EXPECT_EQ(s.model.constraints[2].rest, 0.5);
  EXPECT_EQ(s.model.constraints[3].rest, 0.0);
  // The initial state is untouched: the links start stretched by their whole length.
  EXPECT_NEAR(eval_constraint(s.model.constraints[1], s.initial.x).C, 0.5, kTol);
}

TEST(Defects, ZeroRestLengthRefusesOtherKindsAndIndicesOutOfRange) {
  // Constraint 20 of the cloth is a bending constraint (12 stretch, 8 shear, then bending).
  const Scene cloth = build(kCloth);
  ASSERT_EQ(cloth.model.constraints[20].kind, ConstraintKind::Bending);
  ConfigError e = load_error(std::string(kCloth) + "\n[defects]\nzero_rest_length = [0, 20]\n");
  EXPECT_EQ(e.key(), "defects.zero_rest_length");
  EXPECT_EQ(e.source().line, 9);
  EXPECT_TRUE(contains(e.what(), "bending constraint, not a distance constraint")) << e.what();
  e = load_error(kChain, "c.toml", sets({"defects.zero_rest_length=[4]"}));
  EXPECT_EQ(e.key(), "defects.zero_rest_length");
  EXPECT_TRUE(contains(e.what(), "out of range: the scene has 4 constraints")) << e.what();
  e = load_error(kChain, "c.toml", sets({"defects.zero_rest_length=[-1]"}));
  EXPECT_EQ(e.key(), "defects.zero_rest_length");
}

TEST(Defects, RestScaleOfEveryDistanceConstraintOrOfAList) {
  const Scene plain = build(kCloth);
  const Scene all = build(kCloth, {"defects.rest_scale=100"});
  for (std::size_t j = 0; j < plain.model.constraints.size(); ++j) {
    const Constraint& c = plain.model.constraints[j];
    const double expected = c.kind == ConstraintKind::Distance ? 100.0 * c.rest : c.rest;
    EXPECT_EQ(all.model.constraints[j].rest, expected) << j;
  }
  // A constraint listed twice is scaled once.
  const Scene some = build(kCloth, {"defects.rest_scale=0.5", "defects.rest_scale_constraints=[13, 2, 13]"});
  for (std::size_t j = 0; j < plain.model.constraints.size(); ++j) {
    const double r = plain.model.constraints[j].rest;
    EXPECT_EQ(some.model.constraints[j].rest, j == 2 || j == 13 ? 0.5 * r : r) << j;
  }
  ConfigError e = load_error(kCloth, "c.toml", sets({"defects.rest_scale_constraints=[21]"}));
  EXPECT_EQ(e.key(), "defects.rest_scale_constraints");
  e = load_error(kCloth, "c.toml", sets({"defects.rest_scale=0"}));
  EXPECT_EQ(e.key(), "defects.rest_scale");
}

TEST(Defects, InverseMassAnyFiniteValueAndThePinGoes) {
  const Scene s = build(kChain, {"defects.inverse_mass_particles=[0, 2, 3]",
                                 "defects.inverse_mass_values=[-1.0, 1e6, 0.0]"});
  EXPECT_EQ(s.model.inv_mass[0], -1.0);
  EXPECT_EQ(s.model.inv_mass[1], 1.0);
  EXPECT_EQ(s.model.inv_mass[2], 1e6);
  EXPECT_EQ(s.model.inv_mass[3], 0.0);
  // Particle 0 was pinned; with a non-zero inverse mass it is not attached any more.
  EXPECT_TRUE(s.model.attachments.empty());
  // The model checks let these through, and only these.
  EXPECT_TRUE(check_model(s.model, {0, 2, 3}).empty());
  ASSERT_EQ(check_model(s.model).size(), 1u);
  EXPECT_TRUE(contains(check_model(s.model)[0].what, "particle 0: inverse mass -1 is negative"));
  // A value of 0 keeps a pin.
  const Scene kept = build(kChain, {"defects.inverse_mass_particles=[0]", "defects.inverse_mass_values=[0.0]"});
  ASSERT_EQ(kept.model.attachments.size(), 1u);
  EXPECT_EQ(kept.model.attachments[0].particle, 0);
}

TEST(Defects, InverseMassRefusals) {
  ConfigError e = load_error(kChain, "c.toml", sets({"defects.inverse_mass_particles=[1, 2]",
                                                      "defects.inverse_mass_values=[3.0]"}));
  EXPECT_EQ(e.key(), "defects.inverse_mass_values");
  EXPECT_TRUE(contains(e.what(), "1 values for the 2 particles")) << e.what();
  e = load_error(kChain, "c.toml", sets({"defects.inverse_mass_particles=[1]"}));
  EXPECT_EQ(e.key(), "defects.inverse_mass_particles");
  e = load_error(kChain, "c.toml", sets({"defects.inverse_mass_particles=[5]", "defects.inverse_mass_values=[1.0]"}));
  EXPECT_EQ(e.key(), "defects.inverse_mass_particles");
  EXPECT_TRUE(contains(e.what(), "out of range: the scene has 5 particles")) << e.what();
  e = load_error(kChain, "c.toml", sets({"defects.inverse_mass_particles=[1, 1]", "defects.inverse_mass_values=[1.0, 2.0]"}));
  EXPECT_EQ(e.key(), "defects.inverse_mass_particles");
  EXPECT_TRUE(contains(e.what(), "repeats a particle")) << e.what();
  for (const char* bad : {"nan", "inf", "-inf"}) {
    e = load_error(std::string(kChain) + "\n[defects]\ninverse_mass_particles = [1]\ninverse_mass_values = [" + bad + "]\n");
    EXPECT_EQ(e.key(), "defects.inverse_mass_values") << bad;
    EXPECT_TRUE(contains(e.what(), "is not a finite number")) << e.what();
  }
  // Without the defect a negative inverse mass stays refused: a negative mass is refused by its
  // key's bounds, and the model checks refuse what the defect did not set.
  e = load_error(kChain, "c.toml", sets({"scene.mass=-1"}));
  EXPECT_EQ(e.key(), "scene.mass");
}

TEST(Defects, FlipTetsSwapsTwoVerticesAndKeepsTheRestVolumePositive) {
  const Scene plain = build(kBlock);
  const std::size_t tets = plain.model.tets.size();
  ASSERT_EQ(tets, 12u);
  const Scene flipped = build(kBlock, {"defects.flip_every=2", "defects.flip_tets=[3]"});
  std::set<int> flipped_tets;
  for (std::size_t j = 0; j < plain.model.constraints.size(); ++j) {
    const Constraint& a = plain.model.constraints[j];
    const Constraint& b = flipped.model.constraints[j];
    if (a.kind != ConstraintKind::Volume) {
      EXPECT_EQ(a.particles, b.particles);
      continue;
    }
    ASSERT_GT(a.rest, 0.0);
    EXPECT_EQ(b.rest, a.rest);
    // At rest the unflipped constraint reads 0 and a flipped one C = -V - V0 = -2 V0.
    const double C = eval_constraint(b, flipped.initial.x).C;
    if (b.particles == a.particles) {
      EXPECT_NEAR(C, 0.0, 1e-15);
      continue;
    }
    EXPECT_EQ(b.particles[0], a.particles[1]);
    EXPECT_EQ(b.particles[1], a.particles[0]);
    EXPECT_EQ(b.particles[2], a.particles[2]);
    EXPECT_EQ(b.particles[3], a.particles[3]);
    EXPECT_NEAR(C, -2.0 * a.rest, 1e-15);
    for (std::size_t t = 0; t < tets; ++t) {
      std::array<int, 4> x = plain.model.tets[t], y = a.particles;
      std::sort(x.begin(), x.end());
      std::sort(y.begin(), y.end());
      if (x == y) flipped_tets.insert(static_cast<int>(t));
    }
  }
  EXPECT_EQ(flipped_tets, (std::set<int>{0, 2, 3, 4, 6, 8, 10}));
  // The tets themselves (and so the volume metrics) keep their orientation.
  EXPECT_EQ(flipped.model.tets, plain.model.tets);
}

TEST(Defects, FlipTetsRefusals) {
  ConfigError e = load_error(kChain, "c.toml", sets({"defects.flip_every=1"}));
  EXPECT_EQ(e.key(), "defects.flip_every");
  EXPECT_TRUE(contains(e.what(), "the chain scene has none")) << e.what();
  e = load_error(kChain, "c.toml", sets({"defects.flip_tets=[0]"}));
  EXPECT_EQ(e.key(), "defects.flip_tets");
  e = load_error(kBlock, "c.toml", sets({"defects.flip_tets=[12]"}));
  EXPECT_EQ(e.key(), "defects.flip_tets");
  EXPECT_TRUE(contains(e.what(), "out of range: the scene has 12 tets")) << e.what();
  e = load_error(kBlock, "c.toml", sets({"scene.volumes=false", "defects.flip_tets=[1]"}));
  EXPECT_EQ(e.key(), "defects.flip_tets");
  EXPECT_TRUE(contains(e.what(), "tet 1 has no volume constraint")) << e.what();
  e = load_error(kBlock, "c.toml", sets({"defects.flip_every=-1"}));
  EXPECT_EQ(e.key(), "defects.flip_every");
}

TEST(Defects, InitialScaleAboutTheCentroidOfTheDynamicParticles) {
  const Scene plain = build(kChain);
  const Scene s = build(kChain, {"defects.initial_scale=1.5"});
  // Dynamic particles 1..4 at x = 0.5, 1.0, 1.5, 2.0 (y = 1): centroid x = 1.25.
  EXPECT_EQ(s.initial.x.row(0), plain.initial.x.row(0));  // pinned: not moved
  for (int i = 1; i <= 4; ++i) {
    EXPECT_NEAR(s.initial.x(i, 0), 1.25 + 1.5 * (0.5 * i - 1.25), kTol) << i;
    EXPECT_NEAR(s.initial.x(i, 1), 1.0, kTol) << i;
    EXPECT_NEAR(s.initial.x(i, 2), 0.0, kTol) << i;
  }
  // The model (rest state, rest lengths) is untouched: the state violates it.
  EXPECT_EQ(s.model.rest_positions, plain.model.rest_positions);
  EXPECT_NEAR(eval_constraint(s.model.constraints[2], s.initial.x).C, 0.25, kTol);
}

TEST(Defects, InitialJitterIsSeededAndBounded) {
  const Scene plain = build(kCloth);
  const Scene a = build(kCloth, {"defects.initial_jitter=0.01", "defects.initial_seed=7"});
  const Scene b = build(kCloth, {"defects.initial_jitter=0.01", "defects.initial_seed=7"});
  const Scene c = build(kCloth, {"defects.initial_jitter=0.01", "defects.initial_seed=8"});
  EXPECT_EQ(a.initial.x, b.initial.x);  // the same seed, the same bits
  EXPECT_NE(a.initial.x, c.initial.x);
  int moved = 0;
  for (int i = 0; i < plain.model.particle_count(); ++i) {
    const bool pinned = plain.model.inv_mass[static_cast<std::size_t>(i)] == 0.0;
    for (int k = 0; k < 3; ++k) {
      const double d = a.initial.x(i, k) - plain.initial.x(i, k);
      if (pinned) {
        EXPECT_EQ(d, 0.0) << i;
      }
      EXPECT_LE(std::abs(d), 0.01) << i;
      moved += d != 0.0;
    }
  }
  EXPECT_EQ(moved, 7 * 3);  // every coordinate of the 7 free particles
  EXPECT_EQ(load_error(kCloth, "c.toml", sets({"defects.initial_jitter=-0.1"})).key(), "defects.initial_jitter");
  EXPECT_EQ(load_error(kCloth, "c.toml", sets({"defects.initial_scale=0"})).key(), "defects.initial_scale");
}

TEST(Defects, RelaxFramesIsAnIntegerAtLeastZero) {
  EXPECT_EQ(load_text(kChain, "c.toml", sets({"relax.frames=8"})).get_int("relax.frames"), 8);
  EXPECT_EQ(load_text(kChain, "c.toml").get_int("relax.frames"), 0);
  EXPECT_EQ(load_error(kChain, "c.toml", sets({"relax.frames=-1"})).key(), "relax.frames");
  EXPECT_EQ(load_error(kChain, "c.toml", sets({"relax.frame=1"})).key(), "relax.frame");
}

TEST(Defects, EveryKindCarriesThem) {
  // A defect of the initial state applies to any scene kind: the particle and the pendulum.
  const Scene p = build("[scene]\nkind = \"particle\"\n", {"defects.initial_jitter=0.5"});
  EXPECT_NE(p.initial.x.row(0).norm(), 0.0);
  const Scene pend = build("[scene]\nkind = \"pendulum\"\n", {"defects.zero_rest_length=[0]"});
  EXPECT_EQ(pend.model.constraints[0].rest, 0.0);
}

}  // namespace
}  // namespace pbdbench::config
