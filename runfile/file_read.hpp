// A file of one of runfile/'s layouts read back: its content as written, its provenance, and
// every scalar root attribute (derived ones too: created, ...); and the description of a
// layout's attributes (AttributeInfo), which each file kind publishes from its one table
// (run_root_attributes(), compare_root_attributes(), ...) for tests and the docs.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace pbdbench {

// Who wrote a file, and when: the root attributes created, pbdbench_version, git_commit,
// compiler, build_type and cxx_flags of every file runfile/ writes (layout.cpp kProvenance).
struct Provenance {
  std::string created;           // ISO 8601 UTC (runfile/utc_now.hpp)
  std::string pbdbench_version;  // runfile/build_info.hpp
  std::string git_commit;
  std::string compiler;
  std::string build_type;
  std::string cxx_flags;
};

template <class Content>
struct FileRead {
  Content result;
  Provenance provenance;
  std::map<std::string, std::string> attributes;  // every scalar string attribute of the root
  std::map<std::string, double> numbers;          // every numeric scalar attribute of the root
};

// One attribute of a layout, as its table declares it.
enum class AttributeType { Text, Integer, Real };
const char* to_string(AttributeType type);  // "str", "int", "float"

struct AttributeInfo {
  std::string name;
  AttributeType type = AttributeType::Text;
  std::string units;  // "" for none (text, counts, flags)
  std::string doc;
  bool read_back = true;  // false: derived when written (a constant, a summary), not read into
                          // the struct the file stores
};

// The attributes as a Markdown table (| attribute | type | units | meaning |), the form
// results/README.md carries verbatim ('|' in a doc escaped).
std::string attributes_markdown(const std::vector<AttributeInfo>& attributes);

// The provenance attributes (created and the build's), in the order they are written.
std::vector<AttributeInfo> provenance_attributes();

}  // namespace pbdbench
