// `pbdbench claims [ID...]`: runs the claims' experiments and writes the report.
//
//   pbdbench claims                      every claim, full tier -> paper/claims/
//   pbdbench claims S5.4                 one claim, full tier   -> results/claims/full/
//   pbdbench claims --tier quick --expect claims/verdicts_quick.toml   (the test suite)
//
// Run files go to results/claims/<tier>/runs/<id>/ unless --runs says otherwise; a run file
// already holding the same finished configuration from the same build is read, not run again
// (--force runs everything again).
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "claims/experiment.hpp"

namespace pbdbench::claims {

struct ClaimsCommand {
  std::vector<std::string> ids;        // empty: every claim
  Tier tier = Tier::Full;
  std::filesystem::path experiments;   // default: experiments_dir()
  std::filesystem::path out;           // default: see above
  std::filesystem::path runs;          // default: results/claims/<tier>/runs
  bool force = false;
  std::filesystem::path record;        // write the verdicts here
  std::filesystem::path expect;        // compare the verdicts with this record
  std::string command_line;            // as typed, for the report
};

struct ClaimsOutcome {
  std::filesystem::path out;           // the folder written
  std::vector<std::string> differences;  // from --expect
};

// Throws ExperimentError for a bad experiment file or an unknown id.
ClaimsOutcome run_claims(const ClaimsCommand& command, std::ostream& out, std::ostream& log);

}  // namespace pbdbench::claims
