#include "config/toml_text.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace pbdbench::config {

Source source_of(const std::filesystem::path& file, const toml::source_region& region) {
  return {file.string(), static_cast<int>(region.begin.line)};
}

std::string toml_value_text(const toml::node& node, const std::filesystem::path& file) {
  if (auto s = node.as_string()) {
    std::string out = "\"";
    for (char c : s->get()) {
      switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\t': out += "\\t"; break;
        default: out += c;
      }
    }
    return out + "\"";
  }
  if (auto i = node.as_integer()) return std::to_string(i->get());
  if (auto b = node.as_boolean()) return b->get() ? "true" : "false";
  if (auto f = node.as_floating_point()) {
    const double v = f->get();
    if (!std::isfinite(v)) throw ConfigError(source_of(file, node.source()), "", "a value must be finite");
    char buf[64];
    auto res = std::to_chars(buf, buf + sizeof buf, v);
    std::string out(buf, res.ptr);
    if (out.find_first_of(".e") == std::string::npos) out += ".0";
    return out;
  }
  if (auto a = node.as_array()) {
    std::string out = "[";
    for (size_t k = 0; k < a->size(); ++k) {
      if (k > 0) out += ", ";
      out += toml_value_text(*a->get(k), file);
    }
    return out + "]";
  }
  throw ConfigError(source_of(file, node.source()), "",
                    "a value must be a string, number, boolean or array");
}

namespace {
void flatten_into(const toml::table& table, const std::string& prefix, std::vector<FlatEntry>& out) {
  for (auto&& [key, node] : table) {
    const std::string path =
        prefix.empty() ? std::string(key.str()) : prefix + "." + std::string(key.str());
    if (auto sub = node.as_table())
      flatten_into(*sub, path, out);
    else
      out.push_back({path, &node, static_cast<int>(key.source().begin.line)});
  }
}
}  // namespace

std::vector<FlatEntry> flatten_table(const toml::table& table, const std::string& prefix) {
  std::vector<FlatEntry> out;
  flatten_into(table, prefix, out);
  std::stable_sort(out.begin(), out.end(),
                   [](const FlatEntry& a, const FlatEntry& b) { return a.line < b.line; });
  return out;
}

}  // namespace pbdbench::config
