// What `pbdbench claims` and `pbdbench paper` write from the evaluated experiments:
//
//   <out>/README.md      the report: the counts by part first (what they count is said), then a
//                        row per claim (or per published number), then a section per experiment
//                        with the article's words or the paper's setup, each part's rule and
//                        verdict, its registration, measures, timings, runs and figure; it reads
//                        on its own, for someone who never saw the code
//   <out>/claims.json    everything measured, for the figures (scripts/plot_claims.py) and for
//   (reproductions.json) anyone who wants the numbers
//   verdict records      `--record FILE` writes each part's verdict; `--expect FILE` compares
//                        (the test suite runs the quick tier against the committed records)
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "experiments/claim_index.hpp"
#include "experiments/evaluate.hpp"
#include "experiments/provenance.hpp"
#include "experiments/registry.hpp"

namespace pbdbench::experiments {

struct ReportContext {
  Tier tier = Tier::Full;
  std::string machine;  // e.g. "AMD EPYC 7B13, 2 cores"
  std::string build;    // e.g. "0.1.0 Release, GNU 12.2.0, commit abc123"
  std::string command;  // the command line that made the report
  std::filesystem::path figures_dir;  // relative to the report's folder ("figures")
  int jobs = 1;                       // runs made at a time (timings always run alone)
  const ClaimIndex* index = nullptr;  // claims: the index (its source and untestable claims)
  std::map<std::string, RegistrationStatus> registration;  // by experiment id
};

// The claims' report, or, when the experiments are reproductions, the reproductions' report (a
// row per published number: published, source, ours, rule, verdict).
std::string report_markdown(const std::vector<ClaimResult>& claims, const ReportContext& context);
std::string results_json(const std::vector<ClaimResult>& claims, const ReportContext& context,
                         const std::filesystem::path& relative_to);

// The counts of a set of results as one line each, the same words in the console and the report:
// "73 parts in the article's regime: 32 supported, 31 contradicted, 6 inconclusive, 4 not
// testable"; "22 claims: ...".
std::string part_counts_line(const std::vector<ClaimResult>& results);

// A part's registered versions (experiments/registry.hpp): the verdict under each version that
// had results and was revised, and whether its rule or words changed after results.
struct PartHistory {
  bool revised_after_results = false;  // an earlier version's rule or words differ from today's
  bool first_registered_known = false;  // a registered version before today's had results
  std::string first_registered;        // that first registered version's verdict
  std::vector<std::string> versions;   // "registered DATE: rule `...`: verdict", oldest first
};
PartHistory part_history(const RegistrationStatus* status, const std::string& part_id, const PartResult& part);

// "Revisions: ..." : how many counted verdicts changed after their first registration, the
// first-registered verdicts counted beside today's, and how many parts were revised after results.
std::string revisions_line(const std::vector<ClaimResult>& results, const ReportContext& context);
std::string experiment_counts_line(const std::vector<ClaimResult>& results);

// Verdict records: one line per part, "S5.4.2" = "contradicted", and one per claim, "S5.4" =
// "contradicted". Parts that read timing measures are recorded but not compared.
std::string verdicts_toml(const std::vector<ClaimResult>& claims, Tier tier);
// The differences between the claims' verdicts and a record (only for the claims evaluated);
// empty when they agree. Throws std::runtime_error when the file cannot be read.
std::vector<std::string> verdict_differences(const std::vector<ClaimResult>& claims,
                                             const std::filesystem::path& record);

// A part's id: "<experiment id>.<k>", k from 1.
std::string part_id(const ClaimResult& result, size_t k);

}  // namespace pbdbench::experiments
