#include "runfile/compare_file.hpp"

#include <fmt/format.h>

#include <array>
#include <stdexcept>

#include "runfile/layout.hpp"
#include "runfile/output_guard.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr const char* kContent = "pbdbench compare";

using R = CompareResult;
using layout::IndexPairs;

// ---------------------------------------------------------------------------------------------
// The layout.

const std::array kHead = {
    PBDBENCH_DERIVED(R, "content", "", "the kind of file: `pbdbench compare`", std::string(kContent)),
    PBDBENCH_DERIVED(R, "compare_format_version", "", "the layout's version: 1", 1LL),
};
// (then run_<key> and reference_<key>: the two runs' maps)

const std::array kRoot = {
    PBDBENCH_ATTRIBUTE(R, "until", "s", "the comparison's end asked for (inf without `--until`)", until),
    PBDBENCH_DERIVED(R, "end_time", "s", "the last common frame time (NaN when none)",
                     r.frames.time.empty() ? kNaN : r.frames.time.back()),
    PBDBENCH_DERIVED(R, "frames_used", "", "the common frames, and which of the reference's were its own or interpolated, in words",
                     r.frames.time.empty() ? std::string() : match_line(r.frames, "frames")),
    PBDBENCH_DERIVED(R, "rows_used", "", "the same of the series rows",
                     r.rows.time.empty() ? std::string() : match_line(r.rows, "rows")),
    PBDBENCH_ATTRIBUTE(R, "frame_spacing_run", "s", "median spacing of the run's frames compared",
                       frame_spacing_run),
    PBDBENCH_ATTRIBUTE(R, "frame_spacing_reference", "s",
                       "the same of the reference's frames in the window",
                       frame_spacing_reference),
    layout::AttributeSpec<R>{
        "warnings", "", "the comparison's warnings, one per line; empty when none",
        [](const R& r) { return layout::Value(layout::join_lines(r.warnings)); },
        [](R& r, const layout::Value& v) {
          if (const auto* s = std::get_if<std::string>(&v)) r.warnings = layout::split_lines(*s);
        }},
    // (then created and the build's provenance)
};

// The indices of a TimeMatch's reference samples, (K, 2): lo and hi.
IndexPairs pairs(const TimeMatch& m) {
  IndexPairs out;
  for (size_t i = 0; i < m.time.size(); ++i) out.push_back({m.lo[i], m.hi[i]});
  return out;
}

void unpair(TimeMatch& m, layout::Array&& a) {
  IndexPairs p;
  layout::assign(p, std::move(a));
  m.lo.clear();
  m.hi.clear();
  m.exact = 0;
  for (const auto& [lo, hi] : p) {
    m.lo.push_back(static_cast<long>(lo));
    m.hi.push_back(static_cast<long>(hi));
    if (lo == hi) ++m.exact;
  }
}

#define PBDBENCH_PAIRS(path, doc, match)                                                       \
  layout::DatasetSpec<R> {                                                                     \
    path, "", doc, [](const R& r) { return layout::Array(pairs(r.match)); },                   \
        [](R& r, layout::Array&& a) { unpair(r.match, std::move(a)); }                         \
  }

// /compare
const std::array kCompare = {
    PBDBENCH_DATASET(R, "time", "s", "common frame times (the run's frame times)", frames.time),
    PBDBENCH_DATASET(R, "position_error_rms", "m",
                     "root mean square over particles of |x_run - x_reference| at each common "
                     "frame time",
                     position_error_rms),
    PBDBENCH_DATASET(R, "position_error_max", "m",
                     "max over particles of |x_run - x_reference| at each common frame time",
                     position_error_max),
    PBDBENCH_DATASET(R, "run_frame", "", "index of the run's frames at each common time",
                     frames.run),
    PBDBENCH_PAIRS("reference_frame",
                   "indices (lo, hi) of the reference's frames around each common time; lo = hi "
                   "where it has one at that time",
                   frames),
    PBDBENCH_DATASET(R, "reference_frame_weight", "1",
                     "weight of hi: reference = (1 - w) ref[lo] + w ref[hi]; 0 where it has one "
                     "at that time",
                     frames.weight),
    PBDBENCH_DATASET(R, "series_time", "s", "common series times (the run's series times)",
                     rows.time),
    PBDBENCH_DATASET(R, "run_row", "", "index of the run's series rows at each common time",
                     rows.run),
    PBDBENCH_PAIRS("reference_row",
                   "indices (lo, hi) of the reference's series rows around each common time; lo "
                   "= hi where it has one at that time",
                   rows),
    PBDBENCH_DATASET(R, "reference_row_weight", "1",
                     "weight of hi: reference = (1 - w) ref[lo] + w ref[hi]; 0 where it has one "
                     "at that time",
                     rows.weight),
};

#undef PBDBENCH_PAIRS

// /compare/diff/<name>: one per series compared; the doc says which kind of difference.
constexpr std::string_view kDiffDoc1 = "run - reference of the series ";
constexpr std::string_view kDiffDoc3 = "|run - reference| of the 3-vector series ";
constexpr std::string_view kDiffDocEnd = " at each series time";

// /compare/observables
constexpr auto tip = [](const R& r) { return r.tip_displacement.present; };
constexpr auto tip_relative = [](const R& r) {
  return r.tip_displacement.present && !r.tip_displacement.relative_gap.empty();
};
constexpr auto force = [](const R& r) { return r.support_force.present; };
constexpr auto force_relative = [](const R& r) {
  return r.support_force.present && !r.support_force.relative_gap.empty();
};
constexpr auto pendulum = [](const R& r) { return r.pendulum; };

const std::array kObservables = {
    PBDBENCH_DATASET(R, "tip_displacement_run", "m",
                     "tip displacement of the run at each series time", tip_displacement.run, tip),
    PBDBENCH_DATASET(R, "tip_displacement_reference", "m",
                     "tip displacement of the reference at each series time",
                     tip_displacement.reference, tip),
    PBDBENCH_DATASET(R, "tip_displacement_gap", "m", "|run - reference| of the tip displacement",
                     tip_displacement.gap, tip),
    PBDBENCH_DATASET(R, "tip_displacement_relative_gap", "1",
                     "|run - reference| / |reference| of the tip displacement",
                     tip_displacement.relative_gap, tip_relative),
    PBDBENCH_DATASET(R, "support_force_run", "N", "support force of the run at each series time",
                     support_force.run, force),
    PBDBENCH_DATASET(R, "support_force_reference", "N",
                     "support force of the reference at each series time", support_force.reference,
                     force),
    PBDBENCH_DATASET(R, "support_force_gap", "N", "|run - reference| of the support force",
                     support_force.gap, force),
    PBDBENCH_DATASET(R, "support_force_relative_gap", "1",
                     "|run - reference| / |reference| of the support force",
                     support_force.relative_gap, force_relative),
    PBDBENCH_DATASET(R, "pendulum_angle_run", "rad",
                     "pendulum angle of the run at each series time", pendulum_angle_run,
                     pendulum),
    PBDBENCH_DATASET(R, "pendulum_angle_reference", "rad",
                     "pendulum angle of the reference at each series time",
                     pendulum_angle_reference, pendulum),
    PBDBENCH_DATASET(R, "pendulum_period_run", "s",
                     "mean time between upward zero crossings of the run's pendulum angle (NaN "
                     "with less than one full period)",
                     period_run, pendulum),
    PBDBENCH_DATASET(R, "pendulum_period_reference", "s", "the same of the reference",
                     period_reference, pendulum),
    PBDBENCH_DATASET(R, "pendulum_periods_run", "1", "full periods averaged (run)", periods_run,
                     pendulum),
    PBDBENCH_DATASET(R, "pendulum_periods_reference", "1", "full periods averaged (reference)",
                     periods_reference, pendulum),
    PBDBENCH_DATASET(R, "pendulum_period_relative_difference", "1",
                     "(period_run - period_reference) / period_reference",
                     period_relative_difference, pendulum),
};

// The two runs' maps: root attributes run_<key> and reference_<key>.
const std::array<std::pair<const char*, std::map<std::string, std::string> R::*>, 2> kRuns = {{
    {"run_", &R::run},
    {"reference_", &R::reference},
}};

std::string num(double v) { return fmt::format("{:.4g}", v == 0.0 ? 0.0 : v); }  // no "-0"

}  // namespace

std::string match_line(const TimeMatch& m, const char* what) {
  const long interpolated = static_cast<long>(m.time.size()) - m.exact;
  return fmt::format(
      "{} common {}, t = {} to {} s (the run's {}); the reference's: {} at the same times, {} "
      "interpolated between two of its own",
      m.time.size(), what, num(m.time.front()), num(m.time.back()), what, m.exact, interpolated);
}

std::vector<AttributeInfo> compare_root_attributes() {
  std::vector<AttributeInfo> out;
  layout::describe(kHead, out);
  for (const auto& run : kRuns) {
    const std::string prefix = run.first;
    const std::string whose = prefix == "run_" ? "the run's" : "the reference's";
    out.push_back({prefix + "<key>", AttributeType::Text, "",
                   whose + " file, solver, scenario, status, config and git_commit (one attribute per key)",
                   true});
  }
  layout::describe(kRoot, out);
  for (AttributeInfo& a : provenance_attributes()) out.push_back(std::move(a));
  return out;
}

bool is_compare_file(const fs::path& path) { return is_pbdbench_file(path, kContent); }

void write_compare_file(const fs::path& path, const CompareResult& r) {
  layout::write_file(path, "compare", [&](H5::H5File& file) {
    layout::write_attributes(file, kHead, r);
    for (const auto& [prefix, map] : kRuns)
      for (const auto& [key, value] : r.*map) h5::put(file, prefix + key, value);
    layout::write_attributes(file, kRoot, r);
    layout::write_provenance(file);

    H5::Group g = file.createGroup("/compare");
    layout::write_datasets(g, kCompare, r);
    H5::Group d = g.createGroup("diff");
    for (const auto& [name, v] : r.diff) {
      const bool norm = r.diff_width.at(name) == 3;
      h5::write(d, name, v, r.diff_units.at(name),
                std::string(norm ? kDiffDoc3 : kDiffDoc1) + name + std::string(kDiffDocEnd));
    }
    H5::Group o = g.createGroup("observables");
    layout::write_datasets(o, kObservables, r);
  });
}

CompareFile read_compare_file(const fs::path& path) {
  CompareFile out;
  CompareResult& r = out.result;
  layout::read_file(path, "compare", kContent, [&](const H5::H5File& file) {
    h5::read_attributes(file, out.attributes, out.numbers);
    for (const auto& [prefix, map] : kRuns)
      for (const auto& [name, value] : out.attributes)
        if (name.starts_with(prefix)) (r.*map)[name.substr(std::string(prefix).size())] = value;
    layout::read_attributes(file, kHead, r);
    layout::read_attributes(file, kRoot, r);
    out.provenance = layout::read_provenance(file);
    if (!file.nameExists("/compare")) return;
    const H5::Group g = file.openGroup("/compare");
    layout::read_datasets(g, kCompare, r);
    if (g.nameExists("diff")) {
      const H5::Group d = g.openGroup("diff");
      for (hsize_t i = 0; i < d.getNumObjs(); ++i) {
        const std::string name = d.getObjnameByIdx(i);
        const H5::DataSet ds = d.openDataSet(name);
        r.diff[name] = h5::read_doubles(ds);
        r.diff_units[name] = h5::get_string(ds, "units");
        r.diff_width[name] = h5::get_string(ds, "doc").starts_with(kDiffDoc3) ? 3 : 1;
      }
    }
    if (g.nameExists("observables")) {
      const H5::Group o = g.openGroup("observables");
      layout::read_datasets(o, kObservables, r);
      r.tip_displacement.present = o.nameExists("tip_displacement_run");
      r.support_force.present = o.nameExists("support_force_run");
      r.pendulum = o.nameExists("pendulum_angle_run");
    }
  });
  return out;
}

}  // namespace pbdbench
