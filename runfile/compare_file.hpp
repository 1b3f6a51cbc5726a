// The compare file of `pbdbench compare`: its content (CompareResult, computed by
// harness/compare.hpp), its layout declared once as tables (compare_file.cpp), the writer and the
// reader. The layout (results/README.md, "Compare files"):
//
//   /                     attributes: content ("pbdbench compare"), compare_format_version,
//                         run_<key> and reference_<key> (file, solver, scenario, status, config,
//                         git_commit), until, end_time, frames_used, rows_used,
//                         frame_spacing_run, frame_spacing_reference, warnings (one per line),
//                         created and the build's provenance
//   /compare/...          time, position_error_rms, position_error_max, run_frame,
//                         reference_frame, reference_frame_weight, series_time, run_row,
//                         reference_row, reference_row_weight
//   /compare/diff/<name>  one dataset per series compared
//   /compare/observables  tip_displacement_*, support_force_*, pendulum_* (when present)
#pragma once

#include <filesystem>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/types.hpp"
#include "runfile/file_read.hpp"

namespace pbdbench {

// The common times of a run and a reference, and where the reference was sampled at each:
// ref(t) = (1 - weight) ref[lo] + weight ref[hi], with lo == hi and weight 0 when the reference
// has a sample at t itself.
struct TimeMatch {
  std::vector<double> time;   // (K) s, the common times (the run's sample times)
  std::vector<long> run;      // (K) index of the run's sample at each time
  std::vector<long> lo, hi;   // (K) indices of the reference's samples around each time
  std::vector<double> weight; // (K) weight of hi, in [0, 1)
  long exact = 0;             // times at which the reference has a sample of its own
};

// A width-3 observable of both runs at the common series times, and their gap.
struct VectorObservable {
  bool present = false;  // in both files, and not NaN throughout in both
  Points run;            // (R x 3)
  Points reference;      // (R x 3), interpolated at the run's times
  std::vector<double> gap;           // (R) |run - reference|
  std::vector<double> relative_gap;  // (R) gap / |reference| (support force only)
};

struct CompareResult {
  // The two files: path, solver, scenario, status, config, git_commit (root attributes).
  std::map<std::string, std::string> run, reference;
  double until = std::numeric_limits<double>::infinity();

  // Positions, at the run's frame times.
  TimeMatch frames;
  std::vector<double> position_error_rms;  // (F) m, RMS over particles of |x_run - x_ref|
  std::vector<double> position_error_max;  // (F) m, max over particles of the same
  double frame_spacing_run = 0.0;          // s, median spacing of the run's frames compared
  double frame_spacing_reference = 0.0;    // s, the same of the reference's frames in the window

  // Series, at the run's series times.
  TimeMatch rows;
  // name -> (R): run - reference for width-1 series, |run - reference| for width-3 series; every
  // series both files have but time, the step counters and the wall-clock timings.
  std::map<std::string, std::vector<double>> diff;
  std::map<std::string, int> diff_width;         // name -> 1 or 3
  std::map<std::string, std::string> diff_units;  // name -> units

  // Observables of the scene.
  VectorObservable tip_displacement;  // m
  VectorObservable support_force;     // N
  bool pendulum = false;              // both have pendulum_angle, not NaN throughout in both
  std::vector<double> pendulum_angle_run, pendulum_angle_reference;  // (R) rad
  double period_run = std::numeric_limits<double>::quiet_NaN();        // s
  double period_reference = std::numeric_limits<double>::quiet_NaN();  // s
  int periods_run = 0, periods_reference = 0;  // full periods averaged
  double period_relative_difference = std::numeric_limits<double>::quiet_NaN();  // (run-ref)/ref

  std::vector<std::string> warnings;  // sparse reference frames, different scenario names, ...
};

// "21 common frames, t = 0 to 1 s (the run's frames); the reference's: 11 at the same times,
// 10 interpolated between two of its own": the frames_used and rows_used attributes.
std::string match_line(const TimeMatch& m, const char* what);

// True when `path` is a regular file holding a compare file (what `compare --out` may replace).
bool is_compare_file(const std::filesystem::path& path);

// Writes the compare file. Throws std::runtime_error naming the path on failure.
void write_compare_file(const std::filesystem::path& path, const CompareResult& result);

// A compare file read back: the result as written, and every scalar root attribute (the
// provenance, created, frames_used, ...).
using CompareFile = FileRead<CompareResult>;

// Throws std::runtime_error naming the path when the file cannot be read or is not a compare file.
CompareFile read_compare_file(const std::filesystem::path& path);

// The root attributes of a compare file, as compare_file.cpp's tables declare them, in the order
// they are written: content, compare_format_version, run_<key> and reference_<key> (one row
// each, for every key of CompareResult::run), until ... warnings, then provenance_attributes().
std::vector<AttributeInfo> compare_root_attributes();

}  // namespace pbdbench
