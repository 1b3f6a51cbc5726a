#include "app/regress_command.hpp"

#include <algorithm>
#include <fstream>
#include <ostream>

#include <fmt/format.h>

#include "regress/regress.hpp"
#include "runfile/build_info.hpp"

namespace pbdbench::regress {

namespace fs = std::filesystem;

namespace {
void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + path.string());
}
}  // namespace

RegressOutcome run_regress(const RegressCommand& cmd, std::ostream& out, std::ostream& log) {
  const fs::path source(PBDBENCH_SOURCE_DIR);
  const std::string tier = experiments::to_string(cmd.tier);
  const Registry reg = load_registry(cmd.registry.empty() ? registry_file() : cmd.registry);
  std::vector<const CaseSpec*> cases;
  for (const CaseSpec& c : reg.cases)
    if (cmd.cases.empty() ? (cmd.tier == experiments::Tier::Full || c.quick)
                          : std::find(cmd.cases.begin(), cmd.cases.end(), c.name) != cmd.cases.end())
      cases.push_back(&c);
  for (const std::string& name : cmd.cases)
    if (std::none_of(reg.cases.begin(), reg.cases.end(), [&](const CaseSpec& c) { return c.name == name; }))
      throw experiments::ExperimentError(fmt::format("{}: no case named '{}'", reg.file.string(), name));

  RegressOutcome outcome;
  outcome.out = !cmd.out.empty() ? cmd.out : source / "results" / "regress" / tier;
  log << fmt::format("regress: {} cases, {} tier, run files in {}\n", cases.size(), tier,
                     (outcome.out / "runs").string());
  std::vector<CaseResult> results;
  for (const CaseSpec* c : cases) {
    results.push_back(measure_case(reg, *c, outcome.out / "runs", cmd.force, cmd.control));
    log << fmt::format("  {}: {}\n", c->name, results.back().status);
  }
  write_text(outcome.out / "regress.json", results_json(results));

  const fs::path baselines =
      !cmd.baselines.empty() ? cmd.baselines : source / "regress" / fmt::format("baselines_{}.toml", tier);
  if (cmd.update) {
    write_text(baselines, baseline_toml(results, cmd.tier));
    out << fmt::format("{} cases measured; baselines written to {} (build {})\n", results.size(),
                       baselines.string(), build_info().git_commit);
    outcome.updated = true;
    return outcome;
  }

  const fs::path base_file = !cmd.against.empty() ? cmd.against / "regress.json" : baselines;
  const Baseline base = read_baseline(base_file);
  Report rep = compare(reg, cases, results, base);
  if (cmd.repeat) {
    for (size_t k = 0; k < cases.size(); ++k) {
      const CaseResult again = measure_case(reg, *cases[k], outcome.out / "repeat", true, cmd.control);
      const bool same = again.hash == results[k].hash;
      if (!same) ++outcome.bit_differences;
      rep.hash_lines.push_back(fmt::format("{}: run twice, {}", cases[k]->name,
                                           same ? "the same bits (" + again.hash + ")"
                                                : "different bits: " + results[k].hash + " then " + again.hash));
    }
  }
  outcome.worse = rep.worse;
  outcome.better = rep.better;
  const std::string header = fmt::format(
      "`pbdbench regress` ({} tier): {} cases of `{}` against `{}` (made by {}). Now: {}. Rows are "
      "metrics; a change beyond `allowed` (abs + rel |baseline|) in the metric's bad direction is "
      "**worse**; timings are ratios, never verdicts.",
      tier, cases.size(), fs::relative(reg.file, source).generic_string(), base_file.generic_string(),
      base.commit.empty() ? "an unknown build" : base.commit, build_info().git_commit);
  write_text(outcome.out / "regress.md", report_markdown(rep, header));
  write_report_h5(outcome.out / "regress.h5", rep);
  out << report_table(rep);
  for (const std::string& l : rep.hash_lines)
    if (l.find("differ") != std::string::npos) out << "bitwise: " << l << "\n";
  out << fmt::format("-> {}\n", (outcome.out / "regress.md").string());
  return outcome;
}

}  // namespace pbdbench::regress
