// Helper of the Python tests (tests/scripts/): writes a small run file with RunFileWriter, from
// the fixture tetrahedron (tests/runfile/fixture_model.hpp) falling under gravity while it
// deforms a little, measured with the real metrics.
//
//   runfile_fixture OUT.h5 [--solver NAME] [--iterations N] [--substeps N] [--rows N]
//                          [--status complete|exploded|failed|incomplete|crashed]
//                          [--no-volume 1]
//   runfile_fixture --list-series    every series of such a file: name, tab, units
//   runfile_fixture --markdown       series_markdown(), for results/README.md
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
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"
#include "tests/runfile/fixture_model.hpp"

namespace pbdbench {
namespace {

int usage(const char* argv0) {
  std::cerr << "usage: " << argv0
            << " OUT.h5 [--solver NAME] [--iterations N] [--substeps N] [--rows N]"
               " [--status complete|exploded|failed|incomplete|crashed] [--no-volume 1]\n"
            << "       " << argv0 << " --list-series | --markdown\n";
  return 2;
}

int run(int argc, char** argv) {
  if (argc < 2) return usage(argv[0]);
  const std::string first = argv[1];
  Model model = test::fixture_model();
  if (first == "--markdown") {
    std::cout << series_markdown();
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
