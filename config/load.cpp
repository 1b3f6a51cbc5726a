// Loading a scenario: TOML parsing, --set overrides, validation against the schema, the Config
// accessors, to_toml, and the option structs a run needs.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "config/config.hpp"
#include "config/data_dir.hpp"
#include "config/internal.hpp"

namespace pbdbench::config {

namespace {

using detail::find_key;

constexpr double kMaxSteps = 1e12;  // steps a run may plan (a long holds them; 11 days at 1 us a step)
using detail::format_double;
using detail::format_value;
using detail::suggest;

// ---------------------------------------------------------------------------------------------
// Raw (not yet validated) values with their sources.
struct Raw {
  std::string path;  // the schema path: "solver.iterations", "collider.radius"
  std::string name;  // the path as shown to the user: "solver.iterations", "collider.0.radius"
  const toml::node* node = nullptr;
  Source source;
  double order = 0;  // file position, or after the whole file for overrides (in their order)
  bool empty_table = false;  // an empty table, e.g. `[solver.pbd]` with nothing under it
};
using RawMap = std::map<std::string, Raw>;  // keyed by path

struct RawCollider {
  RawMap keys;
  Source source;  // the [[collider]] header
};

double position_of(const toml::node& node) {
  const auto& b = node.source().begin;
  return static_cast<double>(b.line) * 1e6 + static_cast<double>(b.column);
}

// "body.size" -> "body.0.size"
std::string body_name(int index, const std::string& path) {
  return "body." + std::to_string(index) + path.substr(std::string("body").size());
}

std::string collider_name(int index, const std::string& path) {
  // "collider.radius" -> "collider.0.radius"
  return "collider." + std::to_string(index) + path.substr(std::string("collider").size());
}

[[noreturn]] void fail(const Source& source, const std::string& key, const std::string& message) {
  throw ConfigError(source, key, message);
}

// Every dotted path below `table`, tables flattened; arrays are values.
void flatten(const toml::table& table, const std::string& prefix, const std::string& file,
             RawMap& out) {
  for (auto&& [key, node] : table) {
    const std::string path = prefix + std::string(key.str());
    if (const toml::table* sub = node.as_table(); sub && !sub->empty()) {
      flatten(*sub, path + ".", file, out);
      continue;
    }
    Raw raw;
    raw.path = path;
    raw.name = path;
    raw.node = &node;
    raw.source = Source{file, static_cast<int>(key.source().begin.line)};
    raw.order = position_of(node);
    raw.empty_table = node.is_table();
    out[path] = raw;
  }
}

// ---------------------------------------------------------------------------------------------
// Describing values and nodes in messages.
std::string number_text(double v) { return fmt::format("{}", v); }

std::string node_text(const toml::node& node) {
  if (auto v = node.as_boolean()) return v->get() ? "true" : "false";
  if (auto v = node.as_integer()) return std::to_string(v->get());
  if (auto v = node.as_floating_point()) return number_text(v->get());
  if (auto v = node.as_string()) return "'" + v->get() + "'";
  if (auto a = node.as_array()) {
    std::string s = "[";
    for (std::size_t i = 0; i < a->size(); ++i) s += (i ? ", " : "") + node_text((*a)[i]);
    return s + "]";
  }
  if (node.is_table()) return "a table";
  std::ostringstream o;
  if (auto v = node.as_date()) o << v->get();
  else if (auto v = node.as_time()) o << v->get();
  else if (auto v = node.as_date_time()) o << v->get();
  return o.str();
}

std::string node_kind(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::boolean: return "the boolean " + node_text(node);
    case toml::node_type::integer: return "the integer " + node_text(node);
    case toml::node_type::floating_point: return "the float " + node_text(node);
    case toml::node_type::string: return "the string " + node_text(node);
    case toml::node_type::array: return "the array " + node_text(node);
    case toml::node_type::table: return "a table";
    case toml::node_type::date: return "the date " + node_text(node);
    case toml::node_type::time: return "the time " + node_text(node);
    case toml::node_type::date_time: return "the date-time " + node_text(node);
    default: return "nothing";
  }
}

std::string expected_text(const KeySpec& spec) {
  switch (spec.type) {
    case Type::Bool: return "true or false";
    case Type::Int: return "an integer";
    case Type::Float: return "a number";
    case Type::String: return "a string";
    case Type::Vec3: return "an array of 3 numbers [x, y, z]";
    case Type::FloatList:
      return spec.length ? fmt::format("an array of {} numbers", spec.length) : "an array of numbers";
    case Type::IntList:
      return spec.length ? fmt::format("an array of {} integers", spec.length) : "an array of integers";
    case Type::StringList: return "an array of strings";
  }
  return "a value";
}

std::string with_units(const std::string& number, const KeySpec& spec) {
  if (spec.units.empty() || spec.units == "1") return number;
  return number + " " + spec.units;
}

// ---------------------------------------------------------------------------------------------
// Converting one raw value to a Value of the spec's type, or failing with a message.
class Converter {
 public:
  Converter(const KeySpec& spec, const Raw& raw) : spec_(spec), raw_(raw) {}

  Value convert() const {
    const toml::node& n = *raw_.node;
    switch (spec_.type) {
      case Type::Bool:
        if (!n.is_boolean()) wrong_type(n);
        return n.as_boolean()->get();
      case Type::Int: return integer(n, raw_.name);
      case Type::Float: return number(n, raw_.name);
      case Type::String: return text(n, raw_.name);
      case Type::Vec3:
      case Type::FloatList: {
        const toml::array& a = array(n);
        std::vector<double> out;
        for (std::size_t i = 0; i < a.size(); ++i) out.push_back(number(a[i], element(i)));
        return out;
      }
      case Type::IntList: {
        const toml::array& a = array(n);
        std::vector<std::int64_t> out;
        for (std::size_t i = 0; i < a.size(); ++i) out.push_back(integer(a[i], element(i)));
        return out;
      }
      case Type::StringList: {
        const toml::array& a = array(n);
        std::vector<std::string> out;
        for (std::size_t i = 0; i < a.size(); ++i) out.push_back(text(a[i], element(i)));
        return out;
      }
    }
    wrong_type(n);
  }

 private:
  std::string element(std::size_t i) const { return raw_.name + "[" + std::to_string(i) + "]"; }

  // The line of an element of a multi-line array is its own.
  Source source_of(const toml::node& n) const {
    Source s = raw_.source;
    if (s.line > 0 && &n != raw_.node) s.line = static_cast<int>(n.source().begin.line);
    return s;
  }

  [[noreturn]] void wrong_type(const toml::node& n) const {
    std::string message = raw_.name + ": expected " + expected_text(spec_) + ", got " + node_kind(n);
    if (spec_.type == Type::Int && n.is_floating_point())
      message += " (a float is not accepted where an integer is expected)";
    fail(source_of(n), raw_.name, message);
  }

  [[noreturn]] void wrong_element(const toml::node& n, const std::string& name,
                                  const std::string& what) const {
    fail(source_of(n), raw_.name, name + ": expected " + what + ", got " + node_kind(n));
  }

  const toml::array& array(const toml::node& n) const {
    const toml::array* a = n.as_array();
    if (!a) wrong_type(n);
    if (spec_.type == Type::Vec3 && a->size() != 3)
      fail(raw_.source, raw_.name,
           fmt::format("{}: expected an array of 3 numbers [x, y, z], got {} element{} {}",
                       raw_.name, a->size(), a->size() == 1 ? "" : "s", node_text(n)));
    if (spec_.length && a->size() != spec_.length)
      fail(raw_.source, raw_.name,
           fmt::format("{}: expected {}, got {} element{} {}", raw_.name, expected_text(spec_),
                       a->size(), a->size() == 1 ? "" : "s", node_text(n)));
    return *a;
  }

  void check_range(double v, const toml::node& n, const std::string& name) const {
    const std::string value = with_units(number_text(v), spec_);
    auto bound = [&](double b) { return with_units(number_text(b), spec_); };
    if (spec_.min_exclusive ? !(v > spec_.min) : !(v >= spec_.min))
      fail(source_of(n), raw_.name,
           spec_.min_exclusive
               ? fmt::format("{} = {} must be greater than {}", name, value, bound(spec_.min))
               : fmt::format("{} = {} is below the minimum {}", name, value, bound(spec_.min)));
    if (spec_.max_exclusive ? !(v < spec_.max) : !(v <= spec_.max))
      fail(source_of(n), raw_.name,
           spec_.max_exclusive
               ? fmt::format("{} = {} must be less than {}", name, value, bound(spec_.max))
               : fmt::format("{} = {} is above the maximum {}", name, value, bound(spec_.max)));
  }

  std::int64_t integer(const toml::node& n, const std::string& name) const {
    if (!n.is_integer()) {
      if (&n == raw_.node) wrong_type(n);
      std::string what = "an integer";
      if (n.is_floating_point()) what += " (a float is not accepted where an integer is expected)";
      wrong_element(n, name, what);
    }
    const std::int64_t v = n.as_integer()->get();
    check_range(static_cast<double>(v), n, name);
    return v;
  }

  double number(const toml::node& n, const std::string& name) const {
    double v = 0;
    if (auto i = n.as_integer()) v = static_cast<double>(i->get());
    else if (auto f = n.as_floating_point()) v = f->get();
    else if (&n == raw_.node) wrong_type(n);
    else wrong_element(n, name, "a number");
    if (!std::isfinite(v))
      fail(source_of(n), raw_.name, fmt::format("{} = {} is not a finite number", name, number_text(v)));
    check_range(v, n, name);
    return v;
  }

  std::string text(const toml::node& n, const std::string& name) const {
    if (!n.is_string()) {
      if (&n == raw_.node) wrong_type(n);
      wrong_element(n, name, "a string");
    }
    std::string v = n.as_string()->get();
    if (!spec_.choices.empty() &&
        std::find(spec_.choices.begin(), spec_.choices.end(), v) == spec_.choices.end()) {
      std::string message = fmt::format("{} = '{}' is not one of {}", name, v,
                                        fmt::join(spec_.choices, ", "));
      const std::string close = suggest(v, spec_.choices);
      if (!close.empty()) message += " (did you mean '" + close + "'?)";
      fail(source_of(n), raw_.name, message);
    }
    return v;
  }

  const KeySpec& spec_;
  const Raw& raw_;
};

std::vector<std::string> paths_of(const std::vector<KeySpec>& keys, const std::string& strip = "") {
  std::vector<std::string> out;
  for (const KeySpec& k : keys) out.push_back(k.path.substr(strip.size()));
  return out;
}

// Every key of the common table and of every scene kind (the paths --set may name).
std::vector<std::string> all_paths() {
  std::vector<std::string> out = paths_of(common_keys());
  for (const SceneKindInfo& kind : scene_kinds())
    for (const KeySpec& k : kind.keys)
      if (std::find(out.begin(), out.end(), k.path) == out.end()) out.push_back(k.path);
  return out;
}

// Whether `path` names a table of the schema ("solver", "solver.pbd", "scene").
bool is_table_path(const std::string& path) {
  for (const std::string& p : all_paths())
    if (p.rfind(path + ".", 0) == 0) return true;
  return false;
}

// A key as shown in a message: a very long one is cut, with its length.
std::string shown_key(const std::string& name) {
  constexpr std::size_t kShown = 80;
  if (name.size() <= kShown) return name;
  return name.substr(0, kShown) + fmt::format("... ({} characters)", name.size());
}

std::string unknown_message(const std::string& name, const std::string& close) {
  std::string message = "unknown key '" + shown_key(name) + "'";
  if (!close.empty()) message += " (did you mean '" + close + "'?)";
  return message;
}

// ---------------------------------------------------------------------------------------------
// The loader.
class Loader {
 public:
  Loader(const std::string& text, const std::filesystem::path& file) : file_(file) {
    file_name_ = file.string();
    try {
      table_ = toml::parse(std::string_view(text), std::string_view(file_name_));
    } catch (const toml::parse_error& e) {
      const auto& b = e.source().begin;
      fail(Source{file_name_, static_cast<int>(b.line)}, "",
           fmt::format("TOML syntax error (column {}): {}", b.column, e.description()));
    }
    for (auto&& [key, node] : table_) {
      if (key.str() == "collider") {
        read_colliders(node);
        continue;
      }
      if (key.str() == "body") {
        read_bodies(node);
        continue;
      }
      if (const toml::table* sub = node.as_table(); sub && !sub->empty()) {
        flatten(*sub, std::string(key.str()) + ".", file_name_, top_);
        continue;
      }
      Raw raw;
      raw.path = raw.name = std::string(key.str());
      raw.node = &node;
      raw.source = Source{file_name_, static_cast<int>(key.source().begin.line)};
      raw.order = position_of(node);
      raw.empty_table = node.is_table();
      top_[raw.path] = raw;
    }
  }

  void apply(const Override& o, std::size_t index) {
    const std::string set = "--set " + o.path + "=" + o.value_text;
    const Source source{set, 0};
    const toml::node* node = parse_value(o.value_text);
    Raw raw;
    raw.node = node;
    raw.source = source;
    raw.order = 1e15 + static_cast<double>(index);  // after everything in the file
    if (o.path.rfind("body.", 0) == 0) {
      // body.<index>.<key>: checked against the body's kind when resolved
      const std::string rest = o.path.substr(5);
      const auto dot = rest.find('.');
      const std::string index_text = rest.substr(0, dot);
      std::size_t i = 0;
      const auto [end, ec] = std::from_chars(index_text.data(), index_text.data() + index_text.size(), i);
      if (dot == std::string::npos || ec != std::errc() ||
          end != index_text.data() + index_text.size() || i >= bodies_.size())
        fail(source, o.path,
             fmt::format("a body key is addressed as body.<index>.<key> with an index below the "
                         "file's {} [[body]] entr{}, e.g. body.0.position",
                         bodies_.size(), bodies_.size() == 1 ? "y" : "ies"));
      raw.path = "body." + rest.substr(dot + 1);
      raw.name = o.path;
      bodies_[i].keys[raw.path] = raw;
      return;
    }
    if (o.path.rfind("collider.", 0) == 0) {
      // collider.<index>.<key>
      const std::string rest = o.path.substr(9);
      const auto dot = rest.find('.');
      const std::string index_text = rest.substr(0, dot);
      const bool numeric = !index_text.empty() &&
                           std::all_of(index_text.begin(), index_text.end(),
                                       [](char c) { return c >= '0' && c <= '9'; });
      if (dot == std::string::npos || !numeric)
        fail(source, o.path,
             "a collider key is addressed as collider.<index>.<key>, e.g. collider.0.offset");
      std::size_t i = 0;
      const auto [end, ec] = std::from_chars(index_text.data(), index_text.data() + index_text.size(), i);
      if (ec != std::errc() || end != index_text.data() + index_text.size() || i >= colliders_.size())
        fail(source, o.path,
             fmt::format("there is no collider {}: the file declares {} [[collider]] entr{}; to add "
                         "a collider, declare it in the file",
                         shown_key(index_text), colliders_.size(), colliders_.size() == 1 ? "y" : "ies"));
      raw.path = "collider." + rest.substr(dot + 1);
      raw.name = o.path;
      if (!find_key(collider_keys(), raw.path)) {
        const std::string close = suggest(raw.path, paths_of(collider_keys()));
        fail(source, o.path,
             unknown_message(o.path, close.empty() ? "" : collider_name(static_cast<int>(i), close)));
      }
      colliders_[i].keys[raw.path] = raw;
      return;
    }
    const std::vector<std::string> known = all_paths();
    if (std::find(known.begin(), known.end(), o.path) == known.end())
      fail(source, o.path, unknown_message(o.path, suggest(o.path, known)));
    raw.path = raw.name = o.path;
    top_[raw.path] = raw;
  }

  Config resolve() {
    Config config;
    config.file = file_;

    // The scene kind decides which scene.* keys exist.
    const KeySpec& kind_spec = *find_key(common_keys(), "scene.kind");
    std::string kind = std::get<std::string>(kind_spec.default_value);
    if (auto it = top_.find("scene.kind"); it != top_.end())
      kind = std::get<std::string>(Converter(kind_spec, it->second).convert());
    const SceneKindInfo& info = *detail::find_kind(kind);

    // Each collider's type decides which collider keys apply.
    const KeySpec& type_spec = *find_key(collider_keys(), "collider.type");
    std::vector<std::string> types;
    for (std::size_t i = 0; i < colliders_.size(); ++i) {
      std::string type = std::get<std::string>(type_spec.default_value);
      if (auto it = colliders_[i].keys.find("collider.type"); it != colliders_[i].keys.end())
        type = std::get<std::string>(Converter(type_spec, it->second).convert());
      types.push_back(type);
    }

    // Everything, in the order it was written, so that the first error is the first in the file.
    struct Item {
      const Raw* raw;
      int collider;
    };
    std::vector<Item> items;
    for (const auto& [path, raw] : top_) items.push_back({&raw, -1});
    for (std::size_t i = 0; i < colliders_.size(); ++i)
      for (const auto& [path, raw] : colliders_[i].keys) items.push_back({&raw, static_cast<int>(i)});
    std::stable_sort(items.begin(), items.end(),
                     [](const Item& a, const Item& b) { return a.raw->order < b.raw->order; });

    std::vector<std::string> valid = paths_of(common_keys());
    for (const std::string& p : paths_of(info.keys)) valid.push_back(p);
    config.colliders.resize(colliders_.size());

    for (const Item& item : items) {
      const Raw& raw = *item.raw;
      if (item.collider < 0) {
        if (raw.empty_table && is_table_path(raw.path)) continue;  // e.g. an empty [solver.pbd]
        const KeySpec* spec = find_key(common_keys(), raw.path);
        if (!spec) spec = find_key(info.keys, raw.path);
        if (!spec) unknown_key(raw, kind, valid);
        config.entries[raw.path] = Entry{Converter(*spec, raw).convert(), raw.source};
      } else {
        const std::string& type = types[static_cast<std::size_t>(item.collider)];
        const std::string name = collider_name(item.collider, raw.path);
        const std::string leaf = raw.path.substr(9);
        const KeySpec* spec = find_key(collider_keys(), raw.path);
        if (!spec) {
          std::string message = fmt::format("unknown key '{}' in [[collider]] entry {}", leaf, item.collider);
          std::vector<std::string> candidates;
          for (const KeySpec& k : collider_keys())
            if (detail::collider_key_applies(k.path, type)) candidates.push_back(k.path.substr(9));
          const std::string close = suggest(leaf, candidates);
          if (!close.empty()) message += " (did you mean '" + close + "'?)";
          fail(raw.source, name, message);
        }
        if (!detail::collider_key_applies(raw.path, type)) {
          std::vector<std::string> own;
          for (const KeySpec& k : collider_keys())
            if (detail::collider_key_applies(k.path, type)) own.push_back(k.path.substr(9));
          fail(raw.source, name,
               fmt::format("key '{}' does not apply to a collider of type '{}' ([[collider]] entry "
                           "{}; a {} takes {})",
                           leaf, type, item.collider, type, fmt::join(own, ", ")));
        }
        Raw named = raw;
        named.name = name;
        config.colliders[static_cast<std::size_t>(item.collider)][raw.path] =
            Entry{Converter(*spec, named).convert(), raw.source};
      }
    }

    // Defaults for every applicable key that was not given.
    for (const KeySpec& k : common_keys())
      if (!config.entries.count(k.path)) config.entries[k.path] = Entry{k.default_value, Source{}};
    for (const KeySpec& k : info.keys)
      if (!config.entries.count(k.path)) config.entries[k.path] = Entry{k.default_value, Source{}};
    if (!top_.count("name")) {
      const std::string stem = file_.stem().string();
      config.entries["name"] = Entry{stem.empty() ? std::string("unnamed") : stem, Source{}};
    }
    for (std::size_t i = 0; i < colliders_.size(); ++i)
      for (const KeySpec& k : collider_keys())
        if (detail::collider_key_applies(k.path, types[i]) && !config.colliders[i].count(k.path))
          config.colliders[i][k.path] = Entry{k.default_value, Source{}};
    resolve_bodies(config);
    config.scenario_name = config.get_string("name");

    check_cross_keys(config);
    return config;
  }

 private:
  // The [[body]] entries: each one's kind decides its keys (that kind's scene keys, written
  // without 'scene.'); placement keys besides. Errors name the entry, the key and its line.
  void resolve_bodies(Config& config) const {
    const KeySpec& kind_spec = *find_key(body_placement_keys(), "body.kind");
    config.bodies.resize(bodies_.size());
    for (std::size_t i = 0; i < bodies_.size(); ++i) {
      const int index = static_cast<int>(i);
      const RawMap& raws = bodies_[i].keys;
      auto kit = raws.find("body.kind");
      if (kit == raws.end())
        fail(bodies_[i].source, body_name(index, "body.kind"),
             fmt::format("[[body]] entry {} has no kind: write kind = one of {}", i,
                         fmt::join(body_kinds(), ", ")));
      const std::string kind = std::get<std::string>(Converter(kind_spec, kit->second).convert());
      const SceneKindInfo& info = *detail::find_kind(kind);
      std::vector<const Raw*> items;
      for (const auto& [path, raw] : raws) items.push_back(&raw);
      std::stable_sort(items.begin(), items.end(),
                       [](const Raw* a, const Raw* b) { return a->order < b->order; });
      auto& out = config.bodies[i];
      for (const Raw* raw : items) {
        const std::string leaf = raw->path.substr(5);
        KeySpec spec;
        if (const KeySpec* p = find_key(body_placement_keys(), raw->path)) {
          spec = *p;
        } else if (const KeySpec* k = find_key(info.keys, "scene." + leaf)) {
          spec = *k;
          spec.path = raw->path;
        } else {
          std::vector<std::string> own;
          for (const KeySpec& p : body_placement_keys()) own.push_back(p.path.substr(5));
          for (const KeySpec& k : info.keys) own.push_back(k.path.substr(6));
          std::string message = fmt::format("unknown key '{}' in [[body]] entry {} (a {} body)",
                                            leaf, i, kind);
          const std::string close = suggest(leaf, own);
          if (!close.empty()) message += " (did you mean '" + close + "'?)";
          fail(raw->source, body_name(index, raw->path), message);
        }
        out[raw->path] = Entry{Converter(spec, *raw).convert(), raw->source};
      }
      for (const KeySpec& p : body_placement_keys())
        if (!out.count(p.path)) out[p.path] = Entry{p.default_value, Source{}};
      for (const KeySpec& k : info.keys) {
        const std::string path = "body." + k.path.substr(6);
        if (!out.count(path)) out[path] = Entry{k.default_value, Source{}};
      }
    }
  }

  void read_bodies(const toml::node& node) {
    const Source source{file_name_, static_cast<int>(node.source().begin.line)};
    const toml::array* a = node.as_array();
    if (!a || node.is_table())
      fail(source, "body", "bodies are an array of tables: write each as [[body]]");
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::node& e = (*a)[i];
      const Source es{file_name_, static_cast<int>(e.source().begin.line)};
      const toml::table* t = e.as_table();
      if (!t) fail(es, "body", fmt::format("body entry {} is not a table: write it as [[body]]", i));
      RawCollider b;
      b.source = es;
      flatten(*t, "body.", file_name_, b.keys);
      for (auto& [path, raw] : b.keys) raw.name = body_name(static_cast<int>(i), path);
      bodies_.push_back(std::move(b));
    }
  }

  void read_colliders(const toml::node& node) {
    const Source source{file_name_, static_cast<int>(node.source().begin.line)};
    if (node.is_table())
      fail(source, "collider",
           "'collider' is a table; colliders are an array of tables: write each as [[collider]]");
    const toml::array* a = node.as_array();
    if (!a) fail(source, "collider", "'collider' must be an array of tables: write each as [[collider]]");
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::node& e = (*a)[i];
      const Source es{file_name_, static_cast<int>(e.source().begin.line)};
      const toml::table* t = e.as_table();
      if (!t) fail(es, "collider", fmt::format("collider entry {} is not a table: write it as [[collider]]", i));
      RawCollider c;
      c.source = es;
      flatten(*t, "collider.", file_name_, c.keys);
      for (auto& [path, raw] : c.keys) raw.name = collider_name(static_cast<int>(i), path);
      colliders_.push_back(std::move(c));
    }
  }

  // An override's value: TOML syntax, or the text itself as a string when it does not parse.
  const toml::node* parse_value(const std::string& text) {
    try {
      toml::table t = toml::parse(std::string_view("v = " + text), std::string_view("--set"));
      if (t.size() == 1 && t.contains("v")) {
        override_tables_.push_back(std::move(t));
        return override_tables_.back().get("v");
      }
    } catch (const toml::parse_error&) {
    }
    toml::table t;
    std::string trimmed = text;
    trimmed.erase(0, trimmed.find_first_not_of(" \t"));
    trimmed.erase(trimmed.find_last_not_of(" \t") + 1);
    t.insert("v", trimmed);
    override_tables_.push_back(std::move(t));
    return override_tables_.back().get("v");
  }

  [[noreturn]] void unknown_key(const Raw& raw, const std::string& kind,
                                const std::vector<std::string>& valid) const {
    // A key of another scene kind.
    for (const SceneKindInfo& other : scene_kinds()) {
      if (other.name == kind) continue;
      if (find_key(other.keys, raw.path))
        fail(raw.source, raw.name,
             fmt::format("unknown key '{}' for scene kind '{}': it is a key of scene kind '{}' "
                         "(scene.kind = '{}' here)",
                         raw.name, kind, other.name, kind));
    }
    if (raw.path == "collider")
      fail(raw.source, raw.name, "'collider' must be an array of tables: write each as [[collider]]");
    if (!raw.empty_table && is_table_path(raw.path))
      fail(raw.source, raw.name,
           fmt::format("'{}' is a table of keys, not a value: write its keys under [{}]", raw.name,
                       raw.name));
    fail(raw.source, raw.name, unknown_message(raw.name, suggest(raw.path, valid)));
  }

  // Physical quantities beyond what double arithmetic can carry through a run: a product of
  // two such values (m g h, 1/m, |x|^2) overflows or underflows. Every key of the scene, the
  // colliders and gravity with units (other than 1 and s: times such as a motion's stop may be
  // "never", 1e300) must be 0 or have a magnitude in [kTiny, kHuge] (vectors: each component at
  // most kHuge).
  void check_magnitudes(const std::map<std::string, Entry>& entries, const std::vector<KeySpec>& a,
                        const std::vector<KeySpec>& b, const std::string& prefix) const {
    constexpr double kHuge = 1e100, kTiny = 1e-100;
    for (const auto& [path, e] : entries) {
      const KeySpec* spec = find_key(a, path);
      if (!spec) spec = find_key(b, path);
      const bool physical = path == "gravity" || path.rfind("scene.", 0) == 0 || path.rfind("collider.", 0) == 0;
      if (!spec || !physical || spec->units.empty() || spec->units == "1" || spec->units == "s") continue;
      std::vector<double> values;
      if (const auto* d = std::get_if<double>(&e.value)) values.push_back(*d);
      else if (const auto* v = std::get_if<std::vector<double>>(&e.value)) values = *v;
      const bool vector = std::holds_alternative<std::vector<double>>(e.value);
      for (double v : values) {
        const double m = std::abs(v);
        // A tiny component of a vector is harmless; a tiny scalar (a mass, a length) is divided by.
        if (m == 0.0 || ((vector || m >= kTiny) && m <= kHuge)) continue;
        const std::string name = prefix.empty() ? path : prefix + path.substr(path.find('.') + 1);
        fail(e.source.file.empty() ? Source{file_name_, 0} : e.source, name,
             fmt::format("{} = {} {}: a magnitude {} than {:g} {} cannot be simulated in double "
                         "precision (its products overflow or underflow)",
                         name, format_value(e.value), spec->units, m > kHuge ? "larger" : "smaller",
                         m > kHuge ? kHuge : kTiny, spec->units));
      }
    }
  }

  // The run as planned: a step count that is a positive whole number a long can hold.
  void check_steps(const Config& config) const {
    const Entry& dt = config.at("time.dt");
    const Entry& duration = config.at("time.duration");
    const double ratio = config.get_double("time.duration") / config.get_double("time.dt");
    auto where = [&](const Entry& e) { return e.source.file.empty() ? Source{file_name_, 0} : e.source; };
    const std::string values = fmt::format("time.duration = {} s, time.dt = {} s",
                                           format_value(duration.value), format_value(dt.value));
    if (!(ratio >= 0.5))
      fail(where(duration), "time.duration",
           values + ": the run would take no step (the step count is duration / dt rounded, here " +
               format_double(ratio) + ")");
    if (!(ratio <= kMaxSteps))
      fail(where(dt), "time.dt",
           fmt::format("{}: {:.3g} steps, more than the {:g} a run may plan", values, ratio, kMaxSteps));
  }

  // One material, whatever the solver (solvers/pbd_material.hpp): pbd derives each k from the
  // compliances (solver.pbd.material = "compliance", the default) or takes the *_stiffness keys
  // as an explicit override ("stiffness"). What it cannot honour is refused rather than left
  // unread: a constraint's damping beta (no pbd meaning in either mode), and the correction of
  // an explicit k when k is derived. (The *_stiffness keys are pbd-seed's k too, the seed
  // listing's only material, so scenes keep them; describe and the run file's "material" say
  // which value pbd used.)
  void check_pbd_material(const Config& config) const {
    if (config.get_string("solver.name") != "pbd") return;
    const bool derived = config.get_string("solver.pbd.material") == "compliance";
    auto where = [&](const Entry& e) { return e.source.file.empty() ? Source{file_name_, 0} : e.source; };
    auto number = [](const Value& v) {
      if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
      if (const auto* d = std::get_if<double>(&v)) return *d;
      return 0.0;
    };
    auto scan = [&](const std::map<std::string, Entry>& m, const std::string& table,
                    const std::string& name_prefix) {
      for (const auto& [path, e] : m) {
        if (path.rfind(table, 0) != 0) continue;
        const bool damping = path.size() >= 7 && path.compare(path.size() - 7, 7, "damping") == 0;
        if (!damping || number(e.value) == 0.0) continue;
        const std::string name = name_prefix + path.substr(table.size());
        fail(where(e), name,
             fmt::format("{} = {} is XPBD's constraint damping beta, which has no pbd meaning: "
                         "set it to 0 for pbd (solver.pbd.velocity_damping damps pbd's motion), "
                         "or use solver.name = \"xpbd\"", name, format_value(e.value)));
      }
    };
    scan(config.entries, "scene.", "scene.");
    for (std::size_t i = 0; i < config.bodies.size(); ++i)
      scan(config.bodies[i], "body.", "body." + std::to_string(i) + ".");
    const Entry& correction = config.at("solver.pbd.stiffness_correction");
    if (derived && std::get<bool>(correction.value))
      fail(where(correction), "solver.pbd.stiffness_correction",
           "solver.pbd.stiffness_correction = true corrects an explicit k, but solver.pbd.material "
           "= \"compliance\" derives k from the compliance for the iteration count already: set "
           "solver.pbd.material = \"stiffness\" to correct the *_stiffness keys");
  }

  // Rules that involve a key's value beyond its own type and bounds.
  void check_cross_keys(const Config& config) const {
    check_pbd_material(config);
    check_magnitudes(config.entries, common_keys(), detail::find_kind(config.get_string("scene.kind"))->keys, "");
    for (std::size_t i = 0; i < config.colliders.size(); ++i)
      check_magnitudes(config.colliders[i], collider_keys(), {}, "collider." + std::to_string(i) + ".");
    check_steps(config);
    auto nonzero = [](const Entry& e, const std::string& name, const std::string& why) {
      const auto& v = std::get<std::vector<double>>(e.value);
      if (v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0)
        fail(e.source, name, fmt::format("{} = {} must be non-zero ({})", name, format_value(e.value), why));
    };
    const std::string kind = config.get_string("scene.kind");
    if (kind == "spring") nonzero(config.at("scene.direction"), "scene.direction", "it is normalised");
    if (config.has("scene.pin_motion") && config.get_string("scene.pin_motion") == "circle")
      nonzero(config.at("scene.pin_motion_axis"), "scene.pin_motion_axis", "the axis of a circular motion");
    for (std::size_t i = 0; i < config.colliders.size(); ++i) {
      const auto& c = config.colliders[i];
      const std::string prefix = "collider." + std::to_string(i) + ".";
      if (auto it = c.find("collider.normal"); it != c.end())
        nonzero(it->second, prefix + "normal", "the normal of a plane");
      if (auto it = c.find("collider.motion");
          it != c.end() && std::get<std::string>(it->second.value) == "circle")
        nonzero(c.at("collider.motion_axis"), prefix + "motion_axis", "the axis of a circular motion");
      if (auto it = c.find("collider.file"); it != c.end()) {
        // A mesh collider: its OBJ must exist (read and checked when the scene is built).
        const Entry& e = it->second;
        const Source where = e.source.file.empty() ? colliders_[i].source : e.source;
        const std::string& name = std::get<std::string>(e.value);
        if (name.empty())
          fail(where, prefix + "file", fmt::format("{}file: a mesh collider needs an OBJ file", prefix));
        const std::filesystem::path resolved = config.file.parent_path() / name;
        std::error_code ec;
        const std::filesystem::file_status st = std::filesystem::status(resolved, ec);
        if (!std::filesystem::is_regular_file(st))
          fail(where, prefix + "file",
               fmt::format("{}file = '{}': no such file (looked for {})", prefix, name, resolved.string()));
      }
    }
    if (kind == "mesh") {
      const Entry& e = config.at("scene.file");
      const std::string& name = std::get<std::string>(e.value);
      if (name.empty()) fail(e.source.file.empty() ? Source{file_name_, 0} : e.source, "scene.file",
                             "scene.file: a mesh scene needs a mesh file");
      const std::filesystem::path resolved = config.file.parent_path() / name;
      std::error_code ec;
      const std::filesystem::file_status st = std::filesystem::status(resolved, ec);
      if (!std::filesystem::exists(st))
        fail(e.source, "scene.file",
             fmt::format("scene.file = '{}': no such file (looked for {})", name, resolved.string()));
      if (!std::filesystem::is_regular_file(st))
        fail(e.source, "scene.file",
             fmt::format("scene.file = '{}': {} is {}, not a mesh file", name, resolved.string(),
                         std::filesystem::is_directory(st) ? "a directory" : "not a regular file"));
    }
  }

  std::filesystem::path file_;
  std::string file_name_;
  toml::table table_;
  std::deque<toml::table> override_tables_;
  RawMap top_;
  std::vector<RawCollider> colliders_;
  std::vector<RawCollider> bodies_;  // [[body]] entries, keys "body.<key>"
};

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Overrides, scenario lookup, loading.

Override parse_override(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos)
    throw ConfigError(Source{"--set " + text, 0}, "",
                      "expected --set KEY=VALUE (e.g. --set solver.iterations=20)");
  Override o{trim(text.substr(0, eq)), trim(text.substr(eq + 1))};
  if (o.path.empty())
    throw ConfigError(Source{"--set " + text, 0}, "", "expected --set KEY=VALUE: the key is empty");
  return o;
}

std::filesystem::path scenarios_dir() {
  if (const char* env = std::getenv("PBDBENCH_SCENARIOS"); env && *env) return env;
  return data_dir() / "scenarios";
}

std::filesystem::path resolve_scenario(const std::string& name_or_path) {
  std::error_code ec;
  const std::filesystem::path p(name_or_path);
  if (std::filesystem::is_regular_file(p, ec)) return p;
  const std::filesystem::path dir = scenarios_dir();
  if (p.extension() != ".toml" && std::filesystem::is_regular_file(dir / (name_or_path + ".toml"), ec))
    return dir / (name_or_path + ".toml");
  if (p.extension() == ".toml" && std::filesystem::is_regular_file(dir / name_or_path, ec))
    return dir / name_or_path;
  std::vector<std::string> names;
  for (const ScenarioInfo& s : list_scenarios()) names.push_back(s.name);
  std::string message = fmt::format("no scenario '{}': not a file, and not a name in the catalog {}",
                                    name_or_path, dir.string());
  const std::string close = suggest(name_or_path, names);
  if (!close.empty()) message += " (did you mean '" + close + "'?)";
  message += names.empty() ? " (the catalog is empty)"
                           : fmt::format("; the catalog has: {}", fmt::join(names, ", "));
  throw ConfigError(Source{}, "", message);
}

Config load_text(const std::string& toml_text, const std::filesystem::path& file,
                 const std::vector<Override>& overrides) {
  Loader loader(toml_text, file);
  for (std::size_t i = 0; i < overrides.size(); ++i) loader.apply(overrides[i], i);
  Config config = loader.resolve();
  // The scene builder's refusals (a degenerate mesh, a pin index out of range, an unsound model)
  // are validation errors too.
  (void)build_scene(config);
  return config;
}

Config load(const std::string& name_or_path, const std::vector<Override>& overrides) {
  const std::filesystem::path path = resolve_scenario(name_or_path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(Source{path.string(), 0}, "", "cannot read the scenario file");
  std::ostringstream text;
  text << in.rdbuf();
  // An empty file is not a scenario (it would run a default particle). Text that is not TOML
  // is reported by the loader with its line.
  bool empty = true;
  try {
    empty = toml::parse(std::string_view(text.str()), std::string_view(path.string())).empty();
  } catch (const toml::parse_error&) {
    empty = false;
  }
  if (empty)
    throw ConfigError(Source{path.string(), 0}, "",
                      "the scenario file has no keys (it is empty, or only whitespace and comments): "
                      "nothing to run; a scenario sets at least [scene] kind");
  return load_text(text.str(), path, overrides);
}

// ---------------------------------------------------------------------------------------------
// Accessors.

namespace {
template <class T>
const T& get_as(const Config& c, const std::string& path, const char* what) {
  const Entry& e = c.at(path);
  if (const T* v = std::get_if<T>(&e.value)) return *v;
  throw ConfigError(e.source, path, fmt::format("{} is {}, not {}", path, format_value(e.value), what));
}
}  // namespace

bool Config::has(const std::string& path) const { return entries.count(path) > 0; }

const Entry& Config::at(const std::string& path) const {
  auto it = entries.find(path);
  if (it == entries.end())
    throw ConfigError(Source{file.string(), 0}, path,
                      fmt::format("no key '{}' in the configuration of '{}'", path, scenario_name));
  return it->second;
}

bool Config::get_bool(const std::string& path) const { return get_as<bool>(*this, path, "a boolean"); }
std::int64_t Config::get_int(const std::string& path) const {
  return get_as<std::int64_t>(*this, path, "an integer");
}
double Config::get_double(const std::string& path) const {
  const Entry& e = at(path);
  if (const auto* i = std::get_if<std::int64_t>(&e.value)) return static_cast<double>(*i);
  return get_as<double>(*this, path, "a number");
}
const std::string& Config::get_string(const std::string& path) const {
  return get_as<std::string>(*this, path, "a string");
}
Vec3 Config::get_vec3(const std::string& path) const {
  const auto& v = get_as<std::vector<double>>(*this, path, "a vec3");
  if (v.size() != 3)
    throw ConfigError(at(path).source, path, fmt::format("{} has {} elements, not 3", path, v.size()));
  return Vec3(v[0], v[1], v[2]);
}
const std::vector<double>& Config::get_floats(const std::string& path) const {
  return get_as<std::vector<double>>(*this, path, "a list of floats");
}
const std::vector<std::int64_t>& Config::get_ints(const std::string& path) const {
  return get_as<std::vector<std::int64_t>>(*this, path, "a list of integers");
}
const std::vector<std::string>& Config::get_strings(const std::string& path) const {
  return get_as<std::vector<std::string>>(*this, path, "a list of strings");
}

std::string Config::to_toml() const {
  std::string out = fmt::format(
      "# The resolved configuration of scenario '{}': every key, defaults included.\n",
      scenario_name);
  // Keys in schema order, grouped by table in the order the tables first appear.
  std::vector<const KeySpec*> keys;
  for (const KeySpec& k : common_keys()) keys.push_back(&k);
  if (has("scene.kind"))
    if (const SceneKindInfo* info = detail::find_kind(get_string("scene.kind")))
      for (const KeySpec& k : info->keys) keys.push_back(&k);
  std::vector<std::string> tables;
  std::map<std::string, std::vector<std::string>> lines;
  for (const KeySpec* k : keys) {
    auto it = entries.find(k->path);
    if (it == entries.end()) continue;
    const auto dot = k->path.rfind('.');
    const std::string table = dot == std::string::npos ? "" : k->path.substr(0, dot);
    const std::string leaf = dot == std::string::npos ? k->path : k->path.substr(dot + 1);
    if (!lines.count(table)) tables.push_back(table);
    lines[table].push_back(leaf + " = " + format_value(it->second.value));
  }
  std::stable_partition(tables.begin(), tables.end(), [](const std::string& t) { return t.empty(); });
  for (const std::string& t : tables) {
    if (!t.empty()) out += "\n[" + t + "]\n";
    for (const std::string& l : lines[t]) out += l + "\n";
  }
  for (const auto& c : colliders) {
    out += "\n[[collider]]\n";
    for (const KeySpec& k : collider_keys())
      if (auto it = c.find(k.path); it != c.end())
        out += k.path.substr(9) + " = " + format_value(it->second.value) + "\n";
  }
  for (const auto& b : bodies) {
    out += "\n[[body]]\n";
    for (const KeySpec& k : body_placement_keys())
      if (auto it = b.find(k.path); it != b.end())
        out += k.path.substr(5) + " = " + format_value(it->second.value) + "\n";
    auto kind = b.find("body.kind");
    if (kind == b.end()) continue;
    if (const SceneKindInfo* info = detail::find_kind(std::get<std::string>(kind->second.value)))
      for (const KeySpec& k : info->keys)
        if (auto it = b.find("body." + k.path.substr(6));
            it != b.end() && !find_key(body_placement_keys(), it->first))
          out += k.path.substr(6) + " = " + format_value(it->second.value) + "\n";
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Options.

namespace detail {

void set_solver_option(SolverOptions& o, const std::string& path, const Value& value) {
  const OptionRow* row = find_solver_option(path);
  if (row == nullptr) throw std::invalid_argument("'" + path + "' is not a solver key");
  struct ToOption {
    OptionValue operator()(bool v) const { return v; }
    OptionValue operator()(std::int64_t v) const { return v; }
    OptionValue operator()(double v) const { return v; }
    OptionValue operator()(const std::string& v) const { return v; }
    OptionValue operator()(const std::vector<std::string>& v) const { return v; }
    OptionValue operator()(const std::vector<double>&) const { return wrong(); }
    OptionValue operator()(const std::vector<std::int64_t>&) const { return wrong(); }
    [[noreturn]] static OptionValue wrong() {
      throw std::invalid_argument("a list of numbers is not the value of a solver option");
    }
  };
  row->set(o, std::visit(ToOption{}, value));
}

}  // namespace detail

SolverOptions solver_options(const Config& config) {
  SolverOptions o;
  for (const OptionRow& r : solver_option_rows())
    detail::set_solver_option(o, r.key, config.at(r.key).value);
  if (const std::string problem = o.validate(); !problem.empty())
    throw ConfigError(Source{config.file.string(), 0}, "solver",
                      "the solver options are invalid: " + problem);
  return o;
}

std::vector<std::string> unread_solver_keys(const Config& config, SolverFamily family) {
  std::vector<std::string> out;
  const std::string solver = config.get_string("solver.name");
  for (const OptionRow& r : solver_option_rows()) {
    if (option_applies(r, family) || !config.has(r.key)) continue;
    const Source& s = config.at(r.key).source;
    if (s.file.empty()) continue;  // the default
    const std::string where = s.line > 0 ? s.file + ":" + std::to_string(s.line) : s.file;
    out.push_back(fmt::format("{} ({}) is set but {} does not read it (an option of {})", r.key,
                              where, solver, families_text(r)));
  }
  return out;
}

long RunOptions::steps() const { return static_cast<long>(std::llround(duration / dt)); }

long RunOptions::every_frame() const {
  if (frame_every > 0) return frame_every;
  return std::max<long>(1, static_cast<long>(std::llround((1.0 / 60.0) / dt)));
}

RunOptions run_options(const Config& config) {
  RunOptions r;
  r.dt = config.get_double("time.dt");
  r.duration = config.get_double("time.duration");
  r.frame_every = static_cast<int>(config.get_int("output.frame_every"));
  r.limits.max_speed = config.get_double("limits.max_speed");
  r.limits.max_extent_ratio = config.get_double("limits.max_extent_ratio");
  r.limits.max_distance = config.get_double("limits.max_distance");
  return r;
}

}  // namespace pbdbench::config
