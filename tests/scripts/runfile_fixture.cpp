// Helper of the Python tests (tests/scripts/): writes a small run file with RunFileWriter, from
// the fixture tetrahedron (tests/runfile/fixture_model.hpp) falling under gravity while it
// deforms a little, measured with the real metrics.
//
//   runfile_fixture OUT.h5 [--solver NAME] [--iterations N] [--substeps N] [--rows N]
//                          [--status complete|exploded|failed|incomplete|crashed]
//                          [--no-volume 1]
//   runfile_fixture --list-series    every series of such a file: name, tab, units
//   runfile_fixture --markdown       series_markdown(), for results/README.md
//   runfile_fixture --compare OUT.h5 | --converge OUT.h5 | --regress OUT.h5
//                                    a small file of that kind, by runfile/'s writer, with the
//                                    values that tests/scripts/test_scripts.py expects
//
// --status exploded: the positions become NaN at 3/4 of the rows and the run stops there.
// --status incomplete: the writer is destroyed without finish(). --status crashed: the process
// ends with _Exit after a flush, as a killed run would (no destructor runs). --no-volume 1: the
// model has no tets and no closed surface (both volume series are NaN throughout).
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <string>

#include "core/state.hpp"
#include "metrics/metrics.hpp"
#include "runfile/compare_file.hpp"
#include "runfile/converge_file.hpp"
#include "runfile/regress_file.hpp"
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"
#include "tests/runfile/fixture_model.hpp"

namespace pbdbench {
namespace {

int usage(const char* argv0) {
  std::cerr << "usage: " << argv0
            << " OUT.h5 [--solver NAME] [--iterations N] [--substeps N] [--rows N]"
               " [--status complete|exploded|failed|incomplete|crashed] [--no-volume 1]\n"
            << "       " << argv0 << " --list-series | --markdown\n"
            << "       " << argv0 << " --compare OUT.h5 | --converge OUT.h5 | --regress OUT.h5\n";
  return 2;
}

// Two frames (the second interpolated), three series rows, one diff of each width, a tip
// displacement and a pendulum.
void write_compare(const std::string& path) {
  CompareResult r;
  r.run = {{"file", "run.h5"}, {"solver", "xpbd"}, {"scenario", "fixture"}, {"status", "complete"}};
  r.reference = {{"file", "ref.h5"}, {"solver", "ref-bdf"}, {"scenario", "fixture"}, {"status", "complete"}};
  r.until = 1.0;
  r.frames = {{0.0, 0.5}, {0, 1}, {0, 0}, {0, 1}, {0.0, 0.5}, 1};
  r.position_error_rms = {0.0, 1e-3};
  r.position_error_max = {0.0, 2e-3};
  r.rows = {{0.0, 0.25, 0.5}, {0, 1, 2}, {0, 1, 2}, {0, 1, 2}, {0.0, 0.0, 0.0}, 3};
  r.diff = {{"total_energy", {0.0, 0.1, 0.2}}, {"linear_momentum", {0.0, 1.0, 2.0}}};
  r.diff_width = {{"total_energy", 1}, {"linear_momentum", 3}};
  r.diff_units = {{"total_energy", "J"}, {"linear_momentum", "kg m/s"}};
  Points tip(3, 3);
  tip << 0, 0, 0, 0, -0.1, 0, 0, -0.2, 0;
  r.tip_displacement = {true, tip, tip, {0.0, 0.0, 0.0}, {}};
  r.pendulum = true;
  r.pendulum_angle_run = {0.1, 0.2, 0.3};
  r.pendulum_angle_reference = {0.1, 0.2, 0.3};
  r.period_run = 1.5;
  r.period_reference = 1.6;
  r.periods_run = 2;
  r.periods_reference = 2;
  r.period_relative_difference = -0.1 / 1.6;
  r.warnings = {"first warning", "second warning"};
  write_compare_file(path, r);
}

// An xpbd order and a global solver.
void write_converge(const std::string& path) {
  ConvergeResult r;
  r.scene = "fixture";
  r.dt = 0.01;
  r.tolerance = 1e-10;
  r.start_residual = 0.5;
  r.machine = "fixture CPU";
  ConvergeMethod x;
  x.key = "xpbd-sequential";
  x.iteration_kind = "sweeps";
  x.xpbd = true;
  x.iteration = {1, 2, 3};
  x.residual = {1e-1, 1e-2, 1e-3};
  x.time = {1e-4, 2e-4, 3e-4};
  x.error = {0.4, 0.2, 0.1};
  ConvergeMethod g;
  g.key = "global-cholmod";
  g.iteration_kind = "Newton iterations";
  g.iteration = {0, 1};
  g.residual = {0.5, 1e-12};
  g.time = {0.0, 1e-3};
  g.inner_iterations = {0, 0};
  g.converged = true;
  r.methods = {x, g};
  write_converge_file(path, r);
}

void write_regress(const std::string& path) {
  write_regress_file(path, {{"chain", "energy_drift", "J", "same", 1.5, 1.5, 0.0, 1e-9},
                            {"cloth", "wall_time", "s", "ratio", 2.0, 3.0, 1.5, 0.0}});
}

int run(int argc, char** argv) {
  if (argc < 2) return usage(argv[0]);
  const std::string first = argv[1];
  Model model = test::fixture_model();
  if (first == "--markdown") {
    std::cout << series_markdown();
    return 0;
  }
  if (argc == 3 && (first == "--compare" || first == "--converge" || first == "--regress")) {
    if (first == "--compare") write_compare(argv[2]);
    if (first == "--converge") write_converge(argv[2]);
    if (first == "--regress") write_regress(argv[2]);
    return 0;
  }
  if (first == "--list-series") {
    for (const SeriesSpec& s : series_table()) std::cout << s.name << "\t" << s.units << "\n";
    for (const GroupSeriesSpec& g : group_series_table())
      for (const std::string& group : model.group_names)
        std::cout << g.prefix << group << "\t" << g.units << "\n";
    return 0;
  }
  std::string solver = "xpbd", status = "complete";
  int iterations = 10, substeps = 1;
  long rows = 50;
  bool no_volume = false;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage(argv[0]);
    const std::string v = argv[++i];
    if (a == "--solver") solver = v;
    else if (a == "--iterations") iterations = std::atoi(v.c_str());
    else if (a == "--substeps") substeps = std::atoi(v.c_str());
    else if (a == "--rows") rows = std::atol(v.c_str());
    else if (a == "--status") status = v;
    else if (a == "--no-volume") no_volume = v == "1";
    else return usage(argv[0]);
  }
  if (iterations < 1 || substeps < 1 || rows < 2) return usage(argv[0]);
  if (no_volume) {
    model.tets.clear();
    model.surface_closed = false;
  }

  RunHeader h;
  h.scenario = "fixture";
  h.scenario_file = "scenarios/fixture.toml";
  h.solver = solver;
  h.config = test::fixture_config(solver, iterations, substeps);
  h.dt = 0.01;
  h.steps_planned = rows - 1;
  RunFileWriter w(first, h, model, 0.0);

  State state = rest_state(model);
  const MetricsBaseline base = measure_baseline(model, state);
  const ExplosionLimits limits;
  const long explode_at = status == "exploded" ? 3 * rows / 4 : -1;
  // The error shrinks with the iteration count, as a solver's would; "pbd" wobbles more, so
  // that plots of two solvers show two lines.
  const double wobble = (solver == "pbd" ? 0.03 : 0.02) / (iterations * substeps);
  long step = 0;
  for (; step < rows; ++step) {
    const double t = h.dt * static_cast<double>(step);
    state.time = t;
    state.step = step;
    for (int p = 0; p < 3; ++p) {  // particle 3 is pinned
      const double s = wobble * std::sin(7.0 * t + p);
      state.x.row(p) = model.rest_positions.row(p) +
                       Eigen::RowVector3d(s, -0.5 * 9.81 * t * t + s, 0.5 * s);
      state.v.row(p) = Eigen::RowVector3d(7.0 * wobble * std::cos(7.0 * t + p),
                                          -9.81 * t + 7.0 * wobble * std::cos(7.0 * t + p),
                                          3.5 * wobble * std::cos(7.0 * t + p));
    }
    if (step == explode_at) state.x(1, 0) = std::numeric_limits<double>::quiet_NaN();
    const Sample sample = measure(model, state, base);
    StepReport report = test::fixture_report(step);
    report.iterations = step == 0 ? 0 : iterations * substeps;
    report.substeps = step == 0 ? 0 : substeps;
    w.append(SeriesRow{t, step, step == 0 ? 0.0 : 1e-4, &sample, &report});
    if (step % 10 == 0) w.append_frame(t, state.x);
    const std::string why = explosion_reason(model, state, sample, limits, base);
    if (!why.empty()) {
      w.finish(RunStatus::Exploded, why, step, 0.01 * static_cast<double>(step), step, t);
      return 0;
    }
  }
  if (status == "complete") {
    w.finish(RunStatus::Complete, "reached steps_planned", rows - 1, 0.01 * rows);
  } else if (status == "failed") {
    w.finish(RunStatus::Failed, "the fixture was asked to fail", rows - 1, 0.01 * rows);
  } else if (status == "crashed") {
    w.flush();
    std::_Exit(0);
  } else if (status != "incomplete") {
    return usage(argv[0]);
  }
  return 0;
}

}  // namespace
}  // namespace pbdbench

int main(int argc, char** argv) {
  try {
    return pbdbench::run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "runfile_fixture: " << e.what() << "\n";
    return 1;
  }
}
