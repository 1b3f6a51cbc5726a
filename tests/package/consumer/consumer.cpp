// An outside program on the installed pbdbench: a chain built with the core's generators, stepped
// by the xpbd solver from the catalogue, its frames written to a run file and read back.
// Prints one line and exits 0 when every check holds (tests/package/test_package.sh).
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "catalog/solver_catalog.hpp"
#include "core/generators.hpp"
#include "core/state.hpp"
#include "metrics/metrics.hpp"
#include "runfile/run_file.hpp"
#include "solver_api/solver.hpp"

using namespace pbdbench;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer OUT.h5\n");
    return 2;
  }
  Model model;
  model.name = "consumer_chain";
  ChainSpec chain;
  chain.links = 10;
  chain.direction = Vec3(1.0, 0.0, 0.0);  // horizontal: it swings down
  add_chain(model, chain);
  State state = rest_state(model);
  SolverOptions options;
  options.name = "xpbd";
  auto solver = make_solver(options, model);
  const double dt = 1.0 / 60.0;
  RunHeader header;
  header.scenario = model.name;
  header.solver = solver->name();
  header.dt = dt;
  header.steps_planned = 30;
  const double top = height_min(model, state);
  {
    RunFileWriter writer(argv[1], header, model);
    writer.append_frame(state.time, state.x);
    for (int k = 0; k < 30; ++k) {
      solver->step(model, state, dt);
      writer.append_frame(state.time, state.x);
    }
    writer.finish(RunStatus::Complete, "", 30, 0.0);
  }
  const RunFileData data = read_run_file(argv[1], false);
  const double low = height_min(model, state);
  const bool ok = data.status() == "complete" && std::isfinite(low) && low < top - 0.1;
  std::printf("consumer: %s, %s, lowest particle %.3f m -> %.3f m after 0.5 s: %s\n", solver->name().c_str(),
              data.status().c_str(), top, low, ok ? "ok" : "WRONG");
  return ok ? 0 : 1;
}
