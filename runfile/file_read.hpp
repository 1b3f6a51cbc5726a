// A file of one of runfile/'s layouts read back: its content as written, and every scalar root
// attribute (derived ones too: the provenance, created, ...).
#pragma once

#include <map>
#include <string>

namespace pbdbench {

template <class Content>
struct FileRead {
  Content result;
  std::map<std::string, std::string> attributes;  // every scalar string attribute of the root
  std::map<std::string, double> numbers;          // every numeric scalar attribute of the root
};

}  // namespace pbdbench
