#include "harness/compare.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "runfile/compare_file.hpp"
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------------
// Interpolation of the reference at the matched times.

double value_at(const std::vector<double>& v, const TimeMatch& m, size_t k) {
  const size_t lo = static_cast<size_t>(m.lo[k]), hi = static_cast<size_t>(m.hi[k]);
  if (hi >= v.size()) return kNaN;
  const double w = m.weight[k];
  return w == 0.0 ? v[lo] : (1.0 - w) * v[lo] + w * v[hi];
}

Vec3 row_at(const Points& v, const TimeMatch& m, size_t k) {
  const Eigen::Index lo = m.lo[k], hi = m.hi[k];
  if (hi >= v.rows()) return Vec3::Constant(kNaN);
  const double w = m.weight[k];
  if (w == 0.0) return v.row(lo).transpose();
  return ((1.0 - w) * v.row(lo) + w * v.row(hi)).transpose();
}

double run_value(const std::vector<double>& v, const TimeMatch& m, size_t k) {
  const size_t i = static_cast<size_t>(m.run[k]);
  return i < v.size() ? v[i] : kNaN;
}

Vec3 run_row(const Points& v, const TimeMatch& m, size_t k) {
  return m.run[k] < v.rows() ? Vec3(v.row(m.run[k]).transpose()) : Vec3::Constant(kNaN);
}

bool any_finite(const std::vector<double>& v) {
  return std::any_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

bool any_finite(const Points& p) {
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    if (p.row(i).allFinite()) return true;
  return false;
}

// The median spacing of times[first..last] (NaN with fewer than two).
double median_spacing(const std::vector<double>& times, size_t first, size_t last) {
  std::vector<double> d;
  for (size_t k = first + 1; k <= last && k < times.size(); ++k) d.push_back(times[k] - times[k - 1]);
  if (d.empty()) return kNaN;
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

double tolerance_at(double t) { return kTimeTolerance * std::max(1.0, std::abs(t)); }

// A width-3 observable of both runs at the common rows.
VectorObservable vector_observable(const CompareRun& run, const CompareRun& ref,
                                   const TimeMatch& rows, const std::string& name,
                                   bool relative) {
  VectorObservable o;
  const auto a = run.series3.find(name), b = ref.series3.find(name);
  if (a == run.series3.end() || b == ref.series3.end()) return o;
  if (!any_finite(a->second) && !any_finite(b->second)) return o;
  o.present = true;
  const size_t n = rows.time.size();
  o.run.resize(static_cast<Eigen::Index>(n), 3);
  o.reference.resize(static_cast<Eigen::Index>(n), 3);
  o.gap.resize(n);
  if (relative) o.relative_gap.resize(n);
  for (size_t k = 0; k < n; ++k) {
    const Vec3 x = run_row(a->second, rows, k), y = row_at(b->second, rows, k);
    o.run.row(static_cast<Eigen::Index>(k)) = x.transpose();
    o.reference.row(static_cast<Eigen::Index>(k)) = y.transpose();
    o.gap[k] = (x - y).norm();
    if (relative) o.relative_gap[k] = y.norm() > 0.0 ? o.gap[k] / y.norm() : kNaN;
  }
  return o;
}

// The rows of a series with time <= end (a run's own samples, for the period).
std::vector<double> head(const std::vector<double>& v, const std::vector<double>& time, double end) {
  std::vector<double> out;
  for (size_t k = 0; k < v.size() && k < time.size() && time[k] <= end + tolerance_at(end); ++k)
    out.push_back(v[k]);
  return out;
}

std::map<std::string, std::string> describe(const CompareRun& r) {
  std::map<std::string, std::string> d;
  d["file"] = r.path.string();
  for (const char* key : {"solver", "scenario", "status", "config", "git_commit"})
    d[key] = r.attribute(key);
  return d;
}

// ---------------------------------------------------------------------------------------------
// The summary.

std::string num(double v) { return fmt::format("{:.4g}", v == 0.0 ? 0.0 : v); }  // no "-0"

std::string vec(const Points& p, Eigen::Index row) {
  return fmt::format("({}, {}, {})", num(p(row, 0)), num(p(row, 1)), num(p(row, 2)));
}

std::string run_line(const std::map<std::string, std::string>& r) {
  return fmt::format("{} ({}, {}, {})", r.at("file"), r.at("solver"), r.at("scenario"),
                     r.at("status"));
}

}  // namespace

// ---------------------------------------------------------------------------------------------

std::string CompareRun::attribute(const std::string& name) const {
  const auto it = attributes.find(name);
  return it == attributes.end() ? std::string() : it->second;
}

CompareRun read_compare_run(const fs::path& path) {
  RunFileParts parts;
  parts.frames = RunFileParts::Frames::All;
  parts.velocities = false;
  parts.model = true;
  // A file that is not a run file is bad input (exit 2), named as such, not a failure to read.
  RunFileData data;
  try {
    data = read_run_file(path, parts);
  } catch (const std::exception& e) {
    throw CompareInputError(fmt::format("{} is not a pbdbench run file that compare can read: {}",
                                        path.string(), e.what()));
  }
  if (data.model.rest_positions.rows() == 0 && data.model.inv_mass.empty())
    throw CompareInputError("run file " + path.string() + ": no /model/rest_positions");
  CompareRun r;
  r.path = path;
  r.attributes = std::move(data.attributes);
  r.rest_positions = std::move(data.model.rest_positions);
  r.frame_time = std::move(data.frame_time);
  r.frames = std::move(data.frames);
  r.series = std::move(data.series);
  r.series3 = std::move(data.series3);
  r.units = std::move(data.units);
  r.nondeterministic = std::move(data.nondeterministic);
  return r;
}

TimeMatch match_times(const std::vector<double>& run_times, const std::vector<double>& ref_times,
                      double until) {
  TimeMatch m;
  if (run_times.empty() || ref_times.empty()) return m;
  const double end = std::min({run_times.back(), ref_times.back(), until});
  for (size_t k = 0; k < run_times.size(); ++k) {
    const double t = run_times[k];
    const double tol = tolerance_at(t);
    if (!(t <= end + tol)) break;
    // The first reference time >= t - tol.
    const auto it = std::lower_bound(ref_times.begin(), ref_times.end(), t - tol);
    if (it == ref_times.end()) break;
    const long j = static_cast<long>(it - ref_times.begin());
    if (std::abs(*it - t) <= tol) {
      m.lo.push_back(j);
      m.hi.push_back(j);
      m.weight.push_back(0.0);
      ++m.exact;
    } else if (j == 0) {
      continue;  // before the reference's first sample: nothing to interpolate from
    } else {
      const double t0 = ref_times[static_cast<size_t>(j - 1)], t1 = *it;
      m.lo.push_back(j - 1);
      m.hi.push_back(j);
      m.weight.push_back((t - t0) / (t1 - t0));
    }
    m.time.push_back(t);
    m.run.push_back(static_cast<long>(k));
  }
  return m;
}

double mean_period(const std::vector<double>& time, const std::vector<double>& angle,
                   int* periods) {
  std::vector<double> crossings;
  const size_t n = std::min(time.size(), angle.size());
  for (size_t k = 0; k + 1 < n; ++k) {
    const double a = angle[k], b = angle[k + 1];
    if (!(a < 0.0 && b >= 0.0)) continue;  // false for NaN too
    if (b - a >= std::numbers::pi) continue;  // wrapped round from -pi to pi, not through 0
    crossings.push_back(time[k] + (time[k + 1] - time[k]) * (-a / (b - a)));
  }
  const int full = crossings.size() >= 2 ? static_cast<int>(crossings.size()) - 1 : 0;
  if (periods) *periods = full;
  if (full == 0) return kNaN;
  return (crossings.back() - crossings.front()) / full;
}

const std::set<std::string>& uncompared_series() {
  static const std::set<std::string> names = {
      "time",           "step",           "substeps",          "iterations",
      "contacts",       "active_contacts", "skipped",          "ref_steps",
      "newton_iterations", "linear_setups", "linear_solves",   "error_test_failures",
      "convergence_failures", "cholesky_factorizations", "lu_factorizations", "stop_reason"};
  return names;
}

CompareResult compare_runs(const CompareRun& run, const CompareRun& ref,
                           const CompareOptions& options) {
  const std::string a = run.path.string(), b = ref.path.string();
  if (std::isnan(options.until) || options.until < 0.0)
    throw CompareInputError(fmt::format("--until must be a time >= 0 s, not {}", options.until));

  // The same scene: the same particles at the same rest positions.
  const Eigen::Index n = run.rest_positions.rows();
  if (n != ref.rest_positions.rows())
    throw CompareInputError(fmt::format(
        "{} and {} are not runs of the same scene: {} particles against {}", a, b, n,
        ref.rest_positions.rows()));
  double scale = 1.0, worst = 0.0;
  Eigen::Index where = -1;
  for (Eigen::Index i = 0; i < n; ++i) {
    scale = std::max({scale, run.rest_positions.row(i).norm(), ref.rest_positions.row(i).norm()});
    const double d = (run.rest_positions.row(i) - ref.rest_positions.row(i)).norm();
    if (std::isnan(d)) {  // NaN counts as a difference
      worst = d;
      where = i;
      break;
    }
    if (d > worst) {
      worst = d;
      where = i;
    }
  }
  if (where >= 0 && !(worst <= kRestTolerance * scale))
    throw CompareInputError(fmt::format(
        "{} and {} are not runs of the same scene: their rest positions differ by up to {} m "
        "(particle {})",
        a, b, num(worst), where));

  CompareResult r;
  r.run = describe(run);
  r.reference = describe(ref);
  r.until = options.until;
  if (r.run["scenario"] != r.reference["scenario"])
    r.warnings.push_back(fmt::format(
        "the scenario names differ ({} against {}): compared as the same scene, since the "
        "particles and their rest positions agree",
        r.run["scenario"], r.reference["scenario"]));

  // Positions at the run's frame times.
  r.frames = match_times(run.frame_time, ref.frame_time, options.until);
  if (r.frames.time.empty())
    throw CompareInputError(fmt::format("{} and {} have no frame in common (before {} s)", a, b,
                                        num(options.until)));
  const size_t F = r.frames.time.size();
  r.position_error_rms.resize(F);
  r.position_error_max.resize(F);
  for (size_t k = 0; k < F; ++k) {
    const Points& x = run.frames[static_cast<size_t>(r.frames.run[k])];
    const Points& lo = ref.frames[static_cast<size_t>(r.frames.lo[k])];
    const Points& hi = ref.frames[static_cast<size_t>(r.frames.hi[k])];
    const double w = r.frames.weight[k];
    double sum = 0.0, max = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const Vec3 y = w == 0.0 ? Vec3(lo.row(i).transpose())
                              : Vec3(((1.0 - w) * lo.row(i) + w * hi.row(i)).transpose());
      const double e = (Vec3(x.row(i).transpose()) - y).norm();
      sum += e * e;
      max = std::isnan(e) || std::isnan(max) ? kNaN : std::max(max, e);
    }
    r.position_error_rms[k] = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
    r.position_error_max[k] = max;
  }
  r.frame_spacing_run =
      median_spacing(run.frame_time, static_cast<size_t>(r.frames.run.front()),
                     static_cast<size_t>(r.frames.run.back()));
  r.frame_spacing_reference =
      median_spacing(ref.frame_time, static_cast<size_t>(r.frames.lo.front()),
                     static_cast<size_t>(r.frames.hi.back()));
  if (r.frame_spacing_reference > r.frame_spacing_run * (1.0 + 1e-6))
    r.warnings.push_back(fmt::format(
        "the reference's frames are sparser than the run's (every {} s against {} s): {} of {} "
        "frames compared against a linear interpolation between two of its frames, which is "
        "off by up to about |acceleration| spacing^2 / 8; write more reference frames "
        "(output.frame_every)",
        num(r.frame_spacing_reference), num(r.frame_spacing_run),
        static_cast<long>(F) - r.frames.exact, F));

  // Series at the run's series times.
  const auto run_time = run.series.find("time"), ref_time = ref.series.find("time");
  if (run_time != run.series.end() && ref_time != ref.series.end())
    r.rows = match_times(run_time->second, ref_time->second, options.until);
  const size_t R = r.rows.time.size();
  auto compared = [&](const std::string& name) {
    return !uncompared_series().count(name) && !run.nondeterministic.count(name) &&
           !ref.nondeterministic.count(name);
  };
  auto units_of = [&](const std::string& name) {
    const auto u = run.units.find(name);
    return u == run.units.end() ? std::string() : u->second;
  };
  for (const auto& [name, v] : run.series) {
    const auto other = ref.series.find(name);
    if (other == ref.series.end() || !compared(name)) continue;
    std::vector<double>& d = r.diff[name];
    d.resize(R);
    for (size_t k = 0; k < R; ++k) d[k] = run_value(v, r.rows, k) - value_at(other->second, r.rows, k);
    r.diff_width[name] = 1;
    r.diff_units[name] = units_of(name);
  }
  for (const auto& [name, v] : run.series3) {
    const auto other = ref.series3.find(name);
    if (other == ref.series3.end() || !compared(name)) continue;
    std::vector<double>& d = r.diff[name];
    d.resize(R);
    for (size_t k = 0; k < R; ++k) d[k] = (run_row(v, r.rows, k) - row_at(other->second, r.rows, k)).norm();
    r.diff_width[name] = 3;
    r.diff_units[name] = units_of(name);
  }

  // Observables of the scene.
  r.tip_displacement = vector_observable(run, ref, r.rows, "tip_displacement", false);
  r.support_force = vector_observable(run, ref, r.rows, "support_force", true);
  const auto pa = run.series.find("pendulum_angle"), pb = ref.series.find("pendulum_angle");
  if (pa != run.series.end() && pb != ref.series.end() &&
      (any_finite(pa->second) || any_finite(pb->second)) && R > 0) {
    r.pendulum = true;
    for (size_t k = 0; k < R; ++k) {
      r.pendulum_angle_run.push_back(run_value(pa->second, r.rows, k));
      r.pendulum_angle_reference.push_back(value_at(pb->second, r.rows, k));
    }
    // Each run's period from its own samples, over the same window.
    const double end = r.rows.time.back();
    r.period_run = mean_period(head(run_time->second, run_time->second, end),
                               head(pa->second, run_time->second, end), &r.periods_run);
    r.period_reference = mean_period(head(ref_time->second, ref_time->second, end),
                                     head(pb->second, ref_time->second, end), &r.periods_reference);
    r.period_relative_difference = (r.period_run - r.period_reference) / r.period_reference;
  }
  return r;
}

std::string compare_summary(const CompareResult& r) {
  std::string out;
  out += "run:       " + run_line(r.run) + "\n";
  out += "reference: " + run_line(r.reference) + "\n";
  out += "positions at " + match_line(r.frames, "frames") + "\n";
  const size_t F = r.frames.time.size();
  size_t worst = 0;
  for (size_t k = 0; k < F; ++k)
    if (!(r.position_error_max[k] <= r.position_error_max[worst])) worst = k;
  out += fmt::format("  position error at t = {} s: RMS {} m, max {} m\n", num(r.frames.time.back()),
                     num(r.position_error_rms.back()), num(r.position_error_max.back()));
  out += fmt::format("  largest max position error: {} m at t = {} s\n",
                     num(r.position_error_max[worst]), num(r.frames.time[worst]));
  if (r.rows.time.empty()) {
    out += "series: none in common\n";
    return out;
  }
  out += "series at " + match_line(r.rows, "rows") + "\n";
  const Eigen::Index last = static_cast<Eigen::Index>(r.rows.time.size()) - 1;
  out += fmt::format("observables at t = {} s:\n", num(r.rows.time.back()));
  bool any = false;
  if (r.tip_displacement.present) {
    const VectorObservable& v = r.tip_displacement;
    out += fmt::format("  tip displacement: run {} m, reference {} m, gap {} m\n", vec(v.run, last),
                       vec(v.reference, last), num(v.gap.back()));
    any = true;
  }
  if (r.support_force.present) {
    const VectorObservable& v = r.support_force;
    // The relative gap only where it has a value: a reference support force of zero (no pins)
    // leaves none to divide by.
    const double relative = v.relative_gap.back();
    out += fmt::format("  support force: run {} N, reference {} N, gap {} N{}\n", vec(v.run, last),
                       vec(v.reference, last), num(v.gap.back()),
                       std::isfinite(relative) ? " (" + num(relative) + " relative)" : "");
    for (const auto& [who, p] : {std::pair{"run", &v.run}, std::pair{"reference", &v.reference}})
      if (!any_finite(*p))
        out += fmt::format("    (NaN throughout in the {}: its solver keeps no multipliers, or an "
                           "FEM element touches a support)\n", who);
    any = true;
  }
  if (r.pendulum) {
    out += fmt::format(
        "  pendulum angle: run {} rad, reference {} rad\n"
        "  pendulum period: run {} s ({} full periods), reference {} s ({}), relative "
        "difference {}\n",
        num(r.pendulum_angle_run.back()), num(r.pendulum_angle_reference.back()), num(r.period_run),
        r.periods_run, num(r.period_reference), r.periods_reference,
        num(r.period_relative_difference));
    any = true;
  }
  if (!any) out += "  none in this scene (no tip, no pendulum bob, no support force in either run)\n";

  // Final differences, in the order of the series table, then the per-group series.
  std::vector<std::string> order;
  for (const SeriesSpec& s : series_table())
    if (r.diff.count(std::string(s.name))) order.emplace_back(s.name);
  for (const auto& [name, v] : r.diff)
    if (std::find(order.begin(), order.end(), name) == order.end()) order.push_back(name);
  size_t width = 0, nan = 0;
  for (const std::string& name : order) width = std::max(width, name.size() + 2);
  std::string rows;
  for (const std::string& name : order) {
    const double v = r.diff.at(name).back();
    if (std::isnan(v)) {
      ++nan;
      continue;
    }
    const std::string shown = r.diff_width.at(name) == 3 ? "|" + name + "|" : name;
    rows += fmt::format("  {:<{}} {:>11} {}\n", shown, width, num(v), r.diff_units.at(name));
  }
  out += fmt::format("final differences, run - reference (|run - reference| for 3-vectors):\n{}",
                     rows);
  if (nan > 0) out += fmt::format("  ({} more are NaN: not defined in one run or both)\n", nan);
  return out;
}

}  // namespace pbdbench
