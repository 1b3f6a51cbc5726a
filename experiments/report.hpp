// What `pbdbench claims` writes from the evaluated claims:
//
//   <out>/README.md      the report: one row per claim (id, claim, experiment, numbers measured,
//                        rule, verdict), then a section per claim with its parts, measures, runs
//                        and figure; it reads on its own, for someone who never saw the code
//   <out>/claims.json    everything measured, for the figures (scripts/plot_claims.py) and for
//                        anyone who wants the numbers
//   verdict records      `--record FILE` writes each part's verdict; `--expect FILE` compares
//                        (the test suite runs the quick tier against claims/verdicts_quick.toml)
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "experiments/evaluate.hpp"

namespace pbdbench::experiments {

struct ReportContext {
  Tier tier = Tier::Full;
  std::string machine;  // e.g. "AMD EPYC 7B13, 2 cores"
  std::string build;    // e.g. "0.1.0 Release, GNU 12.2.0, commit abc123"
  std::string command;  // the command line that made the report
  std::filesystem::path figures_dir;  // relative to the report's folder ("figures")
  int jobs = 1;                       // runs made at a time (timings share the cores when > 1)
};

// The machine this process runs on: the CPU model and the number of cores.
std::string machine_description();
// The build: version, build type, compiler, commit.
std::string build_description();

// The claims' report, or, when the experiments are reproductions, the reproductions' report (a
// row per published number: published, source, ours, rule, verdict).
std::string report_markdown(const std::vector<ClaimResult>& claims, const ReportContext& context);
std::string results_json(const std::vector<ClaimResult>& claims, const ReportContext& context,
                         const std::filesystem::path& relative_to);

// Verdict records: one line per part, "S5.4.2" = "contradicted", and one per claim, "S5.4" =
// "contradicted". Parts marked timing are recorded but not compared.
std::string verdicts_toml(const std::vector<ClaimResult>& claims, Tier tier);
// The differences between the claims' verdicts and a record (only for the claims evaluated);
// empty when they agree. Throws std::runtime_error when the file cannot be read.
std::vector<std::string> verdict_differences(const std::vector<ClaimResult>& claims,
                                             const std::filesystem::path& record);

}  // namespace pbdbench::experiments
