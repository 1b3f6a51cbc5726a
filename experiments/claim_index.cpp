#include "experiments/claim_index.hpp"

#include <algorithm>
#include <set>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "experiments/experiment.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void fail(const fs::path& file, int line, const std::string& key, const std::string& message) {
  throw ExperimentError(fmt::format("{}:{}: {}: {}", file.string(), line, key, message));
}

std::string text(const toml::table& t, const char* key, bool required, const fs::path& file,
                 const std::string& prefix) {
  const toml::node* n = t.get(key);
  if (n == nullptr) {
    if (required) fail(file, static_cast<int>(t.source().begin.line), prefix + key, "missing");
    return "";
  }
  if (!n->is_string()) fail(file, static_cast<int>(n->source().begin.line), prefix + key, "must be a string");
  return n->as_string()->get();
}

void known_keys(const toml::table& t, const std::vector<std::string>& known, const fs::path& file,
                const std::string& prefix) {
  for (auto&& [k, v] : t) {
    const std::string name(k.str());
    if (std::find(known.begin(), known.end(), name) == known.end())
      fail(file, static_cast<int>(k.source().begin.line), prefix + name,
           fmt::format("unknown key; known: {}", fmt::join(known, ", ")));
  }
}

}  // namespace

const IndexedClaim* ClaimIndex::find(const std::string& id) const {
  for (const IndexedClaim& c : claims)
    if (c.id == id) return &c;
  return nullptr;
}

fs::path claim_index_of(const fs::path& experiments_dir) { return experiments_dir.parent_path() / "index.toml"; }

ClaimIndex read_claim_index(const fs::path& file) {
  ClaimIndex index;
  index.file = file;
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    fail(file, static_cast<int>(e.source().begin.line), "", std::string(e.description()));
  }
  known_keys(root, {"source", "claim"}, file, "");
  const toml::table* src = root["source"].as_table();
  if (src == nullptr) fail(file, 1, "source", "missing: say what the claims' source is");
  known_keys(*src, {"title", "kind", "language", "author", "origin", "sha256", "sections"}, file, "source.");
  index.source.title = text(*src, "title", true, file, "source.");
  index.source.kind = text(*src, "kind", true, file, "source.");
  index.source.language = text(*src, "language", true, file, "source.");
  index.source.author = text(*src, "author", true, file, "source.");
  index.source.origin = text(*src, "origin", true, file, "source.");
  index.source.sha256 = text(*src, "sha256", true, file, "source.");
  if (const toml::array* a = (*src)["sections"].as_array())
    for (auto&& s : *a) index.source.sections.push_back(s.value_or(std::string()));
  std::set<std::string> ids;
  if (const toml::array* claims = root["claim"].as_array()) {
    for (auto&& node : *claims) {
      const toml::table* t = node.as_table();
      if (t == nullptr) fail(file, static_cast<int>(node.source().begin.line), "claim", "must be a table");
      known_keys(*t, {"id", "section", "claim", "original", "translation", "untestable"}, file, "claim.");
      IndexedClaim c;
      c.line = static_cast<int>(t->source().begin.line);
      c.id = text(*t, "id", true, file, "claim.");
      c.section = text(*t, "section", true, file, "claim.");
      c.claim = text(*t, "claim", true, file, "claim.");
      c.original = text(*t, "original", true, file, "claim.");
      c.translation = text(*t, "translation", true, file, "claim.");
      c.untestable = text(*t, "untestable", false, file, "claim.");
      if (!ids.insert(c.id).second) fail(file, c.line, "claim.id", "'" + c.id + "' is indexed twice");
      index.claims.push_back(std::move(c));
    }
  }
  if (index.claims.empty()) fail(file, 1, "claim", "an index lists at least one [[claim]]");
  return index;
}

void check_coverage(const ClaimIndex& index, const std::vector<Experiment>& experiments) {
  std::set<std::string> with_experiment;
  for (const Experiment& e : experiments) {
    const IndexedClaim* c = index.find(e.id);
    if (c == nullptr)
      throw ExperimentError(fmt::format("{}: id: '{}' is not a claim of the index {}", e.file.string(), e.id,
                                        index.file.string()));
    if (!c->untestable.empty())
      fail(index.file, c->line, "claim.untestable",
           fmt::format("'{}' is marked untestable but has an experiment ({})", c->id, e.file.string()));
    with_experiment.insert(e.id);
  }
  for (const IndexedClaim& c : index.claims)
    if (c.untestable.empty() && !with_experiment.count(c.id))
      fail(index.file, c.line, "claim",
           fmt::format("'{}' has neither an experiment (claims/experiments/{}.toml) nor an untestable reason",
                       c.id, c.id));
}

}  // namespace pbdbench::experiments
