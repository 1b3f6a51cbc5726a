// The index of the claims a source makes (claims/index.toml for the seed article): what the source
// is, as far as its text identifies it, and every claim it makes, with the original sentence(s),
// an English translation and the section. Each claim has an experiment (claims/experiments/<id>.toml)
// or says why it is not testable here; `pbdbench claims` refuses an index and a folder of
// experiments that do not cover each other.
//
//   [source]
//   title = "..."          # as the text gives it
//   kind = "..."           # e.g. "a practitioner's article"
//   language = "Chinese"
//   author = "..."         # or why it is not known
//   origin = "..."         # where it came from, as far as known
//   sha256 = "..."         # of the text as received, so that a reader can check they hold the same
//   sections = ["1 ...", "2 ...", ...]
//   [[claim]]
//   id = "S5.4"
//   section = "5.4"
//   claim = "..."          # the claim in one English sentence
//   original = "..."       # the article's words (verbatim)
//   translation = "..."    # in English
//   untestable = "..."     # instead of an experiment: why it is not testable here
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace pbdbench::experiments {

struct Experiment;

struct SourceText {
  std::string title;
  std::string kind;
  std::string language;
  std::string author;
  std::string origin;
  std::string sha256;
  std::vector<std::string> sections;
};

struct IndexedClaim {
  std::string id;
  std::string section;
  std::string claim;
  std::string original;
  std::string translation;
  std::string untestable;  // "" when the claim has an experiment
  int line = 0;
};

struct ClaimIndex {
  std::filesystem::path file;
  SourceText source;
  std::vector<IndexedClaim> claims;  // in the file's order
  const IndexedClaim* find(const std::string& id) const;
};

// Throws ExperimentError naming the file, line and key.
ClaimIndex read_claim_index(const std::filesystem::path& file);

// The index beside a folder of claim experiments: <folder>/../index.toml.
std::filesystem::path claim_index_of(const std::filesystem::path& experiments_dir);

// Throws ExperimentError when an experiment's id is not in the index, or a claim of the index has
// neither an experiment among `experiments` nor an untestable reason, or has both.
void check_coverage(const ClaimIndex& index, const std::vector<Experiment>& experiments);

}  // namespace pbdbench::experiments
