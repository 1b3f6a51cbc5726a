// Shared helpers of the config tests.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "tests/temp_dir.hpp"

namespace pbdbench::config::testing {

// The scenario catalog: $PBDBENCH_SCENARIOS (set by CTest), else the source tree's scenarios/.
// Sets the variable when it is absent, so that scenarios_dir() agrees when the test program is run
// by hand.
inline std::filesystem::path catalog_dir() {
  const char* env = std::getenv("PBDBENCH_SCENARIOS");
  if (!env || !*env) {
    const std::string dir = std::string(PBDBENCH_SOURCE_DIR) + "/scenarios";
    setenv("PBDBENCH_SCENARIOS", dir.c_str(), 1);
    return dir;
  }
  return env;
}

// Set before any test runs, so that load("name") finds the catalog in every test.
inline const bool kCatalogEnvironmentSet = !catalog_dir().empty();

// The catalog's names: "<stem>" at its top level, "<folder>/<stem>" in a subfolder (failures/).
inline std::vector<std::string> catalog_names() {
  std::vector<std::string> names;
  const std::filesystem::path dir = catalog_dir();
  for (const auto& f : std::filesystem::recursive_directory_iterator(dir))
    if (f.path().extension() == ".toml")
      names.push_back((f.path().lexically_relative(dir).parent_path() / f.path().stem()).generic_string());
  std::sort(names.begin(), names.end());
  return names;
}

// The ConfigError that loading `text` (named `file`) with `overrides` throws; a test failure and
// an empty error when it loads.
inline ConfigError load_error(const std::string& text, const std::string& file = "bad.toml",
                              const std::vector<Override>& overrides = {}) {
  try {
    (void)load_text(text, file, overrides);
  } catch (const ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "expected a ConfigError loading:\n" << text;
  return ConfigError(Source{}, "", "(no error)");
}

inline std::vector<Override> sets(const std::vector<std::string>& texts) {
  std::vector<Override> out;
  for (const std::string& t : texts) out.push_back(parse_override(t));
  return out;
}

// A fresh directory under the system's temporary directory, removed with the object.
class TempDir : public pbdbench::testing::TempDir {
 public:
  explicit TempDir(const std::string& name) : pbdbench::testing::TempDir("config_" + name) {}
};

}  // namespace pbdbench::config::testing
