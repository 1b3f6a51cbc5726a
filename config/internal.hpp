// Helpers shared by the files of config/ (and its tests); not part of the module's interface.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "config/config.hpp"
#include "core/model.hpp"

namespace pbdbench::config::detail {

// ---------------------------------------------------------------------------------------------
// Schema lookups (config/schema.cpp).

// The spec of `path` in `keys`, or nullptr.
const KeySpec* find_key(const std::vector<KeySpec>& keys, const std::string& path);
// The scene kind called `name`, or nullptr.
const SceneKindInfo* find_kind(const std::string& name);
// The collider types ("plane", "sphere") a collider key ("collider.radius") applies to.
const std::vector<std::string>& collider_key_types(const std::string& path);
bool collider_key_applies(const std::string& path, const std::string& type);

// The names of the collider motion keys / pin motion keys, in the order
// kind, velocity, amplitude, axis, radius, frequency, start, stop.
std::vector<std::string> motion_key_paths(const std::string& prefix);

// ---------------------------------------------------------------------------------------------
// Spelling suggestions (config/schema.cpp).

// Optimal string alignment distance (insertions, deletions, substitutions, transpositions).
std::size_t edit_distance(std::string_view a, std::string_view b);
// The candidate closest to `word` when it is close enough to be a likely typo, else "".
// A candidate whose last dotted component equals the word's last component also qualifies
// (`iterations` at the top level suggests `solver.iterations`).
std::string suggest(const std::string& word, const std::vector<std::string>& candidates);

// ---------------------------------------------------------------------------------------------
// Formatting (config/schema.cpp).

// Shortest text that reads back as the same double, always with a '.' or an exponent so that
// TOML reads it as a float ("1.0", "0.016666666666666666", "1e-08").
std::string format_double(double value);
// A value in TOML syntax: true, 3, 0.5, "text", [0.0, -9.81, 0.0], ["D1", "D2"].
std::string format_value(const Value& value);
// The bounds of a numeric key: "(0, 1]", ">= 0", "> 0", "[1, 100000]", "" when unbounded.
std::string format_bounds(const KeySpec& spec);
// "float", "int", "vec3", "list of 2 ints", ...
std::string type_label(const KeySpec& spec);

// ---------------------------------------------------------------------------------------------
// SolverOptions from [solver] keys (config/load.cpp): sets the field that `path` maps onto.
// Throws std::invalid_argument for a path that is not a solver key.
void set_solver_option(SolverOptions& options, const std::string& path, const Value& value);

}  // namespace pbdbench::config::detail
