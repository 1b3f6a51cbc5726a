// describe_keys, describe_config, list_scenarios, resolve_scenario, and docs/scenarios.md.
//
// docs/scenarios.md is a hand-written introduction, a marker line, and schema_markdown(). After a
// schema change, regenerate it with
//   PBDBENCH_UPDATE_DOCS=1 test_config --gtest_filter=Describe.DocsContainTheSchema
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "catalog/solver_catalog.hpp"

#include "config/config.hpp"
#include "config/internal.hpp"
#include "tests/config/helpers.hpp"

namespace pbdbench::config {
namespace {

using testing::sets;

const char* kMarker = "<!-- Everything below this line is generated from the schema (config/schema.cpp). -->";

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// The line of `text` that starts with `start` (after the indent), or "".
std::string line_of(const std::string& text, const std::string& start) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
    if (line.find_first_not_of(' ') != std::string::npos &&
        line.compare(line.find_first_not_of(' '), start.size(), start) == 0)
      return line;
  return "";
}

TEST(Describe, KeysOfAKindWithTypeDefaultAndUnits) {
  for (const SceneKindInfo& kind : scene_kinds()) {
    SCOPED_TRACE(kind.name);
    const std::string text = describe_keys(kind.name);
    EXPECT_TRUE(contains(text, kind.doc));
    std::vector<const KeySpec*> all;
    for (const KeySpec& k : common_keys()) all.push_back(&k);
    for (const KeySpec& k : kind.keys) all.push_back(&k);
    for (const KeySpec& k : collider_keys()) all.push_back(&k);
    for (const KeySpec* k : all) {
      const std::string line = line_of(text, k->path + " ");
      ASSERT_FALSE(line.empty()) << k->path << " is missing";
      EXPECT_TRUE(contains(line, detail::type_label(*k))) << line;
      EXPECT_TRUE(contains(line, detail::format_value(k->default_value))) << line;
      EXPECT_TRUE(contains(line, k->units)) << line;
      EXPECT_TRUE(contains(line, k->doc)) << line;
      EXPECT_TRUE(contains(line, detail::format_bounds(*k))) << line;
    }
    // No key of another kind.
    for (const SceneKindInfo& other : scene_kinds())
      for (const KeySpec& k : other.keys)
        if (!detail::find_key(kind.keys, k.path)) {
          EXPECT_EQ(line_of(text, k.path + " "), "") << k.path;
        }
  }
  const std::string cloth = describe_keys("cloth");
  EXPECT_TRUE(contains(line_of(cloth, "scene.stretch_compliance "), "m/N"));
  EXPECT_TRUE(contains(line_of(cloth, "scene.resolution "), "[64, 64]"));
  EXPECT_TRUE(contains(line_of(cloth, "scene.pins "), "one of: top_corners, top_edge, corners, none"));
}

TEST(Describe, UnknownKind) {
  try {
    (void)describe_keys("clth");
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "'clth' is not a scene kind (did you mean 'cloth'?); the kinds are particle, spring, "
              "pendulum, chain, cloth, tet_block, tri_block, spheres, mesh");
  }
}

TEST(Describe, ConfigShowsValuesAndSources) {
  const Config c = load_text("[scene]\nkind = \"chain\"\nlinks = 4\n[[collider]]\ntype = \"plane\"\n",
                             "d.toml", sets({"solver.iterations=3"}));
  const std::string text = describe_config(c);
  EXPECT_TRUE(contains(line_of(text, "scene.links "), "d.toml:3"));
  EXPECT_TRUE(contains(line_of(text, "scene.links "), " 4 "));
  EXPECT_TRUE(contains(line_of(text, "solver.iterations "), "--set solver.iterations=3"));
  EXPECT_TRUE(contains(line_of(text, "solver.substeps "), "default"));
  EXPECT_TRUE(contains(line_of(text, "collider.0.type "), "d.toml:5"));
  EXPECT_TRUE(contains(line_of(text, "collider.0.normal "), "default"));
  EXPECT_EQ(line_of(text, "scene.resolution "), "");
  for (const auto& [path, entry] : c.entries) EXPECT_NE(line_of(text, path + " "), "") << path;
}

// The [[body]] entries: each one's placement and kind keys, with their sources, in both forms.
TEST(Describe, ConfigShowsTheBodies) {
  const Config c = load_text(
      "[scene]\nkind = \"tet_block\"\ncells = [1, 1, 1]\n"
      "[[body]]\nkind = \"chain\"\nlinks = 3\nposition = [0.0, 1.0, 0.0]\n"
      "[[body]]\nkind = \"tet_block\"\ncells = [2, 1, 1]\nedge_compliance = 1e-5\n",
      "b.toml", sets({"solver.name=xpbd"}));
  ASSERT_EQ(c.bodies.size(), 2u);
  const std::string table = describe_config(c);
  EXPECT_TRUE(contains(line_of(table, "body.0.kind "), "b.toml:5")) << table;
  EXPECT_TRUE(contains(line_of(table, "body.0.links "), "b.toml:6")) << table;
  EXPECT_TRUE(contains(line_of(table, "body.0.position "), "b.toml:7")) << table;
  EXPECT_TRUE(contains(line_of(table, "body.0.rotation "), "default")) << table;
  EXPECT_TRUE(contains(line_of(table, "body.1.cells "), "b.toml:10")) << table;
  for (std::size_t i = 0; i < c.bodies.size(); ++i)
    for (const auto& [path, entry] : c.bodies[i])
      EXPECT_NE(line_of(table, "body." + std::to_string(i) + path.substr(4) + " "), "") << path;
  const std::string reader = describe_config(c, false, 100, SolverFamily::Xpbd);
  EXPECT_TRUE(contains(reader, "body.0.links = 3")) << reader;
  EXPECT_TRUE(contains(reader, "body.1.edge_compliance = 1e-05")) << reader;
  EXPECT_TRUE(contains(reader, "body.1.cells = [2, 1, 1]")) << reader;
  // A body's stiffness keys are hidden from xpbd as the scene's are.
  EXPECT_FALSE(contains(reader, "body.1.edge_stiffness =")) << reader;
  EXPECT_TRUE(contains(describe_config(c, true, 100, SolverFamily::Xpbd), "body.1.edge_stiffness =")) << reader;
}

TEST(Describe, ListScenariosFindsTheCatalog) {
  const auto list = list_scenarios();
  std::vector<std::string> names;
  for (const ScenarioInfo& s : list) {
    names.push_back(s.name);
    EXPECT_FALSE(s.description.empty()) << s.name;
    EXPECT_TRUE(std::filesystem::exists(s.file)) << s.name;
  }
  EXPECT_EQ(names, testing::catalog_names());  // sorted
  auto kind_of = [&](const std::string& name) {
    for (const ScenarioInfo& s : list)
      if (s.name == name) return s.kind;
    return std::string();
  };
  EXPECT_EQ(kind_of("hanging_cloth"), "cloth");
  EXPECT_EQ(kind_of("free_fall"), "particle");
  EXPECT_EQ(kind_of("balls_in_bowl"), "spheres");
  EXPECT_EQ(kind_of("mesh_box_tets"), "mesh");
  EXPECT_EQ(kind_of("failures/inverted_tets"), "tet_block");  // a subfolder of the catalog
}

TEST(Describe, ResolveScenario) {
  const std::filesystem::path dir = testing::catalog_dir();
  EXPECT_EQ(resolve_scenario("pendulum"), dir / "pendulum.toml");
  EXPECT_EQ(resolve_scenario("pendulum.toml"), dir / "pendulum.toml");
  const std::string path = (dir / "spring.toml").string();
  EXPECT_EQ(resolve_scenario(path), std::filesystem::path(path));
  EXPECT_EQ(load(path).scenario_name, "spring");
  EXPECT_EQ(load("spring").scenario_name, "spring");
  EXPECT_EQ(resolve_scenario("failures/zero_rest_length"), dir / "failures/zero_rest_length.toml");
}

TEST(Describe, UnknownScenarioListsTheCatalog) {
  try {
    (void)resolve_scenario("hanging_clot");
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_TRUE(contains(what, "no scenario 'hanging_clot'")) << what;
    EXPECT_TRUE(contains(what, "(did you mean 'hanging_cloth'?)")) << what;
    for (const std::string& name : testing::catalog_names()) EXPECT_TRUE(contains(what, name)) << name;
  }
}

TEST(Describe, MarkdownHasEveryTableAndKey) {
  const std::string md = schema_markdown();
  for (const KeySpec& k : common_keys()) EXPECT_TRUE(contains(md, "| `" + k.path + "` |")) << k.path;
  for (const KeySpec& k : collider_keys()) EXPECT_TRUE(contains(md, "| `" + k.path + "` |")) << k.path;
  for (const SceneKindInfo& kind : scene_kinds()) {
    EXPECT_TRUE(contains(md, "### `" + kind.name + "`")) << kind.name;
    for (const KeySpec& k : kind.keys) EXPECT_TRUE(contains(md, "| `" + k.path + "` |")) << k.path;
  }
  EXPECT_TRUE(contains(md, "| `time.dt` | float | `0.016666666666666666` | s | (0, 1] |"));
}

TEST(Describe, DocsContainTheSchema) {
  const std::filesystem::path path = std::filesystem::path(PBDBENCH_SOURCE_DIR) / "docs" / "scenarios.md";
  std::string text;
  {
    std::ifstream in(path);
    ASSERT_TRUE(in) << "cannot read " << path;
    std::ostringstream s;
    s << in.rdbuf();
    text = s.str();
  }
  const auto marker = text.find(kMarker);
  ASSERT_NE(marker, std::string::npos) << "no marker line in " << path;
  const std::string generated = schema_markdown();
  if (const char* update = std::getenv("PBDBENCH_UPDATE_DOCS"); update && std::string(update) == "1") {
    text = text.substr(0, marker) + kMarker + "\n\n" + generated;
    std::ofstream(path) << text;
  }
  EXPECT_TRUE(contains(text, generated))
      << path << " is out of date; regenerate it with PBDBENCH_UPDATE_DOCS=1 test_config "
      << "--gtest_filter=Describe.DocsContainTheSchema";
}

}  // namespace
}  // namespace pbdbench::config

namespace pbdbench::config {
namespace {

std::optional<SolverFamily> family_of(const Config& c) {
  const SolverEntry* e = find_solver(c.get_string("solver.name"));
  return e ? std::optional(e->family) : std::nullopt;
}

TEST(Describe, ForAReaderFitsTheWidthShowsTheSolversKeysAndWhatItReads) {
  const std::string chain = "[scene]\nkind = \"chain\"\nlinks = 4\nstiffness = 0.5\ncompliance = 1e-3\n";
  const Config xpbd = load_text(chain, "d.toml", sets({"solver.name=xpbd"}));
  const Config pbd = load_text(chain, "d.toml", sets({"solver.name=pbd"}));
  for (const Config* c : {&xpbd, &pbd}) {
    std::istringstream lines(describe_config(*c, false, 100, family_of(*c)));
    std::string line;
    while (std::getline(lines, line)) EXPECT_LE(line.size(), 100u) << line;
  }
  const std::string x = describe_config(xpbd, false, 100, SolverFamily::Xpbd),
                    p = describe_config(pbd, false, 100, SolverFamily::Pbd);
  EXPECT_TRUE(contains(x, "scene.compliance = 0.001"));
  EXPECT_FALSE(contains(x, "scene.stiffness ="));
  EXPECT_FALSE(contains(x, "solver.seed."));
  EXPECT_TRUE(contains(x, "alpha = 0.001"));
  // pbd by default: the compliance, and the k derived from it with the rule named.
  EXPECT_TRUE(contains(p, "scene.compliance = 0.001"));
  EXPECT_FALSE(contains(p, "scene.stiffness ="));
  EXPECT_TRUE(contains(p, "solver.pbd.material = compliance"));
  // (The lines wrap at 100 columns: the words are read with the line breaks taken out.)
  auto flat = [](const std::string& text) {
    std::string out;
    for (char ch : text)
      if (!(std::isspace(static_cast<unsigned char>(ch)) && !out.empty() && out.back() == ' '))
        out += std::isspace(static_cast<unsigned char>(ch)) ? ' ' : ch;
    return out;
  };
  EXPECT_TRUE(contains(flat(p), "derived from alpha = 0.001 (Mueller 2007 effective stiffness: k = 1 - (1 + h^2 S / alpha)^(-1/n)"))
      << p;
  EXPECT_FALSE(contains(p, "k = 0.5"));
  // pbd with the explicit override: the stiffness keys, stated as an override.
  const Config pbd_k = load_text(chain, "d.toml", sets({"solver.name=pbd", "solver.pbd.material=stiffness"}));
  const std::string pk = describe_config(pbd_k, false, 100, SolverFamily::Pbd);
  EXPECT_TRUE(contains(pk, "scene.stiffness = 0.5"));
  EXPECT_FALSE(contains(pk, "scene.compliance ="));
  EXPECT_TRUE(contains(pk, "solver.pbd.stiffness_correction"));
  EXPECT_TRUE(contains(flat(pk), "k = 0.5 (explicit override"));
  // pbd-seed: the listing's k.
  const Config seed = load_text(chain, "d.toml", sets({"solver.name=pbd-seed"}));
  const std::string sk = describe_config(seed, false, 100, SolverFamily::PbdSeed);
  EXPECT_TRUE(contains(sk, "scene.stiffness = 0.5"));
  EXPECT_TRUE(contains(flat(sk), "k = 0.5 (the seed listing's stiffness"));
  const std::string all = describe_config(pbd, true, 100, SolverFamily::Pbd);
  EXPECT_TRUE(contains(all, "scene.stiffness = 0.5"));
  EXPECT_TRUE(contains(all, "solver.seed."));
  // The shared keys a family does not read are hidden too (the rows' families): ref-* reads no
  // projection sweeps; without a family (a name the catalogue lacks) every solver key shows.
  const Config ref = load_text(chain, "d.toml", sets({"solver.name=ref-bdf"}));
  EXPECT_FALSE(contains(describe_config(ref, false, 100, SolverFamily::Reference), "solver.iterations ="));
  EXPECT_TRUE(contains(describe_config(ref, false, 100, SolverFamily::Reference), "solver.ref.rtol ="));
  EXPECT_TRUE(contains(describe_config(ref, false, 100), "solver.iterations ="));
}

// A key set for a solver that does not read it is accepted and named in a warning: the key,
// where it was set, the solver and the families that read it; defaults are not warned about.
TEST(Describe, KeysTheSolverDoesNotReadAreWarnedAbout) {
  const std::string text = "solver.name = \"pbd\"\n[solver.seed]\nfixes = [\"D1\"]\n"
                           "[scene]\nkind = \"chain\"\nlinks = 3\n";
  const Config c = load_text(text, "w.toml", sets({"solver.global.tolerance=1e-6"}));
  const std::vector<std::string> w = unread_solver_keys(c, SolverFamily::Pbd);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0], "solver.seed.fixes (w.toml:3) is set but pbd does not read it (an option of pbd-seed)");
  EXPECT_TRUE(contains(w[1], "solver.global.tolerance (--set"));
  EXPECT_TRUE(contains(w[1], "an option of global-*"));
  EXPECT_TRUE(unread_solver_keys(c, SolverFamily::PbdSeed).size() == 1u);  // the global key
  EXPECT_TRUE(unread_solver_keys(load_text(text, "w.toml"), SolverFamily::PbdSeed).empty());
  EXPECT_TRUE(contains(describe_config(c, false, 100, SolverFamily::Pbd), "warning: solver.seed.fixes"));
  // A shared key the family does not read: solver.iterations for a reference integrator.
  const Config r = load_text("[solver]\nname = \"ref-bdf\"\niterations = 4\n"
                             "[scene]\nkind = \"chain\"\n", "r.toml");
  const std::vector<std::string> wr = unread_solver_keys(r, SolverFamily::Reference);
  ASSERT_EQ(wr.size(), 1u);
  EXPECT_TRUE(contains(wr[0], "solver.iterations (r.toml:3) is set but ref-bdf does not read it "
                              "(an option of pbd-seed, pbd, xpbd)"));
}

// An FEM scene: what each solver uses for the FEM groups, said truthfully. pbd has no k for
// them (it refuses the scene: no "k = 1" is shown); xpbd projects the constraints with their
// compliances 1 / (mu V) and 1 / (lambda_snh V); the reference solvers use the element's energy.
TEST(Describe, FemGroupsSayWhatEachSolverUses) {
  const std::string block =
      "[scene]\nkind = \"tet_block\"\ncells = [2, 1, 1]\nsize = [0.2, 0.1, 0.1]\nedges = false\n"
      "volumes = false\nmaterial = \"stable_neo_hookean\"\nyoungs_modulus = 1e6\npoisson_ratio = 0.3\n";
  auto describe = [&](const char* solver) {
    const Config c = load_text(block, "fem.toml", sets({std::string("solver.name=") + solver}));
    std::string flat;  // the words, with the 100-column line breaks taken out
    std::istringstream lines(describe_config(c, false, 100));
    for (std::string line; std::getline(lines, line);) {
      EXPECT_LE(line.size(), 100u) << line;
      flat += ' ';
      flat += line.substr(std::min(line.find_first_not_of(' '), line.size()));
    }
    return flat;
  };
  const std::string pbd = describe("pbd"), xpbd = describe("xpbd"), ref = describe("ref-be");
  EXPECT_TRUE(contains(pbd, "x fem_deviatoric): no k (pbd has no stiffness rule")) << pbd;
  EXPECT_TRUE(contains(pbd, "x fem_hydrostatic): no k")) << pbd;
  EXPECT_FALSE(contains(pbd, "k = 1")) << pbd;
  EXPECT_TRUE(contains(pbd, "pbd refuses this scene")) << pbd;
  EXPECT_TRUE(contains(xpbd, "x fem_deviatoric): alpha = ")) << xpbd;
  EXPECT_TRUE(contains(xpbd, "= 1 / (mu V), mu = 3.846e+05 Pa, lambda = 5.769e+05 Pa from E and nu")) << xpbd;
  EXPECT_TRUE(contains(xpbd, "= 1 / (lambda_snh V)")) << xpbd;
  EXPECT_TRUE(contains(ref, "x fem_deviatoric): the element's energy V Psi(F), mu = 3.846e+05 Pa")) << ref;
  EXPECT_FALSE(contains(ref, "): alpha = ")) << ref;
}

}  // namespace
}  // namespace pbdbench::config
