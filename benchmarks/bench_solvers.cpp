// Time per step of each PBD-family solver on the catalog scenes (the same scenario files the
// tests and studies use). Each measurement steps from the same state, 10 steps into the run,
// so that the warm-up is not counted; the build and machine go into the benchmark's context.
//
//   build/benchmarks/bench_solvers --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <fstream>
#include <string>

#include "config/config.hpp"
#include "runfile/build_info.hpp"
#include "solvers/solver.hpp"

using namespace pbdbench;

namespace {

struct Case {
  const char* scenario;
  const char* solver;
};

// The explicit table of what is measured.
constexpr Case kCases[] = {
    {"hanging_chain", "pbd-seed"},   {"hanging_chain", "pbd"},   {"hanging_chain", "xpbd"},
    {"hanging_cloth", "pbd-seed"},   {"hanging_cloth", "pbd"},   {"hanging_cloth", "xpbd"},
    {"cantilever_beam", "pbd-seed"}, {"cantilever_beam", "pbd"}, {"cantilever_beam", "xpbd"},
    {"balls_in_bowl", "pbd-seed"},   {"balls_in_bowl", "pbd"},   {"balls_in_bowl", "xpbd"},
};

void BM_Step(benchmark::State& bench, Case c) {
  const config::Config cfg = config::load(c.scenario, {{"solver.name", c.solver}});
  const Scene scene = config::build_scene(cfg);
  const double dt = config::run_options(cfg).dt;
  auto solver = make_solver(config::solver_options(cfg), scene.model);
  State warm = scene.initial;
  for (int k = 0; k < 10; ++k) solver->step(scene.model, warm, dt);
  for (auto _ : bench) {
    bench.PauseTiming();
    State s = warm;
    bench.ResumeTiming();
    solver->step(scene.model, s, dt);
    benchmark::DoNotOptimize(s.x.data());
  }
  bench.counters["particles"] = scene.model.particle_count();
  bench.counters["constraints"] = scene.model.constraint_count();
  bench.counters["iterations"] = config::solver_options(cfg).iterations;
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

}  // namespace

int main(int argc, char** argv) {
  for (const Case& c : kCases)
    benchmark::RegisterBenchmark((std::string("step/") + c.scenario + "/" + c.solver).c_str(), BM_Step, c)
        ->Unit(benchmark::kMicrosecond);
  benchmark::AddCustomContext("pbdbench_version", build_info().version);
  benchmark::AddCustomContext("git_commit", build_info().git_commit);
  benchmark::AddCustomContext("compiler", build_info().compiler);
  benchmark::AddCustomContext("build_type", build_info().build_type);
  benchmark::AddCustomContext("cxx_flags", build_info().cxx_flags);
  benchmark::AddCustomContext("cpu_model", cpu_model());
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
