// --set overrides: parsing, paths, collider indices, values, scene.kind, order, and errors.
#include <string>

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "tests/config/helpers.hpp"

namespace pbdbench::config {
namespace {

using testing::load_error;
using testing::sets;

const char* kBase =
    "[scene]\n"                  // 1
    "kind = \"chain\"\n"         // 2
    "links = 4\n"                // 3
    "[solver]\n"                 // 4
    "iterations = 5\n"           // 5
    "[[collider]]\n"             // 6
    "type = \"plane\"\n"         // 7
    "offset = 1.0\n"             // 8
    "[[collider]]\n"             // 9
    "type = \"sphere\"\n"        // 10
    "radius = 0.5\n";            // 11

TEST(ParseOverride, SplitsAtTheFirstEquals) {
  const Override o = parse_override(" name = a=b ");
  EXPECT_EQ(o.path, "name");
  EXPECT_EQ(o.value_text, "a=b");
}

TEST(ParseOverride, RefusesTextWithoutEquals) {
  try {
    (void)parse_override("solver.iterations");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.source().file, "--set solver.iterations");
    EXPECT_EQ(std::string(e.what()),
              "--set solver.iterations: expected --set KEY=VALUE (e.g. --set solver.iterations=20)");
  }
  EXPECT_THROW((void)parse_override("=3"), ConfigError);
}

TEST(Overrides, DottedPathReplacesTheFileValue) {
  const Config c = load_text(kBase, "o.toml", sets({"solver.iterations=12", "solver.pbd.velocity_damping=0.25"}));
  EXPECT_EQ(c.get_int("solver.iterations"), 12);
  EXPECT_EQ(c.at("solver.iterations").source.file, "--set solver.iterations=12");
  EXPECT_EQ(c.at("solver.iterations").source.line, 0);
  EXPECT_EQ(c.get_double("solver.pbd.velocity_damping"), 0.25);
  EXPECT_EQ(c.get_int("scene.links"), 4);  // untouched
  EXPECT_EQ(c.at("scene.links").source.line, 3);
}

TEST(Overrides, ColliderByIndex) {
  const Config c = load_text(kBase, "o.toml", sets({"collider.1.radius=2", "collider.0.friction=0.5"}));
  EXPECT_EQ(std::get<double>(c.colliders[1].at("collider.radius").value), 2.0);
  EXPECT_EQ(c.colliders[1].at("collider.radius").source.file, "--set collider.1.radius=2");
  EXPECT_EQ(std::get<double>(c.colliders[0].at("collider.friction").value), 0.5);
  EXPECT_EQ(std::get<double>(c.colliders[0].at("collider.offset").value), 1.0);
}

TEST(Overrides, ColliderTypeSwitchMakesTheFileKeysInapplicable) {
  const ConfigError e = load_error(kBase, "o.toml", sets({"collider.0.type=sphere"}));
  EXPECT_EQ(e.key(), "collider.0.offset");
  EXPECT_EQ(e.source().line, 8);
}

TEST(Overrides, ColliderIndexMustExist) {
  const ConfigError e = load_error(kBase, "o.toml", sets({"collider.2.radius=1"}));
  EXPECT_EQ(e.source().file, "--set collider.2.radius=1");
  EXPECT_EQ(e.source().line, 0);
  EXPECT_EQ(std::string(e.what()),
            "--set collider.2.radius=1: there is no collider 2: the file declares 2 [[collider]] "
            "entries; to add a collider, declare it in the file");
  EXPECT_THROW((void)load_text(kBase, "o.toml", sets({"collider.x.radius=1"})), ConfigError);
  EXPECT_THROW((void)load_text(kBase, "o.toml", sets({"collider.radius=1"})), ConfigError);
}

TEST(Overrides, UnknownColliderKey) {
  const ConfigError e = load_error(kBase, "o.toml", sets({"collider.1.radus=1"}));
  EXPECT_EQ(std::string(e.what()),
            "--set collider.1.radus=1: unknown key 'collider.1.radus' (did you mean 'collider.1.radius'?)");
}

TEST(Overrides, ArrayValues) {
  const Config c = load_text(kBase, "o.toml",
                             sets({"gravity=[0, -1.62, 0]", "solver.seed.fixes=[\"D2\", \"D4\"]"}));
  EXPECT_EQ(c.get_vec3("gravity"), Vec3(0.0, -1.62, 0.0));
  EXPECT_EQ(c.get_strings("solver.seed.fixes"), (std::vector<std::string>{"D2", "D4"}));
}

TEST(Overrides, BareWordIsAString) {
  const Config c = load_text(kBase, "o.toml", sets({"solver.name=pbd", "solver.order=colored",
                                                    "description=a quick test"}));
  EXPECT_EQ(c.get_string("solver.name"), "pbd");
  EXPECT_EQ(c.get_string("solver.order"), "colored");
  EXPECT_EQ(c.get_string("description"), "a quick test");
  // 2024 is valid TOML (an integer) but `name` is a string: the error names the --set.
  const ConfigError e = load_error(kBase, "o.toml", sets({"name=2024"}));
  EXPECT_EQ(std::string(e.what()), "--set name=2024: name: expected a string, got the integer 2024");
}

TEST(Overrides, QuotedStringValue) {
  const Config c = load_text(kBase, "o.toml", sets({"description=\"with = and # inside\""}));
  EXPECT_EQ(c.get_string("description"), "with = and # inside");
}

TEST(Overrides, SceneKindSwitchesTheKindTable) {
  // The file's scene.links belongs to the chain: switching to a pendulum makes it unknown...
  const ConfigError e = load_error(kBase, "o.toml", sets({"scene.kind=pendulum"}));
  EXPECT_EQ(e.key(), "scene.links");
  EXPECT_EQ(e.source().line, 3);
  EXPECT_EQ(std::string(e.what()),
            "o.toml:3: unknown key 'scene.links' for scene kind 'pendulum': it is a key of scene "
            "kind 'chain' (scene.kind = 'pendulum' here)");
  // ... and without kind-specific keys in the file, the new kind gets its own defaults.
  const std::string plain = "[scene]\nkind = \"chain\"\n";
  const Config c = load_text(plain, "o.toml", sets({"scene.kind=pendulum", "scene.length=2"}));
  EXPECT_EQ(c.get_string("scene.kind"), "pendulum");
  EXPECT_EQ(c.get_double("scene.length"), 2.0);
  EXPECT_FALSE(c.has("scene.links"));
  EXPECT_TRUE(c.has("scene.angle_deg"));
  // A key of the new kind, set before the kind itself: the order does not matter for validity.
  const Config d = load_text(plain, "o.toml", sets({"scene.resolution=[4, 5]", "scene.kind=cloth"}));
  EXPECT_EQ(d.get_ints("scene.resolution"), (std::vector<std::int64_t>{4, 5}));
}

TEST(Overrides, AppliedInOrder) {
  const Config c = load_text(kBase, "o.toml", sets({"solver.iterations=7", "solver.iterations=9"}));
  EXPECT_EQ(c.get_int("solver.iterations"), 9);
  EXPECT_EQ(c.at("solver.iterations").source.file, "--set solver.iterations=9");
  const Config d = load_text(kBase, "o.toml", sets({"solver.iterations=9", "solver.iterations=7"}));
  EXPECT_EQ(d.get_int("solver.iterations"), 7);
}

TEST(Overrides, UnknownKeyNamesTheSet) {
  const ConfigError e = load_error(kBase, "o.toml", sets({"solver.iteratons=3"}));
  EXPECT_EQ(e.source().file, "--set solver.iteratons=3");
  EXPECT_EQ(e.source().line, 0);
  EXPECT_EQ(e.key(), "solver.iteratons");
  EXPECT_EQ(std::string(e.what()),
            "--set solver.iteratons=3: unknown key 'solver.iteratons' (did you mean 'solver.iterations'?)");
}

TEST(Overrides, BadValueNamesTheSet) {
  const ConfigError e = load_error(kBase, "o.toml", sets({"solver.iterations=many"}));
  EXPECT_EQ(e.source().file, "--set solver.iterations=many");
  EXPECT_EQ(e.key(), "solver.iterations");
  EXPECT_EQ(std::string(e.what()),
            "--set solver.iterations=many: solver.iterations: expected an integer, got the string 'many'");
  const ConfigError r = load_error(kBase, "o.toml", sets({"time.dt=-0.1"}));
  EXPECT_EQ(std::string(r.what()), "--set time.dt=-0.1: time.dt = -0.1 s must be greater than 0 s");
  const ConfigError n = load_error(kBase, "o.toml", sets({"time.dt=nan"}));
  EXPECT_EQ(std::string(n.what()), "--set time.dt=nan: time.dt = nan is not a finite number");
}

TEST(Overrides, KeyOfAnotherKindNamesTheSet) {
  const ConfigError e = load_error(kBase, "o.toml", sets({"scene.resolution=[4, 4]"}));
  EXPECT_EQ(e.source().file, "--set scene.resolution=[4, 4]");
  EXPECT_EQ(e.key(), "scene.resolution");
}

}  // namespace
}  // namespace pbdbench::config
