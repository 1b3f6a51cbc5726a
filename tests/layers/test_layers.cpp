// The one-way include rule: a file of a folder may include its own folder and the folders of
// the floors below it, never a folder of its own floor or of a floor above. The floors are
// declared once, in the top-level CMakeLists.txt (PBDBENCH_LAYERS, the order the libraries are
// added in), and passed here as PBDBENCH_LAYERS: floors separated by '|', the folders of a
// floor by spaces. benchmarks/ and tests/ stand above every floor and are not scanned.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/temp_dir.hpp"

namespace pbdbench::test {
namespace {

namespace fs = std::filesystem;

// folder -> floor (0 = the ground floor).
std::map<std::string, int> parse_layers(const std::string& text) {
  std::map<std::string, int> floor;
  std::stringstream floors(text);
  std::string one;
  int level = 0;
  while (std::getline(floors, one, '|')) {
    std::stringstream folders(one);
    std::string folder;
    while (folders >> folder) floor[folder] = level;
    ++level;
  }
  return floor;
}

// Every include of a declared folder that runs sideways or up, as "file:line: a -> b".
std::vector<std::string> violations(const fs::path& root, const std::map<std::string, int>& floor) {
  static const std::regex include(R"re(^\s*#\s*include\s*"([A-Za-z0-9_]+)/)re");
  std::vector<std::string> out;
  for (const auto& [folder, level] : floor) {
    if (!fs::is_directory(root / folder)) continue;
    for (const auto& entry : fs::recursive_directory_iterator(root / folder)) {
      const std::string ext = entry.path().extension().string();
      if (!entry.is_regular_file() || (ext != ".cpp" && ext != ".hpp" && ext != ".h")) continue;
      std::ifstream in(entry.path());
      std::string line;
      int number = 0;
      while (std::getline(in, line)) {
        ++number;
        std::smatch m;
        if (!std::regex_search(line, m, include)) continue;
        const std::string target = m[1];
        const auto it = floor.find(target);
        if (it == floor.end() || target == folder) continue;
        if (it->second >= level)
          out.push_back(fs::relative(entry.path(), root).string() + ":" + std::to_string(number) +
                        ": " + folder + " (floor " + std::to_string(level) + ") -> " + target +
                        " (floor " + std::to_string(it->second) + ")");
      }
    }
  }
  return out;
}

const std::map<std::string, int>& project_layers() {
  static const std::map<std::string, int> layers = parse_layers(PBDBENCH_LAYERS);
  return layers;
}

TEST(Layers, EveryIncludeRunsDown) {
  ASSERT_GE(project_layers().size(), 10u) << PBDBENCH_LAYERS;
  const std::vector<std::string> bad = violations(PBDBENCH_SOURCE_DIR, project_layers());
  std::string all;
  for (const std::string& b : bad) all += "\n  " + b;
  EXPECT_TRUE(bad.empty()) << bad.size() << " include(s) run sideways or up:" << all;
}

TEST(Layers, EveryLibraryFolderIsDeclared) {
  // A folder with a CMakeLists.txt of its own at the top is a library or a program: it must
  // have a floor, so that a new folder cannot slip past the rule.
  for (const auto& entry : fs::directory_iterator(PBDBENCH_SOURCE_DIR)) {
    if (!entry.is_directory() || !fs::exists(entry.path() / "CMakeLists.txt")) continue;
    const std::string name = entry.path().filename().string();
    if (name == "tests" || name == "benchmarks") continue;
    EXPECT_TRUE(project_layers().count(name)) << name << "/ has no floor in PBDBENCH_LAYERS";
  }
}

// config/ stands below the catalogue and links no solver family: its libraries (the closure of
// pbdbench_config's links, from CMake) include solver_api/ and not the catalogue, nor reference/
// (SUNDIALS, Ceres, CHOLMOD).
TEST(Layers, ConfigLinksNoReferenceSolver) {
  const std::string links = std::string(" ") + PBDBENCH_CONFIG_LINKS + " ";
  EXPECT_NE(links.find(" pbdbench_solver_api "), std::string::npos) << links;
  EXPECT_EQ(links.find(" pbdbench_catalog "), std::string::npos) << links;
  EXPECT_EQ(links.find(" pbdbench_reference "), std::string::npos) << links;
  EXPECT_LT(project_layers().at("config"), project_layers().at("catalog"));
}

// The scan itself: a tree with one include up, one sideways, and the allowed ones.
TEST(Layers, TheScanFindsAnArrowUpAndSideways) {
  pbdbench::testing::TempDir dir("layers");
  auto write = [&](const std::string& rel, const std::string& text) {
    fs::create_directories((dir.path() / rel).parent_path());
    std::ofstream(dir.path() / rel) << text;
  };
  write("low/a.hpp", "#pragma once\n#include <vector>\n#include \"low/b.hpp\"\n");
  write("low/b.cpp", "// x\n  #include \"high/c.hpp\"\n");  // up
  write("mid/d.hpp", "#include \"side/e.hpp\"\n#include \"low/a.hpp\"\n");  // sideways, down
  write("side/e.hpp", "#include \"unknown/f.hpp\"\n");  // not a declared folder: ignored
  write("high/c.hpp", "#include \"mid/d.hpp\"\n#include \"low/a.hpp\"\n");  // down, down
  const auto layers = parse_layers("low|mid side|high");
  const std::vector<std::string> bad = violations(dir.path(), layers);
  ASSERT_EQ(bad.size(), 2u);
  EXPECT_EQ(bad[0], "low/b.cpp:2: low (floor 0) -> high (floor 2)");
  EXPECT_EQ(bad[1], "mid/d.hpp:1: mid (floor 1) -> side (floor 1)");
}

}  // namespace
}  // namespace pbdbench::test
