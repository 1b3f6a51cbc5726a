// pbdbench compare: the gap between two runs of the same scene over time.
//
//   read_compare_run(path)            a run file, with what compare needs of it
//   compare_runs(run, ref, options)   the gaps at the common times
//   write_compare_file(path, result)  the compare file (runfile/compare_file.hpp)
//   compare_summary(result)           the terminal summary
//
// Common times are the run's own: its frame times for positions, its series times for the
// series, up to the end of the shorter run (and options.until). Where the reference has no
// sample at such a time (it took other steps or kept other frames) it is interpolated linearly in
// time between its two samples around it; which samples were used, and with what weight, is part
// of the result. Positions are compared particle by particle, which is meaningful only for the
// same scene: runs whose particle counts or rest positions differ are refused.
#pragma once

#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/types.hpp"
#include "runfile/compare_file.hpp"

namespace pbdbench {

// Bad input to compare (runs of different scenes, an invalid option, nothing in common): the
// command line exits with 2 on it. Unreadable files are std::runtime_error (exit 1).
class CompareInputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A run file as compare reads it.
struct CompareRun {
  std::filesystem::path path;
  std::map<std::string, std::string> attributes;  // string root attributes: solver, config, ...
  Points rest_positions;                          // (n x 3) m, /model/rest_positions
  std::vector<double> frame_time;                 // (F) s, /frames/time
  std::vector<Points> frames;                     // F frames of (n x 3) m, /frames/positions
  std::map<std::string, std::vector<double>> series;  // width-1 series, (rows) each
  std::map<std::string, Points> series3;              // width-3 series, (rows x 3) each
  std::map<std::string, std::string> units;           // series name -> its `units` attribute
  std::set<std::string> nondeterministic;  // series whose `deterministic` attribute is 0

  std::string attribute(const std::string& name) const;  // "" when absent
};

// Reads a run file (any status: an incomplete or exploded run is compared up to where it ends).
// Throws std::runtime_error naming the path when it cannot be read.
CompareRun read_compare_run(const std::filesystem::path& path);

struct CompareOptions {
  // s, compare only the common times <= until; must be >= 0 (infinity: up to the shorter run's
  // end).
  double until = std::numeric_limits<double>::infinity();
};

// Two samples are at the same time when they differ by at most kTimeTolerance * max(1 s, |t|):
// times are sums of steps, and runs with different steps reach the same time with different
// round-off (1e6 steps of 1e-3 s drift by about 1e-10 s relative), far below this.
inline constexpr double kTimeTolerance = 1e-9;

// Rest positions agree when they differ by at most kRestTolerance * max(1 m, the largest |X|):
// the same scenario builds the same rest positions bit for bit; the tolerance only lets a
// build with a different compiler through.
inline constexpr double kRestTolerance = 1e-9;

// The run's times <= min(run's last, reference's last, until) that the reference's times cover
// (both sorted ascending), each matched as above.
TimeMatch match_times(const std::vector<double>& run_times, const std::vector<double>& ref_times,
                      double until);

// The period of an oscillating angle (s): the mean time between its upward zero crossings
// (angle[k] < 0 <= angle[k+1], located by linear interpolation), over all the full periods
// available; NaN when there are fewer than two crossings (less than one full period). A jump
// across +-pi (the angle wrapping round) is not a crossing. `periods` (optional) receives the
// number of full periods averaged.
double mean_period(const std::vector<double>& time, const std::vector<double>& angle,
                   int* periods = nullptr);

// Series that are not compared: time itself and the step counters (what the solver did, not
// what the state is). The wall-clock timings are left out by their `deterministic` attribute.
const std::set<std::string>& uncompared_series();

// Throws CompareInputError when the runs are not of the same scene (particle counts or rest
// positions differ), options.until is negative or NaN, or they have no common frame.
CompareResult compare_runs(const CompareRun& run, const CompareRun& reference,
                           const CompareOptions& options = {});

// The terminal summary: the two runs, the frames used, the final and largest position error,
// the final gaps of each observable, the periods, and the final differences of the series.
std::string compare_summary(const CompareResult& result);

}  // namespace pbdbench
