// Documentation read from the schema: describe_keys / describe_config (plain text for the
// terminal), list_scenarios (the catalog and its subfolders), and schema_markdown (the generated
// part of docs/scenarios.md).
#include <algorithm>
#include <filesystem>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "config/config.hpp"
#include "config/internal.hpp"
#include "solvers/pbd_material.hpp"

namespace pbdbench::config {

namespace {

using detail::format_bounds;
using detail::format_value;
using detail::type_label;

// The allowed values of a key, in words: its bounds or its choices.
std::string allowed(const KeySpec& k) {
  if (!k.choices.empty()) return "one of: " + fmt::format("{}", fmt::join(k.choices, ", "));
  return format_bounds(k);
}

const SceneKindInfo& kind_or_throw(const std::string& name) {
  if (const SceneKindInfo* info = detail::find_kind(name)) return *info;
  std::vector<std::string> names;
  for (const SceneKindInfo& k : scene_kinds()) names.push_back(k.name);
  std::string message = "'" + name + "' is not a scene kind";
  const std::string close = detail::suggest(name, names);
  if (!close.empty()) message += " (did you mean '" + close + "'?)";
  message += fmt::format("; the kinds are {}", fmt::join(names, ", "));
  throw ConfigError(Source{}, "scene.kind", message);
}

// The keys of a [[body]] entry, in the order a reader writes them: its placement keys, then its
// kind's scene keys (each KeySpec's path "body.<key>"). Every key the entry holds is listed.
std::vector<KeySpec> body_keys(const std::map<std::string, Entry>& body) {
  std::vector<KeySpec> out = body_placement_keys();
  const auto kind = body.find("body.kind");
  if (kind == body.end()) return out;
  if (const SceneKindInfo* info = detail::find_kind(std::get<std::string>(kind->second.value)))
    for (KeySpec k : info->keys) {
      k.path = "body." + k.path.substr(6);
      if (!detail::find_key(body_placement_keys(), k.path)) out.push_back(std::move(k));
    }
  return out;
}

// "body.2.cells" for the key "body.cells" of entry 2.
std::string body_key_name(std::size_t index, const std::string& path) {
  return "body." + std::to_string(index) + path.substr(4);
}

// A plain-text table: columns padded to their widest cell (at most kMaxColumn characters: a
// longer cell, such as a long description, overflows its column rather than widening it for
// every row), the last column left ragged.
std::string text_table(const std::vector<std::vector<std::string>>& rows) {
  constexpr std::size_t kMaxColumn = 40;
  if (rows.empty()) return "";
  std::vector<std::size_t> width(rows[0].size(), 0);
  for (const auto& r : rows)
    for (std::size_t i = 0; i + 1 < r.size(); ++i)
      width[i] = std::max(width[i], std::min(r[i].size(), kMaxColumn));
  std::string out;
  for (const auto& r : rows) {
    std::string line = " ";
    for (std::size_t i = 0; i < r.size(); ++i) {
      line += " " + r[i];
      if (i + 1 < r.size()) line += std::string(width[i] > r[i].size() ? width[i] - r[i].size() + 1 : 1, ' ');
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out += line + "\n";
  }
  return out;
}

std::vector<std::string> key_row(const KeySpec& k, const std::string& shown_path) {
  return {shown_path, type_label(k), format_value(k.default_value), k.units, allowed(k), k.doc};
}

const std::vector<std::string> kHeader = {"KEY", "TYPE", "DEFAULT", "UNITS", "ALLOWED", "DOC"};

std::string source_text(const Source& s) {
  if (s.file.empty()) return "default";
  if (s.line > 0) return s.file + ":" + std::to_string(s.line);
  return s.file;
}

std::string markdown_cell(std::string s) {
  std::string out;
  for (char c : s) {
    if (c == '|') out += "\\|";
    else out += c;
  }
  return out;
}

std::string code(const std::string& s) { return s.empty() ? "" : "`" + s + "`"; }

std::string markdown_allowed(const KeySpec& k) {
  if (!k.choices.empty()) {
    std::vector<std::string> quoted;
    for (const std::string& c : k.choices) quoted.push_back(code(c));
    return "one of " + fmt::format("{}", fmt::join(quoted, ", "));
  }
  return markdown_cell(format_bounds(k));
}

std::string markdown_table(const std::vector<KeySpec>& keys, bool with_types) {
  std::string out = with_types ? "| Key | Applies to | Type | Default | Units | Allowed | Description |\n"
                                 "|---|---|---|---|---|---|---|\n"
                               : "| Key | Type | Default | Units | Allowed | Description |\n"
                                 "|---|---|---|---|---|---|\n";
  for (const KeySpec& k : keys) {
    out += "| " + code(k.path) + " | ";
    if (with_types) out += fmt::format("{}", fmt::join(detail::collider_key_types(k.path), ", ")) + " | ";
    out += type_label(k) + " | " + markdown_cell(code(format_value(k.default_value))) + " | " +
           markdown_cell(k.units) + " | " + markdown_allowed(k) + " | " + markdown_cell(k.doc) + " |\n";
  }
  return out;
}

}  // namespace

std::string describe_keys(const std::string& scene_kind) {
  const SceneKindInfo& info = kind_or_throw(scene_kind);
  std::string out = fmt::format("Scene kind '{}': {}\n", info.name, info.doc);
  std::vector<std::vector<std::string>> rows = {kHeader};
  for (const KeySpec& k : common_keys()) rows.push_back(key_row(k, k.path));
  out += "\nCommon keys:\n" + text_table(rows);
  rows = {kHeader};
  for (const KeySpec& k : info.keys) rows.push_back(key_row(k, k.path));
  out += fmt::format("\nKeys of scene kind '{}':\n", info.name) + text_table(rows);
  rows = {{"KEY", "APPLIES TO", "TYPE", "DEFAULT", "UNITS", "ALLOWED", "DOC"}};
  for (const KeySpec& k : collider_keys()) {
    std::vector<std::string> r = key_row(k, k.path);
    r.insert(r.begin() + 1, fmt::format("{}", fmt::join(detail::collider_key_types(k.path), ", ")));
    rows.push_back(std::move(r));
  }
  out += "\nKeys of each [[collider]] entry:\n" + text_table(rows);
  return out;
}

std::string describe_config(const Config& config) {
  std::string out = fmt::format("Scenario '{}' ({})\n", config.scenario_name, config.file.string());
  const std::vector<std::string> header = {"KEY", "VALUE", "UNITS", "FROM", "DOC"};
  std::vector<std::vector<std::string>> rows = {header};
  auto add = [&rows](const KeySpec& k, const std::string& shown, const Entry& e) {
    rows.push_back({shown, format_value(e.value), k.units, source_text(e.source), k.doc});
  };
  for (const KeySpec& k : common_keys())
    if (config.has(k.path)) add(k, k.path, config.at(k.path));
  if (config.has("scene.kind"))
    if (const SceneKindInfo* info = detail::find_kind(config.get_string("scene.kind")))
      for (const KeySpec& k : info->keys)
        if (config.has(k.path)) add(k, k.path, config.at(k.path));
  for (std::size_t i = 0; i < config.colliders.size(); ++i)
    for (const KeySpec& k : collider_keys())
      if (auto it = config.colliders[i].find(k.path); it != config.colliders[i].end())
        add(k, "collider." + std::to_string(i) + k.path.substr(8), it->second);
  for (std::size_t i = 0; i < config.bodies.size(); ++i)
    for (const KeySpec& k : body_keys(config.bodies[i]))
      if (auto it = config.bodies[i].find(k.path); it != config.bodies[i].end())
        add(k, body_key_name(i, k.path), it->second);
  return out + text_table(rows);
}

namespace {

// Which solver reads a key: "" for every solver, else the family the key belongs to.
// pbd reads the *_stiffness keys only with solver.pbd.material = "stiffness"; pbd-seed (the seed
// article's listing) always, and no other solver.
bool solver_reads(const std::string& solver, std::optional<SolverFamily> family,
                  const std::string& pbd_material, const std::string& path) {
  const bool stiffness_reader = solver == "pbd-seed" || (solver == "pbd" && pbd_material == "stiffness");
  const bool pbd_family = solver == "pbd" || solver == "pbd-seed";
  auto ends_with = [&](const char* tail) {
    const std::string t(tail);
    return path.size() >= t.size() && path.compare(path.size() - t.size(), t.size(), t) == 0;
  };
  if (path.rfind("scene.", 0) == 0) {
    if (ends_with("_stiffness") || path == "scene.stiffness") return stiffness_reader;
    if (ends_with("_compliance") || path == "scene.compliance") return !stiffness_reader;
    if (ends_with("_damping") || path == "scene.damping") return !pbd_family;
    return true;
  }
  // A solver key: the families its row names (solver_api/options.hpp).
  if (const OptionRow* row = find_solver_option(path); row != nullptr && family)
    return option_applies(*row, *family);
  return true;
}

// Words of `text` in lines of at most `width` columns after `indent` spaces.
std::string wrap(const std::string& text, std::size_t indent, std::size_t width) {
  std::string out, line;
  std::istringstream words(text);
  std::string w;
  const std::size_t room = width > indent + 20 ? width - indent : 20;
  while (words >> w) {
    if (!line.empty() && line.size() + 1 + w.size() > room) {
      out += std::string(indent, ' ') + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + w;
  }
  if (!line.empty()) out += std::string(indent, ' ') + line + "\n";
  return out;
}

std::string short_source(const Source& s) {
  if (s.file.empty()) return "default";
  const std::string name = std::filesystem::path(s.file).filename().string();
  return s.line > 0 ? name + ":" + std::to_string(s.line) : s.file;
}

}  // namespace

std::string describe_config(const Config& config, bool all, std::size_t width,
                            std::optional<SolverFamily> family) {
  const std::string solver = config.has("solver.name") ? config.get_string("solver.name") : "";
  const std::string pbd_material =
      config.has("solver.pbd.material") ? config.get_string("solver.pbd.material") : "compliance";
  std::string out = wrap(fmt::format("Scenario '{}' ({}), solver {}{}", config.scenario_name,
                                     config.file.string(), solver,
                                     all ? "" : "; keys that this solver does not read are hidden (--all shows them)"),
                         0, width);
  std::size_t hidden = 0;
  auto add = [&](const KeySpec& k, const std::string& shown, const Entry& e) {
    // A body's kind keys are read as the scene's own ("body.edge_compliance" as
    // "scene.edge_compliance").
    const std::string read_as = k.path.rfind("body.", 0) == 0 ? "scene." + k.path.substr(5) : k.path;
    if (!all && !solver_reads(solver, family, pbd_material, read_as)) {
      ++hidden;
      return;
    }
    std::string value = format_value(e.value) + (k.units.empty() ? "" : " " + k.units);
    const std::string from = short_source(e.source);
    std::string head = "  " + shown + " = " + value;
    if (head.size() + 2 + from.size() <= width)
      out += head + std::string(width - head.size() - from.size(), ' ') + from + "\n";
    else
      out += wrap(shown + " = " + value, 2, width) + std::string(width > from.size() ? width - from.size() : 0, ' ') + from + "\n";
    // A body's kind key that the scene's own keys showed above is documented there.
    if (read_as == k.path || !config.has(read_as) || detail::find_key(body_placement_keys(), k.path))
      out += wrap(k.doc, 6, width);
  };
  for (const KeySpec& k : common_keys())
    if (config.has(k.path)) add(k, k.path, config.at(k.path));
  if (config.has("scene.kind"))
    if (const SceneKindInfo* info = detail::find_kind(config.get_string("scene.kind")))
      for (const KeySpec& k : info->keys)
        if (config.has(k.path)) add(k, k.path, config.at(k.path));
  for (std::size_t i = 0; i < config.colliders.size(); ++i)
    for (const KeySpec& k : collider_keys())
      if (auto it = config.colliders[i].find(k.path); it != config.colliders[i].end())
        add(k, "collider." + std::to_string(i) + k.path.substr(8), it->second);
  for (std::size_t i = 0; i < config.bodies.size(); ++i)
    for (const KeySpec& k : body_keys(config.bodies[i]))
      if (auto it = config.bodies[i].find(k.path); it != config.bodies[i].end())
        add(k, body_key_name(i, k.path), it->second);
  if (hidden > 0) out += fmt::format("  ({} keys of other solvers hidden)\n", hidden);
  if (family)
    for (const std::string& w : unread_solver_keys(config, *family)) out += wrap("warning: " + w, 2, width);

  // What the solver reads for each constraint group of the scene.
  try {
    const Scene scene = build_scene(config);
    const Model& m = scene.model;
    const SolverOptions o = solver_options(config);
    std::string what;
    if (solver == "pbd")
      what = fmt::format("k, PBD's stiffness per projection, Mueller et al. 2007 sec. 3.3; "
                         "solver.pbd.material = {}", pbd_material);
    else if (solver == "pbd-seed")
      what = "k, the seed listing's stiffness per projection; the *_compliance keys are not read";
    else
      what = "compliance alpha (inverse stiffness, 0 = rigid); the *_stiffness keys are not read";
    out += "\n" + wrap(fmt::format("Material as {} uses it, per constraint group ({}):", solver, what),
                       0, width);
    // What the solver uses for each group (solvers/pbd_material.hpp): pbd's k derived by the
    // rule or the explicit override, for this run's substep and iteration count.
    std::istringstream lines(material_text(m, o, run_options(config).dt));
    for (std::string line; std::getline(lines, line);) out += wrap(line, 2, width);
    if (solver == "pbd")
      if (const std::string problem = pbd_material_problem(m); !problem.empty())
        out += wrap("pbd refuses this scene: " + problem, 2, width);
  } catch (const std::exception& e) {
    out += wrap(std::string("(the scene cannot be built: ") + e.what() + ")", 2, width);
  }
  return out;
}

std::vector<ScenarioInfo> list_scenarios() {
  std::vector<ScenarioInfo> out;
  const std::filesystem::path dir = scenarios_dir();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) return out;
  // The catalog's top level and its subfolders (failures/...): a file in a subfolder is named
  // "<folder>/<stem>", the name resolve_scenario takes.
  for (const auto& f : std::filesystem::recursive_directory_iterator(dir, ec)) {
    if (!f.is_regular_file() || f.path().extension() != ".toml") continue;
    ScenarioInfo info;
    info.name = (f.path().lexically_relative(dir).parent_path() / f.path().stem()).generic_string();
    info.file = f.path();
    info.kind = "particle";
    try {
      const toml::table t = toml::parse_file(f.path().string());
      info.kind = t["scene"]["kind"].value_or(std::string("particle"));
      info.description = t["description"].value_or(std::string());
    } catch (const toml::parse_error& e) {
      info.description = fmt::format("(cannot be read: line {}: {})", e.source().begin.line, e.description());
    }
    out.push_back(std::move(info));
  }
  std::sort(out.begin(), out.end(), [](const ScenarioInfo& a, const ScenarioInfo& b) { return a.name < b.name; });
  return out;
}

std::string schema_markdown() {
  std::string out;
  out += "## Common keys\n\nEvery scenario has these keys, whatever its scene kind.\n\n";
  out += markdown_table(common_keys(), false);
  out += "\n## Collider keys\n\nEach `[[collider]]` entry takes these keys (written without the "
         "`collider.` prefix); a key that does not apply to the entry's type is an error. On the "
         "command line a collider key is addressed by index: `--set collider.0.friction=0.5`.\n\n";
  out += markdown_table(collider_keys(), true);
  out += "\n## Scene kinds\n\n`scene.kind` selects one of these; the other `scene.*` keys are "
         "those of the kind.\n";
  for (const SceneKindInfo& k : scene_kinds()) {
    out += fmt::format("\n### `{}`\n\n{}.\n\n", k.name, markdown_cell(k.doc));
    out += markdown_table(k.keys, false);
  }
  return out;
}

}  // namespace pbdbench::config
