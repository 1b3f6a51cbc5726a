// Scenario files are data with a schema. This module loads a scenario (a TOML file, or a name
// from scenarios/), applies command-line overrides, checks every key against the schema, and
// turns the result into the objects a run needs: the Scene (model + initial state), the solver's
// options and the run's options.
//
// Every error is a ConfigError naming the file, the key and the line:
//   scenarios/my.toml:12: solver.iterations = 0 is below the minimum 1
//   --set solver.iteratons=3: unknown key 'solver.iteratons' (did you mean 'solver.iterations'?)
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "core/state.hpp"
#include "metrics/metrics.hpp"
#include "solver_api/options.hpp"

namespace pbdbench::config {

// ---------------------------------------------------------------------------------------------
// Values and where they came from.
using Value = std::variant<bool, std::int64_t, double, std::string, std::vector<double>,
                           std::vector<std::int64_t>, std::vector<std::string>>;

struct Source {
  std::string file;  // the scenario file, "--set KEY=VALUE" for an override, "" for a default
  int line = 0;      // 1-based; 0 when not from a file
};

class ConfigError : public std::runtime_error {
 public:
  ConfigError(Source source, std::string key, const std::string& message);
  const Source& source() const { return source_; }
  const std::string& key() const { return key_; }

 private:
  Source source_;
  std::string key_;
};

// ---------------------------------------------------------------------------------------------
// The schema: one KeySpec per key, in tables declared once. The parser, `describe`, the
// validation errors and docs/scenarios.md all read these tables.
enum class Type { Bool, Int, Float, String, Vec3, FloatList, IntList, StringList };
const char* to_string(Type type);

struct KeySpec {
  std::string path;     // full dotted path: "time.dt", "scene.links", "collider.normal"
  Type type = Type::Float;
  Value default_value;  // of the matching alternative
  std::string units;    // "s", "m", "kg", "1", "" for none
  double min = -1e308;  // numeric bounds, applied to each element of a Vec3/list
  double max = 1e308;
  bool min_exclusive = false;
  bool max_exclusive = false;
  std::vector<std::string> choices;  // allowed values of a String / StringList, when not empty
  std::string doc;                   // one line
  std::size_t length = 0;            // required element count of a FloatList / IntList, 0 = any
};

// A kind of scene: the keys under [scene] that it accepts and how to build it.
struct SceneKindInfo {
  std::string name;  // the value of scene.kind: "particle", "chain", "cloth", ...
  std::string doc;
  std::vector<KeySpec> keys;  // paths "scene.<key>"
};

const std::vector<SceneKindInfo>& scene_kinds();

// Keys every scenario has whatever its scene kind: name, description, gravity, time.*, solver.*,
// output.*, limits.* (and the keys of a [[collider]] entry, paths "collider.<key>").
const std::vector<KeySpec>& common_keys();
const std::vector<KeySpec>& collider_keys();
// A [[body]] entry (paths "body.<key>"): its placement keys (kind, position, rotation, velocity,
// angular_velocity) here; the rest are its kind's scene keys, "scene.<key>" written "body.<key>".
// The kinds a body may be: chain, cloth, tet_block, mesh.
const std::vector<KeySpec>& body_placement_keys();
const std::vector<std::string>& body_kinds();

// ---------------------------------------------------------------------------------------------
// A resolved configuration: every key of the schema that applies, with its value and source.
struct Entry {
  Value value;
  Source source;
};

struct Config {
  std::string scenario_name;     // the scenario's `name`
  std::filesystem::path file;    // the scenario file it was loaded from
  std::map<std::string, Entry> entries;                 // path -> value (defaults filled in)
  std::vector<std::map<std::string, Entry>> colliders;  // one map per [[collider]], keys "collider.<key>"
  std::vector<std::map<std::string, Entry>> bodies;     // one map per [[body]], keys "body.<key>"

  bool has(const std::string& path) const;
  const Entry& at(const std::string& path) const;  // throws ConfigError when absent
  bool get_bool(const std::string& path) const;
  std::int64_t get_int(const std::string& path) const;
  double get_double(const std::string& path) const;  // also reads an Int
  const std::string& get_string(const std::string& path) const;
  Vec3 get_vec3(const std::string& path) const;
  const std::vector<double>& get_floats(const std::string& path) const;
  const std::vector<std::int64_t>& get_ints(const std::string& path) const;
  const std::vector<std::string>& get_strings(const std::string& path) const;

  // The whole resolved configuration as TOML, every key with its value (defaults included), in
  // schema order; loading this text again gives the same configuration.
  std::string to_toml() const;
};

// A command-line override "--set path=value". The value is TOML syntax (3, 0.5, true, "text",
// [0, -9.81, 0]); a bare word that is not valid TOML is taken as a string (--set solver.name=pbd).
// Collider keys are addressed by index: collider.0.offset.
struct Override {
  std::string path;
  std::string value_text;
};
// Parses "path=value"; throws ConfigError (file "--set ...") when there is no '='.
Override parse_override(const std::string& text);

// The candidate closest to `word` when it is close enough to be a likely typo, else "" (for
// "did you mean" in messages about names other than keys: subcommands, solvers).
std::string suggest_name(const std::string& word, const std::vector<std::string>& candidates);

// Where scenario names are looked up: $PBDBENCH_SCENARIOS when set, else data_dir()/scenarios
// (config/data_dir.hpp).
std::filesystem::path scenarios_dir();

// A path to an existing file, or a catalog name ("hanging_cloth" -> scenarios/hanging_cloth.toml).
// Throws ConfigError when neither exists, listing the catalog.
std::filesystem::path resolve_scenario(const std::string& name_or_path);

// Loads, applies the overrides in order, and validates: unknown keys (with a suggestion), wrong
// types, values out of range or not in `choices`, NaN and infinities, and anything the scene
// builder refuses. Throws ConfigError.
Config load(const std::string& name_or_path, const std::vector<Override>& overrides = {});
// The same from text (for tests); `file` names it in errors.
Config load_text(const std::string& toml_text, const std::filesystem::path& file,
                 const std::vector<Override>& overrides = {});

// ---------------------------------------------------------------------------------------------
// What a run needs, built from a validated Config.

// The model and initial state. Throws ConfigError pointing at the responsible key when the
// model is unsound (core/model_checks.hpp): a degenerate mesh names scene.file and the element.
Scene build_scene(const Config& config);

SolverOptions solver_options(const Config& config);

// The solver keys the scenario sets (in its file or with --set) that `family`, the family of its
// solver (the catalogue's, catalog/, above), does not read (solver_api/options.hpp,
// OptionRow::families): one line each naming the key, where it was set, the solver and the
// families that read it:
//   "solver.seed.fixes (s.toml:7) is set but pbd does not read it (an option of pbd-seed)"
// Such a key is accepted, as `describe` hides it rather than refusing it (an experiment may set
// one family's options for all its runs and switch solver.name in one of them); `pbdbench run`
// and `describe` show these lines as warnings.
std::vector<std::string> unread_solver_keys(const Config& config, SolverFamily family);

struct RunOptions {
  double dt = 1.0 / 60.0;  // time.dt: s
  double duration = 1.0;   // time.duration: s; steps = round(duration / dt)
  int frame_every = 0;     // output.frame_every: write positions and velocities every k steps
                           // (and the last); 0: every_frame() below
  ExplosionLimits limits;  // limits.*
  long steps() const;
  // The steps between frames: frame_every, or for 0 the steps nearest 1/60 s of simulated time
  // (at least 1): a smooth animation at 60 frames a second of simulated time.
  long every_frame() const;
};
RunOptions run_options(const Config& config);

// ---------------------------------------------------------------------------------------------
// Documentation.

// A scenario's keys (common, collider, and its scene kind's) with types, defaults, units, ranges
// and docs, as a plain-text table; with a Config, the values it resolved to and their sources.
std::string describe_keys(const std::string& scene_kind);
std::string describe_config(const Config& config);
// The same for a reader, in `width` columns (each key on one line, its doc wrapped below it):
// the solver's own keys only (the solver keys its `family` does not read, the catalogue's
// family of solver.name, and the *_stiffness or *_compliance keys the solver does not read are
// hidden unless `all`; every solver key is shown without a family), the warnings of
// unread_solver_keys, then, per constraint group of the built scene, the material value the
// chosen solver uses.
std::string describe_config(const Config& config, bool all, std::size_t width,
                            std::optional<SolverFamily> family = std::nullopt);

// The scenario files in scenarios_dir() and its subfolders, sorted: name ("hanging_chain",
// "failures/zero_rest_length"), scene kind, description.
struct ScenarioInfo {
  std::string name;
  std::string kind;
  std::string description;
  std::filesystem::path file;
};
std::vector<ScenarioInfo> list_scenarios();

// Every table of the schema (common keys, collider keys, each scene kind) as Markdown: the
// generated part of docs/scenarios.md.
std::string schema_markdown();

}  // namespace pbdbench::config
