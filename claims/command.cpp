#include "claims/command.hpp"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <ostream>

#include <fmt/format.h>

#include "claims/evaluate.hpp"
#include "claims/report.hpp"

namespace pbdbench::claims {

namespace fs = std::filesystem;

namespace {
// Writes `text` unless the file already holds it (so that a rerun that reused every run file
// leaves the report's time stamps alone and the figures are not redrawn).
void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      const std::string old((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (old == text) return;
    }
  }
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + path.string());
}
}  // namespace

ClaimsOutcome run_claims(const ClaimsCommand& cmd, std::ostream& out, std::ostream& log) {
  const fs::path source(PBDBENCH_SOURCE_DIR);
  const fs::path dir = cmd.experiments.empty() ? experiments_dir() : cmd.experiments;
  std::vector<Experiment> all = load_experiments(dir);
  std::vector<Experiment> chosen;
  for (const std::string& id : cmd.ids) {
    auto it = std::find_if(all.begin(), all.end(), [&](const Experiment& e) { return e.id == id; });
    if (it == all.end()) {
      std::vector<std::string> ids;
      for (const Experiment& e : all) ids.push_back(e.id);
      throw ExperimentError(fmt::format("no claim '{}' in {}; the claims are: {}", id, dir.string(),
                                        fmt::join(ids, ", ")));
    }
    chosen.push_back(*it);
  }
  if (cmd.ids.empty()) chosen = all;

  const std::string tier = to_string(cmd.tier);
  ClaimsOutcome outcome;
  outcome.out = !cmd.out.empty() ? cmd.out
                : (cmd.ids.empty() && cmd.tier == Tier::Full) ? source / "paper" / "claims"
                                                                : source / "results" / "claims" / tier;
  EvaluateOptions options;
  options.tier = cmd.tier;
  options.runs_dir = !cmd.runs.empty() ? cmd.runs : source / "results" / "claims" / tier / "runs";
  options.force = cmd.force;
  options.log = &log;

  log << fmt::format("claims: {} experiment{}, {} tier, run files in {}\n", chosen.size(),
                     chosen.size() == 1 ? "" : "s", tier, options.runs_dir.string());
  out << "id      verdict       parts (S supported, C contradicted, - not testable), time\n";
  std::vector<ClaimResult> results;
  for (const Experiment& e : chosen) {
    results.push_back(evaluate_claim(e, options));
    const ClaimResult& r = results.back();
    std::string parts;
    for (const PartResult& p : r.parts) parts += p.verdict == Verdict::Supported ? 'S' : p.verdict == Verdict::Contradicted ? 'C' : '-';
    out << fmt::format("{:<7} {:<13} [{}] {:6.1f} s\n", r.id, to_string(r.verdict), parts, r.wall_time);
    out.flush();
  }

  ReportContext ctx;
  ctx.tier = cmd.tier;
  ctx.machine = machine_description();
  ctx.build = build_description();
  ctx.command = cmd.command_line;
  ctx.figures_dir = "figures";
  write_text(outcome.out / "README.md", report_markdown(results, ctx));
  write_text(outcome.out / "claims.json", results_json(results, ctx, outcome.out));
  if (!cmd.record.empty()) write_text(cmd.record, verdicts_toml(results, cmd.tier));
  if (!cmd.expect.empty()) outcome.differences = verdict_differences(results, cmd.expect);

  int counts[3] = {0, 0, 0};
  for (const ClaimResult& r : results) ++counts[static_cast<int>(r.verdict)];
  out << fmt::format("{} claims: {} supported, {} contradicted, {} not testable -> {}\n", results.size(),
                     counts[0], counts[1], counts[2], (outcome.out / "README.md").string());
  return outcome;
}

}  // namespace pbdbench::claims
