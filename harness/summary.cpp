#include "harness/summary.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "metrics/health.hpp"
#include "runfile/run_file.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Column {
  const char* title;
  const char* units;
  // Returns NaN when not applicable.
  double (*value)(const RunFileData& d);
};

const std::vector<double>* series(const RunFileData& d, const char* name) {
  auto it = d.series.find(name);
  return it == d.series.end() || it->second.empty() ? nullptr : &it->second;
}

double last(const RunFileData& d, const char* name) {
  auto s = series(d, name);
  return s ? s->back() : kNaN;
}

double peak(const RunFileData& d, const char* name) {
  auto s = series(d, name);
  if (!s) return kNaN;
  double m = -std::numeric_limits<double>::infinity();
  for (double v : *s) {
    if (std::isnan(v)) return kNaN;
    m = std::max(m, v);
  }
  return m;
}

double change(const RunFileData& d, const char* name) {
  auto s = series(d, name);
  return s ? s->back() - s->front() : kNaN;
}

double mean_ms_per_step(const RunFileData& d) {
  auto s = series(d, "wall_step");
  if (!s || s->size() < 2) return kNaN;
  double sum = 0.0;
  for (size_t k = 1; k < s->size(); ++k) sum += (*s)[k];  // row 0 is the initial state
  return 1e3 * sum / static_cast<double>(s->size() - 1);
}

const std::vector<Column>& columns() {
  static const std::vector<Column> cols = {
      {"err max", "final", [](const RunFileData& d) { return last(d, "constraint_error_max"); }},
      {"err max", "peak", [](const RunFileData& d) { return peak(d, "constraint_error_max"); }},
      {"err rms", "final", [](const RunFileData& d) { return last(d, "constraint_error_rms"); }},
      {"vol drift", "final", [](const RunFileData& d) { return last(d, "volume_drift"); }},
      {"energy change", "J", [](const RunFileData& d) { return change(d, "total_energy"); }},
      {"penetration", "peak m", [](const RunFileData& d) { return peak(d, "penetration_max"); }},
      {"solver", "ms/step", [](const RunFileData& d) { return mean_ms_per_step(d); }},
  };
  return cols;
}

std::string steps_text(const RunFileData& d) {
  auto done = d.numbers.find("steps_completed");
  auto planned = d.numbers.find("steps_planned");
  if (done == d.numbers.end() || planned == d.numbers.end()) return "?";
  return fmt::format("{}/{}", static_cast<long>(done->second), static_cast<long>(planned->second));
}

std::string status_text(const RunFileData& d) {
  std::string s = d.status();
  if (const size_t n = d.warnings().size(); n > 0) s += fmt::format(" !{}", n);
  if (s == "exploded") {
    auto step = d.numbers.find("exploded_step");
    if (step != d.numbers.end()) s += fmt::format(" @{}", static_cast<long>(step->second));
  }
  return s;
}

// Why the steps stopped (the stop_reason series, solver_api/solver.hpp): "488 converged, 12
// iteration_limit (not trusted) of 500 steps"; "" for a file without the series or steps.
std::string stops_text(const RunFileData& d) {
  auto s = series(d, "stop_reason");
  if (!s || s->size() < 2) return "";
  std::vector<long> count(stop_reasons().size(), 0);
  long unknown = 0;
  for (size_t k = 1; k < s->size(); ++k) {  // row 0 is the initial state
    const double v = (*s)[k];
    if (v >= 0.0 && v < static_cast<double>(count.size()) && v == std::floor(v))
      ++count[static_cast<size_t>(v)];
    else
      ++unknown;
  }
  std::string out;
  for (const StopReasonInfo& info : stop_reasons()) {
    const long n = count[static_cast<size_t>(info.reason)];
    if (n == 0) continue;
    out += fmt::format("{}{} {}{}", out.empty() ? "" : ", ", n, info.name, info.trusted ? "" : " (not trusted)");
  }
  if (unknown > 0) out += fmt::format("{}{} of an unknown reason", out.empty() ? "" : ", ", unknown);
  return out + fmt::format(" of {} step{}", s->size() - 1, s->size() == 2 ? "" : "s");
}

// What the warnings name, in words: "a link stretched beyond twice its rest length
// (overstretched), particles left the scene's region (left_region)".
std::string symptoms_text(const std::vector<std::string>& warnings) {
  std::string out;
  for (const std::string& w : warnings) {
    const std::string code = w.substr(0, w.find(' '));
    const std::string symptom = symptom_of(code);
    out += (out.empty() ? "" : ", ") + (symptom.empty() ? code : symptom + " (" + code + ")");
  }
  return out;
}

std::string number(double v) {
  if (std::isnan(v)) return "-";
  return fmt::format("{:.3g}", v);
}

}  // namespace

std::string summary_table(const std::vector<SummaryEntry>& entries) {
  std::vector<std::vector<std::string>> rows;
  std::string notes;  // the warnings, under the table
  std::string stops;  // why the steps stopped, under the table
  std::vector<std::string> head1 = {"run", "status", "steps"}, head2 = {"", "", ""};
  for (const Column& c : columns()) {
    head1.push_back(c.title);
    head2.push_back(c.units);
  }
  rows.push_back(head1);
  rows.push_back(head2);
  for (const SummaryEntry& e : entries) {
    std::vector<std::string> row = {e.label};
    try {
      const RunFileData d = read_run_file(e.file);
      row.push_back(status_text(d));
      row.push_back(steps_text(d));
      for (const Column& c : columns()) row.push_back(number(c.value(d)));
      if (const std::vector<std::string> warnings = d.warnings(); !warnings.empty()) {
        notes += "  " + e.label + ": seen: " + symptoms_text(warnings) + "\n";
        for (const std::string& w : warnings) notes += "  " + e.label + ": WARNING " + w + "\n";
      }
      if (const std::string why = stops_text(d); !why.empty()) stops += "  " + e.label + ": " + why + "\n";
    } catch (const std::exception& ex) {
      row.push_back("unreadable");
      row.push_back(ex.what());
    }
    rows.push_back(row);
  }
  std::vector<size_t> width;
  for (const auto& row : rows)
    for (size_t k = 0; k < row.size(); ++k) {
      if (width.size() <= k) width.push_back(0);
      width[k] = std::max(width[k], row[k].size());
    }
  std::string out;
  for (size_t r = 0; r < rows.size(); ++r) {
    std::string line;
    for (size_t k = 0; k < rows[r].size(); ++k) {
      if (k == 0)
        line += fmt::format("{:<{}}", rows[r][k], width[k]);
      else
        line += fmt::format("  {:>{}}", rows[r][k], width[k]);
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out += line + "\n";
    if (r == 1) {
      size_t total = 0;
      for (size_t w : width) total += w + 2;
      out += std::string(total - 2, '-') + "\n";
    }
  }
  if (!stops.empty()) out += "Why the steps stopped (stop_reason, solver_api/solver.hpp):\n" + stops;
  if (!notes.empty())
    out += "!N: N warnings (metrics/health.hpp, docs/failures.md): the failures a practitioner would "
           "see, named by their symptoms, though no explosion limit was crossed\n" + notes;
  return out;
}

std::string summary_csv(const std::vector<SummaryEntry>& entries) {
  std::string out = "run,file,status,steps_completed,steps_planned,warnings";
  for (const Column& c : columns()) out += fmt::format(",{} ({})", c.title, c.units);
  out += ",stop reasons\n";
  for (const SummaryEntry& e : entries) {
    out += fmt::format("\"{}\",\"{}\"", e.label, e.file.string());
    try {
      const RunFileData d = read_run_file(e.file);
      auto num = [&](const char* k) {
        auto it = d.numbers.find(k);
        return it == d.numbers.end() ? std::string("") : fmt::format("{}", static_cast<long>(it->second));
      };
      std::string warnings;
      for (const std::string& w : d.warnings()) warnings += (warnings.empty() ? "" : "; ") + w;
      std::replace(warnings.begin(), warnings.end(), '"', '\'');
      out += fmt::format(",{},{},{},\"{}\"", d.status(), num("steps_completed"), num("steps_planned"), warnings);
      for (const Column& c : columns()) out += fmt::format(",{:.17g}", c.value(d));
      out += ",\"" + stops_text(d) + "\"";
    } catch (const std::exception&) {
      out += ",unreadable,,,";
      for (size_t k = 0; k <= columns().size(); ++k) out += ",";
    }
    out += "\n";
  }
  return out;
}

}  // namespace pbdbench
