// Loading and validation: every kind of bad input is refused with the file, the line and the key.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "tests/config/helpers.hpp"

namespace pbdbench::config {
namespace {

using testing::load_error;
using testing::TempDir;

// Checks the whole message (file:line: text), the source and the key of an error.
void expect_error(const ConfigError& e, const std::string& file, int line, const std::string& key,
                  const std::string& message) {
  EXPECT_EQ(e.source().file, file);
  EXPECT_EQ(e.source().line, line);
  EXPECT_EQ(e.key(), key);
  const std::string where = line > 0 ? file + ":" + std::to_string(line) + ": " : file + ": ";
  EXPECT_EQ(std::string(e.what()), where + message);
}

// ---------------------------------------------------------------------------------------------
// Good input.

TEST(Load, DefaultsFillEveryKeyOfTheKind) {
  const Config c = load_text("[scene]\nkind = \"particle\"\n", "dir/ball.toml");
  EXPECT_EQ(c.scenario_name, "ball");  // the file stem
  EXPECT_EQ(c.get_string("name"), "ball");
  EXPECT_TRUE(c.at("name").source.file.empty());
  for (const KeySpec& k : common_keys()) EXPECT_TRUE(c.has(k.path)) << k.path;
  for (const KeySpec& k : scene_kinds()[0].keys) EXPECT_TRUE(c.has(k.path)) << k.path;
  EXPECT_EQ(c.entries.size(), common_keys().size() + scene_kinds()[0].keys.size());
  EXPECT_EQ(c.get_int("solver.iterations"), SolverOptions{}.iterations);
  EXPECT_EQ(c.get_vec3("gravity"), Vec3(0.0, -9.81, 0.0));
  EXPECT_EQ(c.at("scene.kind").source.file, "dir/ball.toml");
  EXPECT_EQ(c.at("scene.kind").source.line, 2);
}

TEST(Load, IntegerAcceptedForFloatAndKeptAsDouble) {
  const Config c = load_text("[time]\ndt = 1\nduration = 3\n", "a.toml");
  EXPECT_EQ(c.get_double("time.dt"), 1.0);
  EXPECT_TRUE(std::holds_alternative<double>(c.at("time.dt").value));
  const Config d = load_text("gravity = [0, -10, 0]\n", "a.toml");
  EXPECT_EQ(d.get_vec3("gravity"), Vec3(0.0, -10.0, 0.0));
}

TEST(Load, InlineTablesAndEmptyTablesOfTheSchema) {
  const Config c = load_text("solver = { iterations = 7, pbd = { velocity_damping = 0.5 } }\n", "a.toml");
  EXPECT_EQ(c.get_int("solver.iterations"), 7);
  EXPECT_EQ(c.get_double("solver.pbd.velocity_damping"), 0.5);
  EXPECT_EQ(c.at("solver.iterations").source.line, 1);
  const Config d = load_text("[solver.xpbd]\n[scene]\n", "a.toml");  // empty tables of the schema
  EXPECT_EQ(d.get_bool("solver.xpbd.residuals"), SolverOptions{}.xpbd_residuals);
}

TEST(Load, ColliderDefaultsDependOnType) {
  const Config c = load_text("[[collider]]\ntype = \"plane\"\n[[collider]]\ntype = \"sphere\"\nradius = 2\n",
                             "a.toml");
  ASSERT_EQ(c.colliders.size(), 2u);
  EXPECT_TRUE(c.colliders[0].count("collider.normal"));
  EXPECT_FALSE(c.colliders[0].count("collider.radius"));
  EXPECT_FALSE(c.colliders[0].count("collider.motion"));
  EXPECT_TRUE(c.colliders[1].count("collider.radius"));
  EXPECT_FALSE(c.colliders[1].count("collider.normal"));
  EXPECT_EQ(std::get<double>(c.colliders[1].at("collider.radius").value), 2.0);
  EXPECT_EQ(c.colliders[1].at("collider.radius").source.line, 5);
}

TEST(Load, RunAndSolverOptions) {
  const Config c = load_text(
      "[time]\ndt = 0.01\nduration = 2\n[output]\nframe_every = 5\n[limits]\nmax_speed = 50\n"
      "[solver]\nname = \"pbd\"\norder = \"jacobi\"\nseed = { fixes = [\"D1\", \"D3\"] }\n",
      "a.toml");
  const RunOptions r = run_options(c);
  EXPECT_EQ(r.dt, 0.01);
  EXPECT_EQ(r.steps(), 200);
  EXPECT_EQ(r.frame_every, 5);
  EXPECT_EQ(r.limits.max_speed, 50.0);
  EXPECT_EQ(r.limits.max_distance, ExplosionLimits{}.max_distance);
  const SolverOptions s = solver_options(c);
  EXPECT_EQ(s.name, "pbd");
  EXPECT_EQ(s.order, ProjectionOrder::Jacobi);
  EXPECT_EQ(s.seed_fixes, (std::vector<std::string>{"D1", "D3"}));
  EXPECT_EQ(s.iterations, SolverOptions{}.iterations);
  EXPECT_EQ(s.precision, Precision::Double);
  EXPECT_EQ(solver_options(load_text("[solver]\nprecision = \"float\"\n", "a.toml")).precision,
            Precision::Float);
}

TEST(Load, AccessorsRefuseWrongTypesAndMissingKeys) {
  const Config c = load_text("", "a.toml");
  EXPECT_THROW(c.at("solver.nope"), ConfigError);
  EXPECT_THROW(c.get_int("time.dt"), ConfigError);
  EXPECT_THROW(c.get_string("gravity"), ConfigError);
  EXPECT_EQ(c.get_double("solver.iterations"), 10.0);  // an Int reads as a double
}

// ---------------------------------------------------------------------------------------------
// Bad input, one test per kind.

TEST(LoadErrors, UnknownKeyWithSuggestion) {
  const ConfigError e = load_error("description = \"x\"\n[solver]\niteratons = 3\n");
  expect_error(e, "bad.toml", 3, "solver.iteratons",
               "unknown key 'solver.iteratons' (did you mean 'solver.iterations'?)");
}

TEST(LoadErrors, UnknownTopLevelKeySuggestsTheTableItBelongsTo) {
  const ConfigError e = load_error("\n\niterations = 3\n");
  expect_error(e, "bad.toml", 3, "iterations",
               "unknown key 'iterations' (did you mean 'solver.iterations'?)");
}

TEST(LoadErrors, UnknownTable) {
  const ConfigError e = load_error("[solvr]\niterations = 3\n");
  expect_error(e, "bad.toml", 2, "solvr.iterations",
               "unknown key 'solvr.iterations' (did you mean 'solver.iterations'?)");
  const ConfigError empty = load_error("[nothing]\n");
  expect_error(empty, "bad.toml", 1, "nothing", "unknown key 'nothing'");
}

TEST(LoadErrors, UnknownKeyWithoutSuggestion) {
  const ConfigError e = load_error("[time]\ndt = 0.01\nzzzzzzzz = 1\n");
  expect_error(e, "bad.toml", 3, "time.zzzzzzzz", "unknown key 'time.zzzzzzzz'");
}

TEST(LoadErrors, UnknownKeyInCollider) {
  const ConfigError e = load_error(
      "[[collider]]\ntype = \"plane\"\n\n[[collider]]\ntype = \"sphere\"\nradus = 0.5\n");
  expect_error(e, "bad.toml", 6, "collider.1.radus",
               "unknown key 'radus' in [[collider]] entry 1 (did you mean 'radius'?)");
}

TEST(LoadErrors, ColliderKeyOfAnotherType) {
  const ConfigError e = load_error("[[collider]]\ntype = \"plane\"\nradius = 0.5\n");
  expect_error(e, "bad.toml", 3, "collider.0.radius",
               "key 'radius' does not apply to a collider of type 'plane' ([[collider]] entry 0; a "
               "plane takes type, normal, offset, restitution, friction)");
}

TEST(LoadErrors, ColliderAsATable) {
  const ConfigError e = load_error("gravity = [0, 0, 0]\n[collider]\ntype = \"plane\"\n");
  EXPECT_EQ(e.source().line, 2);
  EXPECT_EQ(e.key(), "collider");
  EXPECT_NE(std::string(e.what()).find("write each as [[collider]]"), std::string::npos) << e.what();
}

TEST(LoadErrors, ZeroPlaneNormal) {
  const ConfigError e = load_error("[[collider]]\ntype = \"plane\"\nnormal = [0, 0, 0]\n");
  expect_error(e, "bad.toml", 3, "collider.0.normal",
               "collider.0.normal = [0.0, 0.0, 0.0] must be non-zero (the normal of a plane)");
}

TEST(LoadErrors, WrongTypeFloatForInt) {
  const ConfigError e = load_error("[solver]\niterations = 3.5\n");
  expect_error(e, "bad.toml", 2, "solver.iterations",
               "solver.iterations: expected an integer, got the float 3.5 (a float is not accepted "
               "where an integer is expected)");
}

TEST(LoadErrors, WrongTypeStringForFloat) {
  const ConfigError e = load_error("[time]\n\ndt = \"fast\"\n");
  expect_error(e, "bad.toml", 3, "time.dt", "time.dt: expected a number, got the string 'fast'");
}

TEST(LoadErrors, WrongTypeIntForBool) {
  const ConfigError e = load_error("[solver]\njacobi_averaging = 1\n");
  expect_error(e, "bad.toml", 2, "solver.jacobi_averaging",
               "solver.jacobi_averaging: expected true or false, got the integer 1");
}

TEST(LoadErrors, WrongTypeValueForTable) {
  const ConfigError e = load_error("solver = 3\n");
  expect_error(e, "bad.toml", 1, "solver",
               "'solver' is a table of keys, not a value: write its keys under [solver]");
}

TEST(LoadErrors, WrongElementTypeInList) {
  const ConfigError e = load_error("[scene]\nkind = \"cloth\"\nresolution = [8, 8.0]\n");
  expect_error(e, "bad.toml", 3, "scene.resolution",
               "scene.resolution[1]: expected an integer (a float is not accepted where an integer "
               "is expected), got the float 8");
}

TEST(LoadErrors, OutOfRangeInclusiveMinimum) {
  const ConfigError e = load_error("[solver]\niterations = 0\n");
  expect_error(e, "bad.toml", 2, "solver.iterations", "solver.iterations = 0 is below the minimum 1");
}

TEST(LoadErrors, OutOfRangeExclusiveMinimum) {
  const ConfigError e = load_error("[time]\ndt = 0\n");
  expect_error(e, "bad.toml", 2, "time.dt", "time.dt = 0 s must be greater than 0 s");
}

TEST(LoadErrors, OutOfRangeInclusiveMaximum) {
  const ConfigError e = load_error("[solver]\njacobi_relaxation = 2.5\n");
  expect_error(e, "bad.toml", 2, "solver.jacobi_relaxation",
               "solver.jacobi_relaxation = 2.5 is above the maximum 2");
  // The maximum itself is allowed.
  EXPECT_NO_THROW(load_text("[solver]\njacobi_relaxation = 2.0\n", "ok.toml"));
}

TEST(LoadErrors, OutOfRangeOfAnInteger) {
  const ConfigError e = load_error("[solver]\nsubsteps = 100001\n");
  expect_error(e, "bad.toml", 2, "solver.substeps", "solver.substeps = 100001 is above the maximum 100000");
}

TEST(LoadErrors, NotInChoices) {
  const ConfigError e = load_error("[solver]\norder = \"reverse\"\n");
  expect_error(e, "bad.toml", 2, "solver.order",
               "solver.order = 'reverse' is not one of sequential, reversed, shuffled, colored, "
               "jacobi, grouped_shuffled, bottom_up (did you mean 'reversed'?)");
}

TEST(LoadErrors, PrecisionNotInChoices) {
  const ConfigError e = load_error("[solver]\n\nprecision = \"single\"\n");
  expect_error(e, "bad.toml", 3, "solver.precision",
               "solver.precision = 'single' is not one of double, float");
}

TEST(LoadErrors, StringListNotInChoices) {
  const ConfigError e = load_error("[solver.seed]\nfixes = [\"D1\",\n  \"D0\"]\n");
  std::string ids;
  for (const std::string& id : seed_departure_ids()) ids += (ids.empty() ? "" : ", ") + id;
  expect_error(e, "bad.toml", 3, "solver.seed.fixes",
               "solver.seed.fixes[1] = 'D0' is not one of " + ids + " (did you mean 'D1'?)");
}

TEST(LoadErrors, NaN) {
  const ConfigError e = load_error("[time]\ndt = 0.01\nduration = nan\n");
  expect_error(e, "bad.toml", 3, "time.duration", "time.duration = nan is not a finite number");
}

TEST(LoadErrors, Infinity) {
  const ConfigError e = load_error("[limits]\nmax_speed = inf\n");
  expect_error(e, "bad.toml", 2, "limits.max_speed", "limits.max_speed = inf is not a finite number");
}

TEST(LoadErrors, InfinityInAVec3) {
  const ConfigError e = load_error("gravity = [0,\n  -inf,\n  0]\n");
  expect_error(e, "bad.toml", 2, "gravity", "gravity[1] = -inf is not a finite number");
}

TEST(LoadErrors, Vec3OfWrongLength) {
  const ConfigError e = load_error("description = \"x\"\ngravity = [0, -9.81]\n");
  expect_error(e, "bad.toml", 2, "gravity",
               "gravity: expected an array of 3 numbers [x, y, z], got 2 elements [0, -9.81]");
}

TEST(LoadErrors, NegativeMass) {
  const ConfigError e = load_error("[scene]\nkind = \"particle\"\nmass = -1\n");
  expect_error(e, "bad.toml", 3, "scene.mass", "scene.mass = -1 kg must be greater than 0 kg");
}

TEST(LoadErrors, NegativeDensity) {
  const ConfigError e = load_error("[scene]\nkind = \"tet_block\"\ndensity = -1000.0\n");
  expect_error(e, "bad.toml", 3, "scene.density",
               "scene.density = -1000 kg/m^3 must be greater than 0 kg/m^3");
}

TEST(LoadErrors, ZeroClothSize) {
  const ConfigError e = load_error("[scene]\nkind = \"cloth\"\nsize = [1.0,\n        0.0]\n");
  expect_error(e, "bad.toml", 4, "scene.size", "scene.size[1] = 0 m must be greater than 0 m");
}

TEST(LoadErrors, ListOfWrongLength) {
  const ConfigError e = load_error("[scene]\nkind = \"cloth\"\nresolution = [8, 8, 8]\n");
  expect_error(e, "bad.toml", 3, "scene.resolution",
               "scene.resolution: expected an array of 2 integers, got 3 elements [8, 8, 8]");
}

TEST(LoadErrors, UnknownSceneKind) {
  const ConfigError e = load_error("[scene]\nkind = \"clth\"\n");
  expect_error(e, "bad.toml", 2, "scene.kind",
               "scene.kind = 'clth' is not one of particle, spring, pendulum, chain, cloth, "
               "tet_block, tri_block, spheres, mesh (did you mean 'cloth'?)");
}

TEST(LoadErrors, KeyOfAnotherSceneKind) {
  const ConfigError e = load_error("[scene]\nkind = \"cloth\"\nlinks = 5\n");
  expect_error(e, "bad.toml", 3, "scene.links",
               "unknown key 'scene.links' for scene kind 'cloth': it is a key of scene kind 'chain' "
               "(scene.kind = 'cloth' here)");
}

TEST(LoadErrors, SceneKeyWithoutKindIsAParticleKey) {
  // Without scene.kind the scene is a particle: cloth keys are unknown.
  const ConfigError e = load_error("[scene]\nresolution = [8, 8]\n");
  EXPECT_EQ(e.key(), "scene.resolution");
  EXPECT_EQ(e.source().line, 2);
}

TEST(LoadErrors, NonExistingMeshFile) {
  TempDir dir("missing_mesh");
  const std::string file = (dir.path() / "m.toml").string();
  const ConfigError e = load_error("[scene]\nkind = \"mesh\"\nfile = \"nothere.obj\"\n", file);
  expect_error(e, file, 3, "scene.file",
               "scene.file = 'nothere.obj': no such file (looked for " +
                   (dir.path() / "nothere.obj").string() + ")");
}

TEST(LoadErrors, MeshSceneWithoutFile) {
  const ConfigError e = load_error("[scene]\nkind = \"mesh\"\n");
  EXPECT_EQ(e.key(), "scene.file");
  EXPECT_EQ(e.source().file, "bad.toml");
  EXPECT_NE(std::string(e.what()).find("needs a mesh file"), std::string::npos) << e.what();
}

TEST(LoadErrors, DegenerateTetMesh) {
  TempDir dir("flat_tet");
  // Two tets; the second has all four points in the plane z = 0.
  dir.write("flat.node",
            "6 3 0 0\n"
            "0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 0\n5 0.5 0.5 0\n");
  dir.write("flat.ele", "2 4 0\n0 0 1 2 3\n1 1 2 4 5\n");
  const std::string file = (dir.path() / "flat.toml").string();
  const ConfigError e =
      load_error("description = \"a flat tet\"\n[scene]\nkind = \"mesh\"\nfile = \"flat.node\"\n", file);
  EXPECT_EQ(e.source().file, file);
  EXPECT_EQ(e.source().line, 4);
  EXPECT_EQ(e.key(), "scene.file");
  const std::string what = e.what();
  EXPECT_EQ(what.rfind(file + ":4: scene.file = 'flat.node': ", 0), 0u) << what;
  EXPECT_NE(what.find("tet 1"), std::string::npos) << what;  // names the element
  EXPECT_NE(what.find("flat.node"), std::string::npos) << what;
}

TEST(LoadErrors, MeshErrorKeepsItsFileAndLine) {
  TempDir dir("bad_obj");
  dir.write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  const std::string file = (dir.path() / "s.toml").string();
  const ConfigError e = load_error("[scene]\nkind = \"mesh\"\nfile = \"bad.obj\"\n", file);
  EXPECT_EQ(e.source().line, 3);
  EXPECT_EQ(e.key(), "scene.file");
  // The mesh reader's own position, bad.obj line 4, is kept in the message.
  EXPECT_NE(std::string(e.what()).find((dir.path() / "bad.obj").string() + ":4:"), std::string::npos)
      << e.what();
}

TEST(LoadErrors, MalformedToml) {
  const ConfigError e = load_error("description = \"x\"\n[time]\ndt = = 0.01\n");
  EXPECT_EQ(e.source().file, "bad.toml");
  EXPECT_EQ(e.source().line, 3);
  EXPECT_EQ(std::string(e.what()).rfind("bad.toml:3: TOML syntax error", 0), 0u) << e.what();
}

TEST(LoadErrors, DuplicateKeyIsATomlError) {
  const ConfigError e = load_error("[time]\ndt = 0.01\ndt = 0.02\n");
  EXPECT_EQ(e.source().line, 3);
}

TEST(LoadErrors, SceneBuilderRefusalNamesTheKey) {
  const ConfigError e = load_error("[scene]\nkind = \"cloth\"\nresolution = [4, 4]\npin_indices = [3, 16]\n");
  expect_error(e, "bad.toml", 4, "scene.pin_indices",
               "scene.pin_indices[1] = 16 is out of range: the scene has 16 particles (indices 0 to 15)");
}

TEST(LoadErrors, FirstErrorInFileOrderIsReported) {
  const ConfigError e = load_error("[time]\ndt = 0\n[solver]\niterations = 0\n");
  EXPECT_EQ(e.source().line, 2);
  EXPECT_EQ(e.key(), "time.dt");
}

TEST(LoadErrors, MissingScenarioFile) {
  TempDir dir("nofile");
  try {
    (void)load((dir.path() / "none.toml").string());
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no scenario"), std::string::npos) << e.what();
  }
}


// ---------------------------------------------------------------------------------------------
// The run as planned, and values beyond double precision: refused naming the key and line.

TEST(LoadErrors, AStepCountThatOverflowsOrIsZero) {
  expect_error(load_error("[scene]\nkind = \"particle\"\n[time]\ndt = 1e-300\nduration = 2.0\n"), "bad.toml", 4,
               "time.dt",
               "time.duration = 2.0 s, time.dt = 1e-300 s: 2e+300 steps, more than the 1e+12 a run may plan");
  expect_error(load_error("[scene]\nkind = \"particle\"\n[time]\ndt = 0.1\nduration = 0.01\n"), "bad.toml", 5,
               "time.duration",
               "time.duration = 0.01 s, time.dt = 0.1 s: the run would take no step (the step count is "
               "duration / dt rounded, here 0.09999999999999999)");
  // Half a step rounds to one: accepted.
  EXPECT_EQ(run_options(load_text("[scene]\nkind = \"particle\"\n[time]\ndt = 0.1\nduration = 0.05\n", "a.toml"))
                .steps(),
            1);
}

TEST(LoadErrors, PhysicalValuesBeyondDoublePrecisionNameTheirKey) {
  const ConfigError mass = load_error("[scene]\nkind = \"particle\"\nmass = 1e-320\n");
  EXPECT_EQ(mass.key(), "scene.mass");
  EXPECT_EQ(mass.source().line, 3);
  EXPECT_NE(std::string(mass.what()).find("smaller than 1e-100 kg"), std::string::npos) << mass.what();
  const ConfigError gravity = load_error("gravity = [0.0, -1e308, 0.0]\n[scene]\nkind = \"chain\"\n");
  EXPECT_EQ(gravity.key(), "gravity");
  EXPECT_EQ(gravity.source().line, 1);
  const ConfigError origin = load_error("[scene]\nkind = \"cloth\"\norigin = [1e308, 0.0, 0.0]\n");
  EXPECT_EQ(origin.key(), "scene.origin");
  const ConfigError radius = load_error(
      "[scene]\nkind = \"particle\"\n[[collider]]\ntype = \"sphere\"\nradius = 1e200\n");
  EXPECT_EQ(radius.key(), "collider.0.radius");
  EXPECT_EQ(radius.source().line, 5);
  // A tiny component of a vector is harmless; "never" (1e300 s) is a time, not a quantity.
  EXPECT_NO_THROW((void)load_text("gravity = [1e-300, -9.81, 0.0]\n[scene]\nkind = \"particle\"\n", "a.toml"));
}

TEST(LoadErrors, PlacementsBeyondTheWorldNameTheirKey) {
  // Coordinates, speeds, rotations and scales have bounds (1e6 in their units): beyond them the
  // builder would only meet the degenerate triangles or NaN positions that they make.
  const ConfigError position = load_error(
      "[scene]\nkind = \"chain\"\n[[body]]\nkind = \"tet_block\"\nposition = [1e200, 0.0, 0.0]\n");
  EXPECT_EQ(position.key(), "body.0.position");
  EXPECT_EQ(position.source().line, 5);
  EXPECT_NE(std::string(position.what()).find("above the maximum 1000000 m"), std::string::npos) << position.what();
  const ConfigError rotation = load_error(
      "[scene]\nkind = \"chain\"\n[[body]]\nkind = \"tet_block\"\nrotation = [0.0, -1e308, 0.0]\n");
  EXPECT_EQ(rotation.key(), "body.0.rotation");
  const ConfigError scale = load_error(
      "[scene]\nkind = \"chain\"\n[[collider]]\ntype = \"mesh\"\nfile = \"x.obj\"\nscale = 1e300\n");
  EXPECT_EQ(scale.key(), "collider.0.scale");
  EXPECT_EQ(scale.source().line, 6);
  const ConfigError speed = load_error("[scene]\nkind = \"particle\"\nvelocity = [2e6, 0.0, 0.0]\n");
  EXPECT_EQ(speed.key(), "scene.velocity");
  // The bounds themselves are accepted.
  EXPECT_NO_THROW((void)load_text("[scene]\nkind = \"particle\"\nposition = [1e6, -1e6, 0.0]\n"
                                  "velocity = [0.0, -1e6, 0.0]\n", "a.toml"));
}

TEST(LoadErrors, ACollidersIndexThatOverflowsIsNamed) {
  const ConfigError e = load_error("[scene]\nkind = \"chain\"\n[[collider]]\ntype = \"plane\"\n", "bad.toml",
                                   testing::sets({"collider.99999999999999999999.radius=1"}));
  EXPECT_EQ(e.key(), "collider.99999999999999999999.radius");
  EXPECT_NE(std::string(e.what()).find("there is no collider 99999999999999999999"), std::string::npos) << e.what();
}

TEST(LoadErrors, AnEmptyScenarioFileIsRefused) {
  TempDir dir("empty_scenario");
  for (const char* text : {"", "  \n\t\n", "# only a comment\n"}) {
    dir.write("empty.toml", text);
    const std::string file = (dir.path() / "empty.toml").string();
    try {
      (void)load(file);
      ADD_FAILURE() << "an empty scenario was accepted: '" << text << "'";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.source().file, file);
      EXPECT_NE(std::string(e.what()).find("has no keys"), std::string::npos) << e.what();
    }
  }
}

TEST(LoadErrors, AMeshThatIsADirectoryOrADeviceIsNamedSo) {
  TempDir dir("mesh_not_a_file");
  std::filesystem::create_directories(dir.path() / "meshes");
  const std::string file = (dir.path() / "m.toml").string();
  const ConfigError d = load_error("[scene]\nkind = \"mesh\"\nfile = \"meshes\"\n", file);
  EXPECT_EQ(d.key(), "scene.file");
  EXPECT_NE(std::string(d.what()).find("is a directory, not a mesh file"), std::string::npos) << d.what();
  const ConfigError z = load_error("[scene]\nkind = \"mesh\"\nfile = \"/dev/zero\"\n", file);
  EXPECT_NE(std::string(z.what()).find("not a regular file"), std::string::npos) << z.what();
}

TEST(LoadErrors, AHugeUnknownKeyIsCutInTheMessage) {
  const std::string key(1 << 20, 'k');
  const ConfigError e = load_error("[scene]\nkind = \"spring\"\n" + key + " = 1\n");
  EXPECT_EQ(e.source().line, 3);
  EXPECT_LT(std::string(e.what()).size(), 300u);
  EXPECT_NE(std::string(e.what()).find("(1048582 characters)"), std::string::npos);
}

// One material (solvers/pbd_material.hpp): what pbd cannot honour is refused, naming the key.
TEST(LoadErrors, PbdRefusesAConstraintDampingAndTheCorrectionOfADerivedStiffness) {
  const std::string chain =
      "[solver]\nname = \"pbd\"\n[scene]\nkind = \"chain\"\nlinks = 3\ndamping = 0.5\n";
  const ConfigError d = load_error(chain);
  EXPECT_EQ(d.source().file, "bad.toml");
  EXPECT_EQ(d.source().line, 6);
  EXPECT_EQ(d.key(), "scene.damping");
  EXPECT_NE(std::string(d.what()).find("no pbd meaning"), std::string::npos) << d.what();
  // xpbd reads it.
  EXPECT_NO_THROW((void)load_text(chain, "ok.toml", testing::sets({"solver.name=xpbd"})));
  // The correction of an explicit k, with k derived from the compliance.
  const std::string corrected =
      "[solver]\nname = \"pbd\"\n[solver.pbd]\nstiffness_correction = true\n[scene]\nkind = \"chain\"\n";
  const ConfigError c = load_error(corrected);
  EXPECT_EQ(c.key(), "solver.pbd.stiffness_correction");
  EXPECT_EQ(c.source().line, 4);
  EXPECT_NE(std::string(c.what()).find("solver.pbd.material = \"stiffness\""), std::string::npos) << c.what();
  EXPECT_NO_THROW((void)load_text(corrected, "ok.toml", testing::sets({"solver.pbd.material=stiffness"})));
  // An unknown material.
  const ConfigError m = load_error("[solver]\nname = \"pbd\"\n[solver.pbd]\nmaterial = \"steel\"\n");
  EXPECT_EQ(m.key(), "solver.pbd.material");
}

}  // namespace
}  // namespace pbdbench::config
