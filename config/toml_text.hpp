// TOML values written back as override text, for the files that hold overrides as TOML tables
// (sweep files, claim experiment files): `[set] "solver.iterations" = 5` becomes the override
// "solver.iterations" = "5", parsed again by the scenario loader like a --set value.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <toml++/toml.h>

#include "config/config.hpp"

namespace pbdbench::config {

// Where a node of `file` is: {file, line}.
Source source_of(const std::filesystem::path& file, const toml::source_region& region);

// A TOML value as text that is both valid TOML and valid JSON (strings double-quoted and
// escaped, floats in shortest round-trip form with a decimal point or exponent). Throws
// ConfigError for tables, dates and non-finite numbers.
std::string toml_value_text(const toml::node& node, const std::filesystem::path& file);

// A table's leaves as dotted paths, in the order the keys appear in the file: both
// `"solver.iterations" = 5` and `[solver] iterations = 5` give "solver.iterations".
struct FlatEntry {
  std::string path;
  const toml::node* node = nullptr;
  int line = 0;
};
std::vector<FlatEntry> flatten_table(const toml::table& table, const std::string& prefix = "");

}  // namespace pbdbench::config
