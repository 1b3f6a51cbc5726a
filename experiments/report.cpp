#include "experiments/report.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>
#include <toml++/toml.h>

namespace pbdbench::experiments {

namespace fs = std::filesystem;

namespace {

std::string number(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == std::floor(v) && std::abs(v) < 1e6) return fmt::format("{:.0f}", v);
  return fmt::format("{:.3g}", v);
}

// Markdown table cell: no line breaks, no bare '|'.
std::string cell(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\n') out += ' ';
    else if (c == '|') out += "\\|";
    else out += c;
  }
  return out;
}

// A table cell of code: the text between backticks, or nothing for no text.
std::string code_cell(const std::string& text) { return text.empty() ? "" : fmt::format("`{}`", cell(text)); }

// A Markdown block quote of a text that may span lines.
std::string block_quote(const std::string& text) {
  std::string out = "> ";
  for (char c : text) {
    out += c;
    if (c == '\n') out += "> ";
  }
  return out + "\n";
}

std::string anchor(const std::string& id) {
  std::string out;
  for (char c : id)
    if (std::isalnum(static_cast<unsigned char>(c))) out += static_cast<char>(std::tolower(c));
  return out;
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) out += fmt::format("\\u{:04x}", c);
        else out += c;
    }
  }
  return out + "\"";
}

std::string json_number(double v) { return std::isfinite(v) ? fmt::format("{}", v) : "null"; }

std::string with_units(double v, const std::string& units) {
  return number(v) + (units.empty() || units == "1" ? "" : " " + units);
}

std::string measure_value(const MeasureResult& m) {
  if (!m.interval) return with_units(m.value, m.units);
  return fmt::format("{} [{}, {}]{}", number(m.value), number(m.lo), number(m.hi),
                     m.units.empty() || m.units == "1" ? "" : " " + m.units);
}

// The measures a part's rule reads, with their values.
std::string measured(const ClaimResult& c, const PartResult& p) {
  std::vector<std::string> shown;
  const std::string text = p.rule + " " + p.requires_;
  for (const MeasureResult& m : c.measures) {
    // A whole-word match of the measure's name in the rule.
    size_t at = 0;
    bool used = false;
    while ((at = text.find(m.name, at)) != std::string::npos) {
      const bool left = at == 0 || !(std::isalnum(static_cast<unsigned char>(text[at - 1])) || text[at - 1] == '_');
      const size_t end = at + m.name.size();
      const bool right = end >= text.size() || !(std::isalnum(static_cast<unsigned char>(text[end])) || text[end] == '_');
      if (left && right) used = true;
      at = end;
    }
    if (used) shown.push_back(fmt::format("{} = {}", m.name, measure_value(m)));
  }
  return fmt::format("{}", fmt::join(shown, "; "));
}

std::string verdict_with_reason(const PartResult& p, ExperimentKind kind) {
  std::string v = fmt::format("**{}**", verdict_word(p.verdict, kind));
  if (p.verdict == Verdict::Identity || p.verdict == Verdict::SetupUnknown || p.verdict == Verdict::NotShown)
    v += fmt::format(" (the rule {} here)", std::isnan(p.outcome) ? "is not measured" : p.outcome != 0.0 ? "holds" : "does not hold");
  if (!p.reason.empty()) v += ": " + p.reason;
  return v;
}

// Whether the part could have failed, for a table cell.
std::string can_fail_cell(const PartResult& p, ExperimentKind kind) {
  switch (p.can_fail) {
    case CanFail::NotDecided:
      return p.has_counterfactual ? fmt::format("(counterfactual: {})", verdict_word(p.counterfactual_verdict, kind)) : "";
    case CanFail::Shown: return fmt::format("yes (counterfactual: {})", verdict_word(p.counterfactual_verdict, kind));
    case CanFail::NotFlipped:
      return fmt::format("no (counterfactual: {})", verdict_word(p.counterfactual_verdict, kind));
    case CanFail::NoVariation: return "no (no variation)";
    case CanFail::ByConstruction: return "no (by construction)";
    case CanFail::NoCounterfactual: return "not shown";
  }
  return "";
}

// The part's counterfactual, as a line of its section.
std::string counterfactual_line(const PartResult& p, ExperimentKind kind) {
  if (!p.has_counterfactual) {
    if (p.can_fail == CanFail::ByConstruction) return "- Could fail: no, an identity by construction.\n";
    if (p.can_fail == CanFail::NoCounterfactual) return "- Could fail: not shown (no counterfactual).\n";
    return "";
  }
  std::string why = p.counterfactual_why;
  while (!why.empty() && (why.back() == '.' || why.back() == ' ')) why.pop_back();  // the line adds its own
  std::string out = fmt::format("- Counterfactual: {} — {}. On the variant the rule gives **{}**", cell(p.counterfactual_variant),
                                why, verdict_word(p.counterfactual_verdict, kind));
  if (!p.counterfactual_reason.empty()) out += " (" + p.counterfactual_reason + ")";
  if (!p.counterfactual_measured.empty()) out += "; measured there: " + p.counterfactual_measured;
  out += fmt::format(". Could fail: {}.\n", to_string(p.can_fail));
  return out;
}

// The parts shown but not counted: identities (by construction, a counterfactual that did not
// flip, no variation) and parts not shown able to fail.
void identity_section(std::ostringstream& md, const std::vector<ClaimResult>& items) {
  std::string rows;
  int identities = 0, not_shown = 0;
  for (const ClaimResult& c : items)
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const PartResult& p = c.parts[k];
      if (p.verdict != Verdict::Identity && p.verdict != Verdict::NotShown) continue;
      ++(p.verdict == Verdict::Identity ? identities : not_shown);
      rows += fmt::format("| [{}](#{}) | {} | {} | {} | {} |\n", part_id(c, k), anchor(c.id), cell(p.says),
                          code_cell(p.rule), verdict_word(p.verdict, c.kind),
                          cell(p.reason.empty() ? to_string(p.can_fail) : p.reason));
    }
  md << "## Identities and parts not shown able to fail\n\n"
     << "A verdict counts only when it could have come out the other way: each decided part names a "
        "counterfactual, a variant of its runs under which its rule should give the other verdict, and the "
        "variant is run in every tier. A part whose counterfactual does not flip its rule, whose compared "
        "measures do not vary beyond round-off across their runs, or that holds by construction is an "
        "**identity**; a decided part without a counterfactual is **not shown able to fail**. Both are shown "
        "here and never counted (`docs/experiments.md`).\n\n";
  if (rows.empty()) {
    md << "None.\n\n";
    return;
  }
  md << fmt::format("{} {}, {} not shown able to fail.\n\n", identities, identities == 1 ? "identity" : "identities",
                    not_shown)
     << "| part | says | rule | verdict | why |\n|---|---|---|---|---|\n" << rows << "\n";
}

std::string registration_text(const RegistrationStatus& st) {
  using State = RegistrationStatus::State;
  const std::string hash = st.sha256.substr(0, 12);
  switch (st.state) {
    case State::Unregistered:
      return fmt::format("not registered (file sha256 {}): nothing shows that its rules came before its results", hash);
    case State::Modified:
      return fmt::format("changed since its registration of {} (file sha256 {}, registered {}): register the "
                         "revision (`pbdbench register`) before trusting the order of rules and results",
                         st.latest->registered, hash, st.latest->sha256.substr(0, 12));
    case State::Registered: break;
  }
  std::string out = fmt::format("registered {} (sha256 {})", st.latest->registered, hash);
  if (!st.commit.empty()) out += fmt::format(" in commit {} ({})", st.commit.substr(0, 10), st.commit_date);
  if (st.before_results)
    out += *st.before_results ? fmt::format("; the results come from a build of commit {}, which contains it: "
                                            "registered before its results",
                                            st.results_commit.substr(0, 10))
                              : fmt::format("; the results come from a build of commit {}, which does not contain "
                                            "the registration: the results came first",
                                            st.results_commit.substr(0, 10));
  else
    out += "; whether before its results is not checked: " + st.why_unchecked;
  return out;
}

// The short form for a table cell.
std::string registration_cell(const RegistrationStatus* st) {
  if (st == nullptr) return "";
  using State = RegistrationStatus::State;
  if (st->state == State::Unregistered) return "not registered";
  if (st->state == State::Modified) return "changed since registered";
  std::string out = st->latest->registered.substr(0, 10);
  if (st->before_results) out += *st->before_results ? ", before results" : ", after results";
  if (!st->revisions.empty()) out += fmt::format(", revised {}×", st->revisions.size());
  return out;
}

// Whether the parts' rules were first written before any result or revised after results.
std::string rules_cell(const RegistrationStatus* st, const ClaimResult& c) {
  if (st == nullptr) return "";
  int revised = 0;
  for (size_t k = 0; k < c.parts.size(); ++k)
    revised += part_history(st, part_id(c, k), c.parts[k]).revised_after_results;
  return revised == 0 ? "rules written before any result"
                      : fmt::format("{} of {} parts revised after results", revised, c.parts.size());
}

// A part's verdict under each registered version that had results, and today's.
std::string versions_line(const RegistrationStatus* st, const std::string& id, const PartResult& p,
                          ExperimentKind kind) {
  const PartHistory h = part_history(st, id, p);
  if (h.versions.empty()) return "";
  return fmt::format("- Versions{}: {}; today: `{}` {}\n",
                     h.revised_after_results ? " (revised after results)" : " (rule and words unchanged)",
                     fmt::join(h.versions, "; "), p.rule, verdict_word(p.verdict, kind));
}

void revisions_section(std::ostringstream& md, const RegistrationStatus* st) {
  if (st == nullptr || st->revisions.empty()) return;
  for (const Registration* r : st->revisions) {
    const EarlierResult& e = *r->earlier;
    md << fmt::format("**Revised after results** (registered {}): {}\n\n", r->registered, r->note);
    md << fmt::format("The version it revised had results ({}): verdict **{}**.\n\n", e.source, e.verdict);
    if (!e.parts.empty()) {
      md << "| earlier part | it said | its rule | its verdict |\n|---|---|---|---|\n";
      for (const auto& [id, verdict] : e.parts) {
        const auto rule = e.rules.find(id);
        const auto says = e.says.find(id);
        md << fmt::format("| {} | {} | {} | {} |\n", id, says == e.says.end() ? "" : cell(says->second),
                          rule == e.rules.end() ? "" : code_cell(rule->second),
                          verdict);
      }
      md << "\n";
    }
  }
}

// The table of an experiment's measures: name, value, units, what it is, how it was taken.
void measures_table(std::ostringstream& md, const ClaimResult& c) {
  if (c.measures.empty()) return;
  md << "| measure | value | units | what it is | taken as |\n|---|---|---|---|---|\n";
  for (const MeasureResult& m : c.measures) {
    std::string how = "`" + m.expression + "`";
    if (!m.run.empty())
      how += m.trials.size() > 1 ? fmt::format(" of run {}, {} over {} trials", m.run, m.over_trials, m.trials.size())
                                 : fmt::format(" of run {}", m.run);
    if (!m.timing.empty())
      how += fmt::format(" per repeat of timing group {}: median of {}, interval of the median at {:.1f} %", m.timing,
                         m.trials.size(), 100.0 * m.coverage);
    else if (m.interval)
      how += " (interval: at the ends of the intervals it reads)";
    const std::string value =
        m.interval ? fmt::format("{} [{}, {}]", number(m.value), number(m.lo), number(m.hi)) : number(m.value);
    md << fmt::format("| {} | {} | {} | {} | {} |\n", m.name, value, m.units, cell(m.doc), cell(how));
  }
  md << "\n";
}

void timings_table(std::ostringstream& md, const ClaimResult& c) {
  for (const TimingResult& t : c.timings) {
    md << fmt::format("Timing group **{}**: {} repeats after a warm-up, runs interleaved (order rotated each repeat), "
                      "solver time per step; measured on {}, {}{}.\n\n",
                      t.group, t.seconds_per_step.size(), t.machine, t.build, t.reused ? " (record reused)" : "");
    md << "| run | median (ms/step) | 95 % interval of the median | min | max | status |\n|---|---|---|---|---|---|\n";
    for (size_t k = 0; k < t.runs.size(); ++k) {
      std::vector<double> v;
      for (const auto& row : t.seconds_per_step) v.push_back(row[k] * 1e3);
      const MedianInterval mi = median_interval(v);
      const double lo = v.empty() ? 0.0 : *std::min_element(v.begin(), v.end());
      const double hi = v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
      md << fmt::format("| {} | {} | [{}, {}] | {} | {} | {} |\n", t.runs[k], number(mi.median), number(mi.lo),
                        number(mi.hi), number(lo), number(hi), t.status[k]);
    }
    md << "\n";
  }
}

void runs_table(std::ostringstream& md, const ClaimResult& c) {
  if (c.runs.empty()) return;
  md << "| run | solver | trials | complete | exploded | failed | warned |\n|---|---|---|---|---|---|---|\n";
  std::string notes;  // the first warning of each warned run, under the table
  for (const RunResult& r : c.runs) {
    std::string solver = r.solver;
    if (r.solver == "pbd-seed")
      solver += r.seed_fixes.empty() ? " (as printed)" : fmt::format(" (fixes {})", fmt::join(r.seed_fixes, " "));
    if (r.timing_only) {
      md << fmt::format("| {} | {} | timed only | | | | |\n", r.name, solver);
      continue;
    }
    md << fmt::format("| {} | {} | {} | {} | {} | {} | {} |\n", r.name, solver, r.files.size(), r.complete, r.exploded,
                      r.failed + r.incomplete, r.warned);
    if (r.warned > 0) notes += fmt::format("- {}: {}\n", r.name, r.first_warning);
  }
  md << "\n";
  if (!notes.empty())
    md << "Warnings (what a reader would call a failure though no explosion limit was crossed; the first "
          "of each run):\n\n" << notes << "\n";
}

const RegistrationStatus* status_of(const ReportContext& ctx, const std::string& id) {
  const auto it = ctx.registration.find(id);
  return it == ctx.registration.end() ? nullptr : &it->second;
}

std::string counts_phrase(const int counts[], ExperimentKind kind, const std::vector<Verdict>& order) {
  std::vector<std::string> out;
  for (Verdict v : order) out.push_back(fmt::format("{} {}", counts[static_cast<int>(v)], verdict_word(v, kind)));
  return fmt::format("{}", fmt::join(out, ", "));
}

// The reproductions' report.
std::string reproduction_markdown(const std::vector<ClaimResult>& items, const ReportContext& ctx) {
  std::ostringstream md;
  md << "# Reproductions\n\n"
     << "Published results of the papers that define position-based dynamics in practice, run again here. "
        "Each reproduction is a file in `reproductions/experiments/`, registered before its result "
        "(`reproductions/registry.toml`): the setup, with every value labelled as taken from the paper "
        "(with its source) or assumed (with why), the runs, the measures, and for each published number "
        "the rule that decides it. A part is **reproduced** when its rule holds and **not reproduced** "
        "when it does not; **inconclusive** when a run it needs failed or left its valid regime, or a "
        "timing's 95 % interval straddles the threshold; **setup unknown** when the paper's setup cannot "
        "be recovered (our outcome under an assumed setup is shown, not counted); **identity** when the "
        "check holds by construction (shown, not counted); **not testable** says why not. Costs are "
        "ratios of repeated, interleaved measurements on one machine (median and 95 % interval), never "
        "absolute times against the papers' hardware. The seed article's claims, put to the test the same "
        "way, are in [claims/](claims/README.md).\n\n"
     << fmt::format("Generated by `{}` ({} tier) on {}, {}. Do not edit: run the command again.\n\n", ctx.command,
                    to_string(ctx.tier), ctx.machine, ctx.build)
     << "**" << part_counts_line(items) << ".**\n\n**" << experiment_counts_line(items) << ".**\n\n"
     << "**" << revisions_line(items, ctx) << ".**\n\n";
  md << "| part | published | source | ours | rule | verdict | could fail |\n|---|---|---|---|---|---|---|\n";
  for (const ClaimResult& c : items) {
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const PartResult& p = c.parts[k];
      std::string ours;
      if (!p.ours.empty())
        for (const MeasureResult& m : c.measures)
          if (m.name == p.ours) ours = measure_value(m);
      md << fmt::format("| [{}](#{}) {} | {} | {} | {} | {} | **{}** | {} |\n", part_id(c, k), anchor(c.id),
                        cell(p.says), cell(p.published), cell(p.source), cell(ours), code_cell(p.rule),
                        verdict_word(p.verdict, c.kind), can_fail_cell(p, c.kind));
    }
  }
  md << "\n";
  identity_section(md, items);
  for (const ClaimResult& c : items) {
    const RegistrationStatus* st = status_of(ctx, c.id);
    md << fmt::format("## {}\n\n", c.id);
    md << fmt::format("**{}**, {}. {}\n\nVerdict: **{}**.\n\n", c.paper, c.section, c.claim,
                      verdict_word(c.verdict, c.kind));
    md << "**Setup.** " << c.experiment << fmt::format(" (`{}`)\n\n", c.file.filename().string());
    if (!c.setup.empty()) {
      md << "| setup | value | from | source, or why |\n|---|---|---|---|\n";
      for (const SetupSpec& s : c.setup)
        md << fmt::format("| {} | {} | {} | {} |\n", cell(s.what), cell(s.value), to_string(s.from),
                          cell(s.from == SetupFrom::Paper ? s.source : s.why));
      md << "\n";
    }
    if (st != nullptr) md << "**Registration.** " << registration_text(*st) << ".\n\n";
    revisions_section(md, st);
    md << "| part | published | source | ours | rule | verdict |\n|---|---|---|---|---|---|\n";
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const PartResult& p = c.parts[k];
      const std::string ours = p.ours.empty() ? "" : fmt::format("{} = {}", p.ours, with_units(p.ours_value, p.ours_units));
      std::string rule = code_cell(p.rule);
      if (!p.requires_.empty()) rule += " (requires `" + cell(p.requires_) + "`)";
      md << fmt::format("| {}: {} | {} | {} | {} | {} | {} |\n", part_id(c, k), cell(p.says), cell(p.published),
                        cell(p.source), cell(ours), rule, cell(verdict_with_reason(p, c.kind)));
    }
    md << "\n";
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const std::string line = counterfactual_line(c.parts[k], c.kind);
      if (!line.empty()) md << "- " << part_id(c, k) << line.substr(1);
      const std::string versions = versions_line(st, part_id(c, k), c.parts[k], c.kind);
      if (!versions.empty()) md << "- " << part_id(c, k) << versions.substr(1);
    }
    if (st != nullptr) md << "Rules: " << rules_cell(st, c) << ".\n";
    md << "\n";
    if (c.figure.kind != "none")
      md << fmt::format("![{}]({})\n\n", c.id, (ctx.figures_dir / (c.id + ".png")).generic_string());
    measures_table(md, c);
    timings_table(md, c);
    runs_table(md, c);
  }
  return md.str();
}

}  // namespace

std::string part_id(const ClaimResult& c, size_t k) { return fmt::format("{}.{}", c.id, k + 1); }

PartHistory part_history(const RegistrationStatus* st, const std::string& id, const PartResult& p) {
  PartHistory h;
  if (st == nullptr) return h;
  for (size_t i = 0; i < st->entries.size(); ++i) {
    const Registration& r = *st->entries[i];
    if (!r.earlier) continue;
    const EarlierResult& e = *r.earlier;
    const auto verdict = e.parts.find(id);
    const auto rule = e.rules.find(id);
    const auto says = e.says.find(id);
    if (rule != e.rules.end() && rule->second != p.rule) h.revised_after_results = true;
    if (says != e.says.end() && says->second != p.says) h.revised_after_results = true;
    if (verdict == e.parts.end()) continue;
    // Entry i revised the version registered by entry i - 1 (entry 0: a version before any
    // registration).
    const std::string label = i == 0 ? std::string("before registration")
                                     : "registered " + st->entries[i - 1]->registered.substr(0, 10);
    h.versions.push_back(fmt::format("{}: {}{}", label,
                                     rule == e.rules.end() ? std::string() : "`" + rule->second + "` ",
                                     verdict->second));
    if (i > 0 && !h.first_registered_known) {
      h.first_registered_known = true;
      h.first_registered = verdict->second;
    }
  }
  return h;
}

std::string revisions_line(const std::vector<ClaimResult>& results, const ReportContext& ctx) {
  if (results.empty()) return "no revisions";
  const ExperimentKind kind = results.front().kind;
  int changed = 0, counted = 0, revised = 0, revised_counted = 0;
  int first[kVerdictCount] = {}, now[kVerdictCount] = {};
  for (const ClaimResult& c : results) {
    const auto it = ctx.registration.find(c.id);
    const RegistrationStatus* st = it == ctx.registration.end() ? nullptr : &it->second;
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const PartResult& p = c.parts[k];
      if (p.beyond) continue;
      const PartHistory h = part_history(st, part_id(c, k), p);
      const bool is_counted = p.verdict == Verdict::Supported || p.verdict == Verdict::Contradicted;
      counted += is_counted;
      revised += h.revised_after_results;
      revised_counted += h.revised_after_results && is_counted;
      Verdict then = p.verdict;
      if (h.first_registered_known && !parse_verdict(h.first_registered, then)) then = Verdict::NotTestable;
      ++first[static_cast<int>(then)];
      ++now[static_cast<int>(p.verdict)];
      if (is_counted && h.first_registered_known && then != p.verdict) ++changed;
    }
  }
  auto pair = [&](const int counts[]) {
    return fmt::format("{} {}, {} {}", counts[static_cast<int>(Verdict::Supported)],
                       verdict_word(Verdict::Supported, kind), counts[static_cast<int>(Verdict::Contradicted)],
                       verdict_word(Verdict::Contradicted, kind));
  };
  return fmt::format("Revisions: {} of the {} counted verdicts differ from the verdict under their first registered "
                     "version; counted by the first registered versions' verdicts (today's where no registered "
                     "version before today's had results): {}, against {} today; {} {} revised after results "
                     "({} of them counted today)",
                     changed, counted, pair(first), pair(now), revised, revised == 1 ? "part's rule or words were" : "parts' rules or words were",
                     revised_counted);
}

std::string part_counts_line(const std::vector<ClaimResult>& results) {
  if (results.empty()) return "no parts";
  const ExperimentKind kind = results.front().kind;
  const PartCounts pc = count_parts(results);
  int article = 0, beyond = 0;
  for (int k = 0; k < kVerdictCount; ++k) article += pc.article[k], beyond += pc.beyond[k];
  const int identities = pc.article[static_cast<int>(Verdict::Identity)];
  const int not_shown = pc.article[static_cast<int>(Verdict::NotShown)];
  const std::string uncounted = fmt::format("{} {} and {} not shown able to fail, shown but not counted", identities,
                                            identities == 1 ? "identity" : "identities", not_shown);
  if (kind == ExperimentKind::Reproduction) {
    return fmt::format("{} published results, counted by part: {}; {}", article,
                       counts_phrase(pc.article, kind,
                                     {Verdict::Supported, Verdict::Contradicted, Verdict::Inconclusive,
                                      Verdict::SetupUnknown, Verdict::NotTestable}),
                       uncounted);
  }
  std::string out = fmt::format(
      "{} {} in the article's regime: {}; {}", article, article == 1 ? "part" : "parts",
      counts_phrase(pc.article, kind,
                    {Verdict::Supported, Verdict::Contradicted, Verdict::Inconclusive, Verdict::NotTestable}),
      uncounted);
  if (beyond > 0)
    out += fmt::format("; {} beyond it: {}", beyond,
                       counts_phrase(pc.beyond, kind,
                                     {Verdict::Supported, Verdict::Contradicted, Verdict::Inconclusive,
                                      Verdict::NotTestable, Verdict::Identity, Verdict::NotShown}));
  return out;
}

std::string experiment_counts_line(const std::vector<ClaimResult>& results) {
  if (results.empty()) return "no experiments";
  const ExperimentKind kind = results.front().kind;
  int counts[kVerdictCount] = {};
  for (const ClaimResult& r : results) ++counts[static_cast<int>(r.verdict)];
  std::vector<Verdict> order = {Verdict::Supported, Verdict::Contradicted, Verdict::Mixed, Verdict::Inconclusive,
                                Verdict::NotTestable};
  if (kind == ExperimentKind::Reproduction) order.push_back(Verdict::SetupUnknown);
  order.push_back(Verdict::NotShown);
  order.push_back(Verdict::Identity);
  return fmt::format("{} {}, each from its decided parts in {} regime: {}", results.size(),
                     kind == ExperimentKind::Claim ? (results.size() == 1 ? "claim with an experiment" : "claims with an experiment")
                                                   : (results.size() == 1 ? "experiment" : "experiments"),
                     kind == ExperimentKind::Claim ? "the article's" : "the paper's", counts_phrase(counts, kind, order));
}

std::string report_markdown(const std::vector<ClaimResult>& claims, const ReportContext& ctx) {
  if (!claims.empty() && claims.front().kind == ExperimentKind::Reproduction)
    return reproduction_markdown(claims, ctx);
  std::ostringstream md;
  md << "# The seed article on trial\n\n";
  if (ctx.index != nullptr) {
    const SourceText& s = ctx.index->source;
    md << fmt::format("**The article.** {} — {}, in {}. Author: {}. {} The text as received has SHA-256 `{}`; "
                      "its claims, with the original sentences and English translations, are indexed in "
                      "`claims/index.toml`.\n\n",
                      s.title, s.kind, s.language, s.author, s.origin, s.sha256);
  }
  md << "Every claim of the article that an experiment can decide is put to one here. Each experiment is a file "
        "in `claims/experiments/`, registered before its results (`claims/registry.toml`, `pbdbench register`): "
        "the runs it makes, what it measures from their run files, which costs it times, and for each part of "
        "the claim the article's sentence (original and translation), the reading tested, and the rule, with its "
        "thresholds, that decides it. Parts run first in the regime the article means (its iteration counts, "
        "steps and scenes); a part that goes beyond that regime is labelled *beyond* and does not make the "
        "claim's verdict. A part **judges the listing** (the article's code as printed, whose defects are judged "
        "once, there) or **judges the method** (run by the listing repaired, `pbd-seed` with the defect fixes "
        "D1 D3 D4 D5 D6 D7 D8 D9 of `docs/seed-departures.md`, or by `pbd`).\n\n"
     << "A part is **supported** when its rule holds, **contradicted** when it does not, **inconclusive** when a "
        "run it needs failed, exploded without the part accounting for it, or left the regime the part requires, "
        "or when a timing's 95 % interval straddles the threshold, and **not testable** when it names something "
        "the harness cannot measure (the reason is given). A claim is **supported** when all of its decided "
        "parts in the article's regime are, **contradicted** when all are contradicted, **mixed** when both "
        "occur, and **inconclusive** when none is decided. Costs are measured like a benchmark: repeated, "
        "interleaved runs, the median and a 95 % interval.\n\n"
     << "`pbdbench` solvers: `pbd-seed` is the article's own code to the letter unless fixes are named, `pbd` is "
        "Mueller et al. 2007, `xpbd` is Macklin et al. 2016, `force-symplectic` an explicit force-based "
        "integrator, `ref-*` the implicit reference integrators and `global-*` the converged global projection "
        "(`docs/solvers.md`).\n\n"
     << fmt::format("Generated by `{}` ({} tier) on {}, {}. Do not edit: run the command again.\n\n", ctx.command,
                    to_string(ctx.tier), ctx.machine, ctx.build)
     << "**" << part_counts_line(claims) << ".**\n\n**" << experiment_counts_line(claims) << ".**\n\n"
     << "**" << revisions_line(claims, ctx) << ".**\n\n";
  if (ctx.index != nullptr) {
    int untestable = 0;
    for (const IndexedClaim& c : ctx.index->claims) untestable += !c.untestable.empty();
    md << fmt::format("The index holds {} claims: {} with an experiment, {} not testable here (listed at the end "
                      "with their reasons).\n\n",
                      ctx.index->claims.size(), ctx.index->claims.size() - untestable, untestable);
  }

  md << "## Verdicts\n\n"
     << "| id | the claim | parts | verdict | registered |\n|---|---|---|---|---|\n";
  for (const ClaimResult& c : claims) {
    int counts[kVerdictCount] = {};
    int beyond = 0;
    for (const PartResult& p : c.parts) {
      if (p.beyond) ++beyond;
      else ++counts[static_cast<int>(p.verdict)];
    }
    std::vector<std::string> parts;
    for (Verdict v : {Verdict::Supported, Verdict::Contradicted, Verdict::Inconclusive, Verdict::NotTestable,
                      Verdict::Identity, Verdict::NotShown})
      if (counts[static_cast<int>(v)] > 0) parts.push_back(fmt::format("{} {}", counts[static_cast<int>(v)], to_string(v)));
    if (beyond > 0) parts.push_back(fmt::format("{} beyond", beyond));
    std::string claim = c.claim;
    if (ctx.index != nullptr)
      if (const IndexedClaim* ic = ctx.index->find(c.id)) claim = ic->claim;
    const RegistrationStatus* rst = status_of(ctx, c.id);
    std::string registered = registration_cell(rst);
    if (const std::string rules = rules_cell(rst, c); !rules.empty()) registered += "; " + rules;
    md << fmt::format("| [{}](#{}) | {} | {} | **{}** | {} |\n", c.id, anchor(c.id), cell(claim),
                      fmt::join(parts, ", "), to_string(c.verdict), registered);
  }
  md << "\n";

  for (const ClaimResult& c : claims) {
    const IndexedClaim* ic = ctx.index != nullptr ? ctx.index->find(c.id) : nullptr;
    const RegistrationStatus* st = status_of(ctx, c.id);
    md << fmt::format("## {}\n\n", c.id);
    md << fmt::format("Section {} of the article. Verdict: **{}**.\n\n", c.section, to_string(c.verdict));
    md << "**The claim.** " << (ic != nullptr ? ic->claim : c.claim) << "\n\n";
    if (ic != nullptr) md << block_quote(ic->original) << ">\n" << block_quote(ic->translation) << "\n";
    md << "**The experiment.** " << c.experiment << fmt::format(" (`{}`)\n\n", c.file.filename().string());
    if (st != nullptr) md << "**Registration.** " << registration_text(*st) << ".\n\n";
    revisions_section(md, st);
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const PartResult& p = c.parts[k];
      md << fmt::format("**{}** — judges the {}{} — {}\n\n", part_id(c, k), to_string(p.judges),
                        p.beyond ? ", **beyond the article's regime**" : "",
                        verdict_with_reason(p, c.kind));
      md << block_quote(p.quote) << ">\n" << block_quote(p.translation) << "\n";
      md << "- Tested: " << p.says << "\n";
      if (!p.reading.empty()) md << "- Reading: " << p.reading << "\n";
      if (!p.truth.empty()) md << "- Judged against: " << p.truth << "\n";
      if (!p.rule.empty()) {
        md << "- Rule: `" << p.rule << "`";
        if (!p.requires_.empty()) md << ", decided only when `" << p.requires_ << "`";
        md << "\n";
        const std::string m = measured(c, p);
        if (!m.empty()) md << "- Measured: " << m << "\n";
      }
      if (!p.judged_with.empty()) md << "- Runs: " << fmt::format("{}", fmt::join(p.judged_with, "; ")) << "\n";
      md << counterfactual_line(p, c.kind);
      md << versions_line(st, part_id(c, k), p, c.kind);
      md << "\n";
    }
    measures_table(md, c);
    timings_table(md, c);
    runs_table(md, c);
    if (c.figure.kind != "none")
      md << fmt::format("![{}]({})\n\n", c.id, (ctx.figures_dir / (c.id + ".png")).generic_string());
  }

  identity_section(md, claims);
  if (ctx.index != nullptr) {
    md << "## Claims not testable here\n\n";
    for (const IndexedClaim& ic : ctx.index->claims) {
      if (ic.untestable.empty()) continue;
      md << fmt::format("**{}** (section {}). {}\n\n", ic.id, ic.section, ic.claim);
      md << block_quote(ic.original) << ">\n" << block_quote(ic.translation) << "\n";
      md << "Not testable here: " << ic.untestable << "\n\n";
    }
  }
  return md.str();
}

std::string results_json(const std::vector<ClaimResult>& claims, const ReportContext& ctx, const fs::path& relative_to) {
  std::ostringstream js;
  js << "{\n  \"tier\": " << json_string(to_string(ctx.tier)) << ",\n  \"machine\": " << json_string(ctx.machine)
     << ",\n  \"build\": " << json_string(ctx.build) << ",\n  \"command\": " << json_string(ctx.command)
     << ",\n  \"parts\": " << json_string(part_counts_line(claims))
     << ",\n  \"experiments\": " << json_string(experiment_counts_line(claims))
     << ",\n  \"revisions\": " << json_string(revisions_line(claims, ctx)) << ",\n  \"claims\": [\n";
  for (size_t i = 0; i < claims.size(); ++i) {
    const ClaimResult& c = claims[i];
    const RegistrationStatus* st = status_of(ctx, c.id);
    js << "    {\"id\": " << json_string(c.id) << ", \"section\": " << json_string(c.section)
       << ", \"kind\": " << json_string(to_string(c.kind)) << ", \"paper\": " << json_string(c.paper)
       << ", \"verdict\": " << json_string(verdict_word(c.verdict, c.kind))
       << ", \"sha256\": " << json_string(st != nullptr ? st->sha256 : "")
       << ",\n     \"claim\": " << json_string(c.claim) << ",\n     \"figure\": {\"kind\": "
       << json_string(c.figure.kind) << ", \"series\": " << json_string(c.figure.series) << ", \"runs\": [";
    for (size_t k = 0; k < c.figure.runs.size(); ++k) js << (k ? ", " : "") << json_string(c.figure.runs[k]);
    js << "], \"measures\": [";
    for (size_t k = 0; k < c.figure.measures.size(); ++k) js << (k ? ", " : "") << json_string(c.figure.measures[k]);
    js << "], \"log\": " << (c.figure.log ? "true" : "false") << ", \"ylabel\": " << json_string(c.figure.ylabel)
       << ", \"title\": " << json_string(c.figure.title) << "},\n     \"runs\": [";
    for (size_t r = 0; r < c.runs.size(); ++r) {
      const RunResult& run = c.runs[r];
      js << (r ? ",\n       " : "\n       ") << "{\"name\": " << json_string(run.name) << ", \"solver\": "
         << json_string(run.solver) << ", \"complete\": " << run.complete << ", \"exploded\": " << run.exploded
         << ", \"failed\": " << run.failed << ", \"warned\": " << run.warned << ", \"files\": [";
      for (size_t k = 0; k < run.files.size(); ++k) {
        std::error_code ec;
        fs::path p = fs::relative(run.files[k], relative_to, ec);
        if (ec || p.empty()) p = run.files[k];
        js << (k ? ", " : "") << json_string(p.generic_string());
      }
      js << "]}";
    }
    js << "],\n     \"measures\": [";
    for (size_t m = 0; m < c.measures.size(); ++m) {
      const MeasureResult& mr = c.measures[m];
      js << (m ? ",\n       " : "\n       ") << "{\"name\": " << json_string(mr.name) << ", \"value\": "
         << json_number(mr.value) << ", \"units\": " << json_string(mr.units) << ", \"run\": " << json_string(mr.run)
         << ", \"timing\": " << json_string(mr.timing);
      if (mr.interval) js << ", \"lo\": " << json_number(mr.lo) << ", \"hi\": " << json_number(mr.hi);
      js << ", \"trials\": [";
      for (size_t k = 0; k < mr.trials.size(); ++k) js << (k ? ", " : "") << json_number(mr.trials[k]);
      js << "]}";
    }
    js << "],\n     \"parts\": [";
    for (size_t k = 0; k < c.parts.size(); ++k) {
      const PartResult& p = c.parts[k];
      js << (k ? ",\n       " : "\n       ") << "{\"id\": " << json_string(part_id(c, k)) << ", \"says\": "
         << json_string(p.says) << ", \"rule\": " << json_string(p.rule) << ", \"requires\": "
         << json_string(p.requires_) << ", \"verdict\": " << json_string(verdict_word(p.verdict, c.kind))
         << ", \"reason\": " << json_string(p.reason) << ", \"judges\": " << json_string(to_string(p.judges))
         << ", \"regime\": " << json_string(p.beyond ? "beyond" : "article")
         << ", \"truth\": " << json_string(p.truth)
         << ", \"published\": " << json_string(p.published) << ", \"source\": " << json_string(p.source)
         << ", \"ours\": " << json_string(p.ours) << ", \"ours_value\": "
         << (p.ours.empty() ? std::string("null") : json_number(p.ours_value))
         << ", \"timing\": " << (p.timing ? "true" : "false")
         << ", \"measured\": " << json_string(verdict_word(p.measured, c.kind))
         << ", \"outcome\": " << json_number(p.outcome)
         << ", \"identity\": " << json_string(p.identity)
         << ", \"can_fail\": " << json_string(to_string(p.can_fail))
         << ", \"compared_spread\": " << json_string(p.compared_spread);
      {
        const PartHistory h = part_history(st, part_id(c, k), p);
        js << ", \"revised_after_results\": " << (h.revised_after_results ? "true" : "false")
           << ", \"first_registered\": " << json_string(h.first_registered_known ? h.first_registered : "")
           << ", \"versions\": [";
        for (size_t v = 0; v < h.versions.size(); ++v) js << (v ? ", " : "") << json_string(h.versions[v]);
        js << "]";
      }
      js << ", \"counterfactual\": ";
      if (p.has_counterfactual)
        js << "{\"why\": " << json_string(p.counterfactual_why) << ", \"variant\": "
           << json_string(p.counterfactual_variant) << ", \"verdict\": "
           << json_string(verdict_word(p.counterfactual_verdict, c.kind)) << ", \"outcome\": "
           << json_number(p.counterfactual_outcome) << ", \"reason\": " << json_string(p.counterfactual_reason)
           << ", \"measured\": " << json_string(p.counterfactual_measured) << "}";
      else
        js << "null";
      js << "}";
    }
    js << "]}" << (i + 1 < claims.size() ? ",\n" : "\n");
  }
  js << "  ]\n}\n";
  return js.str();
}

std::string verdicts_toml(const std::vector<ClaimResult>& claims, Tier tier) {
  std::ostringstream out;
  out << "# The verdict of every part of every experiment, " << to_string(tier) << " tier, recorded by\n"
      << "# `pbdbench claims|paper --tier " << to_string(tier) << " --record FILE`. The test suite runs the "
      << "quick tier and fails\n# when a verdict differs. Parts whose rules read timing measures are "
      << "recorded but not\n# compared (marked timing).\n";
  for (const ClaimResult& c : claims) {
    out << "\n# " << c.id << ": " << verdict_word(c.verdict, c.kind) << "\n";
    for (size_t k = 0; k < c.parts.size(); ++k) {
      out << "\"" << part_id(c, k) << "\" = \"" << verdict_word(c.parts[k].verdict, c.kind) << "\""
          << (c.parts[k].timing ? "  # timing" : "") << "\n";
    }
  }
  return out.str();
}

std::vector<std::string> verdict_differences(const std::vector<ClaimResult>& claims, const fs::path& record) {
  toml::table table;
  try {
    table = toml::parse_file(record.string());
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(record.string() + ":" + std::to_string(e.source().begin.line) + ": " +
                             std::string(e.description()));
  }
  std::vector<std::string> out;
  for (const ClaimResult& c : claims) {
    for (size_t k = 0; k < c.parts.size(); ++k) {
      if (c.parts[k].timing) continue;
      const std::string id = part_id(c, k);
      const std::optional<std::string> expected = table[id].value<std::string>();
      const std::string got = verdict_word(c.parts[k].verdict, c.kind);
      if (!expected) {
        out.push_back(fmt::format("{}: no recorded verdict (now {})", id, got));
      } else if (*expected != got) {
        out.push_back(fmt::format("{}: recorded {}, now {} ({})", id, *expected, got, c.parts[k].says));
      }
    }
  }
  return out;
}

}  // namespace pbdbench::experiments
