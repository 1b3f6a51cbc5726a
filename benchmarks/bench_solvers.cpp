// The PBD core's speed: projections per second of pbd and xpbd per scene, order, constraint kind,
// precision and thread count, beside a plain per-constraint Gauss-Seidel loop written here as the
// baseline of how PBD is commonly implemented; and what the harness (metrics, frames, HDF5) adds
// to a run. docs/performance.md reports these; every case is a row of the tables below.
//
//   PBDBENCH_SCENARIOS=scenarios build/benchmarks/bench_solvers --benchmark_repetitions=5
//       --benchmark_enable_random_interleaving=true --benchmark_min_time=0.2
//       --benchmark_out=bench.json --benchmark_out_format=json
//   /usr/bin/python3 scripts/bench_table.py bench.json
//
// Steady state: every scene is first run for kWarmupSteps steps (1 s) with its own solver, so that
// a cloth hangs folded (not flat, where its bending projections are skipped); each measurement
// steps from a copy of that state and the copy is not timed. The rate counted is
//   Mproj/s = (model constraints x iterations x substeps) / (time in the projection sweeps),
// the sweeps' time being StepReport::time_project for the solvers and the loop itself for the
// baseline; `step_ms` is the whole step. Mproj_per_cpu_s (one thread) counts the same projections
// in the thread's CPU time (the solvers: over the whole step), which other processes on a shared
// machine do not inflate. The machine, build and thread count go into the context and the names.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "core/constraint_functions.hpp"
#include "harness/runner.hpp"
#include "metrics/metrics.hpp"
#include "runfile/build_info.hpp"
#include "runfile/frame_compressor.hpp"
#include "solver_api/solver.hpp"

using namespace pbdbench;

namespace {

constexpr int kWarmupSteps = 60;

// ---------------------------------------------------------------------------------------------
// The scenes: a catalog scenario and overrides (the same definitions the tests and studies use).
struct SceneCase {
  const char* id;
  const char* scenario;
  std::vector<config::Override> overrides;
};

const std::vector<SceneCase>& scenes() {
  static const std::vector<SceneCase> all = {
      {"cloth64_distance", "hanging_cloth", {{"scene.bending", "false"}}},
      {"cloth64", "hanging_cloth", {}},
      {"cloth256_distance", "hanging_cloth", {{"scene.resolution", "[256, 256]"}, {"scene.bending", "false"}}},
      {"cloth256", "hanging_cloth", {{"scene.resolution", "[256, 256]"}}},
      {"chain", "hanging_chain", {}},
      {"beam", "cantilever_beam", {}},
      {"fem_beam", "cantilever_fem", {}},
  };
  return all;
}

// A scene in steady state: its model, the state after the warm-up, dt and its solver's settings.
struct Warm {
  config::Config config;
  Scene scene;
  State state;
  double dt = 0.0;
  SolverOptions options;  // the scenario's own (iterations, substeps)
};

const Warm& warm(const std::string& id) {
  static std::map<std::string, std::unique_ptr<Warm>> cache;
  auto it = cache.find(id);
  if (it != cache.end()) return *it->second;
  const SceneCase* sc = nullptr;
  for (const SceneCase& s : scenes())
    if (id == s.id) sc = &s;
  auto w = std::make_unique<Warm>();
  w->config = config::load(sc->scenario, sc->overrides);
  w->scene = config::build_scene(w->config);
  w->dt = config::run_options(w->config).dt;
  w->options = config::solver_options(w->config);
  SolverOptions o = w->options;
  o.order = ProjectionOrder::Colored;  // the fastest way there; the state is what matters
  auto solver = make_solver(o, w->scene.model);
  w->state = w->scene.initial;
  for (int k = 0; k < kWarmupSteps; ++k) solver->step(w->scene.model, w->state, w->dt);
  return *(cache[id] = std::move(w));
}

// The model restricted to the constraints of one kind (the state's positions are the same).
Model only_kind(const Model& model, ConstraintKind kind) {
  Model m = model;
  m.constraints.clear();
  for (const Constraint& c : model.constraints)
    if (c.kind == kind) m.constraints.push_back(c);
  return m;
}

// The CPU time of the calling thread, s.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// The CPU time of the whole process (every thread), s.
double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

long projections_per_step(const Model& model, const SolverOptions& o) {
  return static_cast<long>(model.constraint_count()) * o.iterations * o.substeps;
}

// ---------------------------------------------------------------------------------------------
// pbd and xpbd.
struct SolverCase {
  std::string scene;
  std::string solver;  // pbd, xpbd
  ProjectionOrder order;
  Precision precision;
  int threads;
  int kind = -1;  // a ConstraintKind: only the constraints of that kind; -1: all
};

void BM_Solver(benchmark::State& bench, SolverCase c) {
  const Warm& w = warm(c.scene);
  const Model model = c.kind < 0 ? w.scene.model : only_kind(w.scene.model, static_cast<ConstraintKind>(c.kind));
  SolverOptions o = w.options;
  o.name = c.solver;
  o.order = c.order;
  o.precision = c.precision;
  o.threads = c.threads;
  auto solver = make_solver(o, model);
  State s = w.state;
  s.lambda.assign(model.constraints.size(), 0.0);
  solver->step(model, s, w.dt);  // the first step after setup is not counted
  double project = 0.0, total = 0.0, cpu = 0.0;
  for (auto _ : bench) {
    bench.PauseTiming();
    s = w.state;
    bench.ResumeTiming();
    const double c0 = thread_cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    const StepReport r = solver->step(model, s, w.dt);
    total += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu += thread_cpu_seconds() - c0;
    project += r.time_project;
    benchmark::DoNotOptimize(s.x.data());
  }
  const double n = static_cast<double>(bench.iterations());
  bench.counters["Mproj_per_s"] = projections_per_step(model, o) * n / project * 1e-6;
  // One thread: the rate in the thread's CPU time over the whole step (prediction, velocities
  // included, so a lower bound on the sweeps' rate), which time taken by other processes on a
  // shared machine does not lower as it lowers the wall-clock rate.
  // With several threads the calling thread's CPU time is not the step's: NaN there. Every case
  // sets the counter, since Google Benchmark's CSV reporter aborts when a case lacks a counter an
  // earlier one had (random interleaving put a t2 case after a t1 case).
  bench.counters["Mproj_per_cpu_s"] = c.threads == 1 ? projections_per_step(model, o) * n / cpu * 1e-6
                                                     : std::numeric_limits<double>::quiet_NaN();
  bench.counters["step_ms"] = total / n * 1e3;
  bench.counters["constraints"] = model.constraint_count();
  bench.counters["threads"] = c.threads;
}

// ---------------------------------------------------------------------------------------------
// The baseline: a plain per-constraint Gauss-Seidel loop, as PBD is commonly written (an array
// of constraint records, positions as 3-vectors, the inverse masses looked up per projection,
// the dihedral angle by acos), in the model's order, in double, one thread. It projects the
// predicted positions of the steady state, `iterations` sweeps, the distance and bending
// constraints of the scene (distance: Mueller et al. 2007, sec. 3.3; bending: appendix A;
// xpbd: Macklin et al. 2016, eq. 18).
struct PlainConstraint {
  ConstraintKind kind;
  int p[4];
  double rest, stiffness, compliance;
};

void plain_sweeps(const std::vector<PlainConstraint>& cs, const std::vector<double>& w,
                  std::vector<Vec3>& x, std::vector<double>& lambda, bool xpbd, double h,
                  int iterations) {
  for (int it = 0; it < iterations; ++it) {
    for (size_t j = 0; j < cs.size(); ++j) {
      const PlainConstraint& c = cs[j];
      double C = 0.0;
      Vec3 g[4];
      int count = 2;
      if (c.kind == ConstraintKind::Distance) {
        const Vec3 d = x[static_cast<size_t>(c.p[1])] - x[static_cast<size_t>(c.p[0])];
        const double len = d.norm();
        if (len == 0.0) continue;
        C = len - c.rest;
        g[1] = d / len;
        g[0] = -g[1];
      } else {
        count = 4;
        const Vec3 &x0 = x[static_cast<size_t>(c.p[0])], &x1 = x[static_cast<size_t>(c.p[1])];
        const Vec3 e = x1 - x0, a = x[static_cast<size_t>(c.p[2])] - x0, b = x[static_cast<size_t>(c.p[3])] - x0;
        const Vec3 c1 = e.cross(a), c2 = e.cross(b);
        const double l1 = c1.norm(), l2 = c2.norm();
        if (l1 == 0.0 || l2 == 0.0) continue;
        const Vec3 n1 = c1 / l1, n2 = c2 / l2;
        const double d = std::clamp(n1.dot(n2), -1.0, 1.0);
        const double s2 = 1.0 - d * d;
        if (s2 < 1e-12) continue;
        C = std::acos(d) - c.rest;
        const Vec3 q1 = (n2 - n1 * d) / l1, q2 = (n1 - n2 * d) / l2;
        const double f = -1.0 / std::sqrt(s2);
        g[2] = f * q1.cross(e);
        g[3] = f * q2.cross(e);
        g[1] = f * (a.cross(q1) + b.cross(q2));
        g[0] = -(g[1] + g[2] + g[3]);
      }
      double wsum = 0.0;
      for (int i = 0; i < count; ++i) wsum += w[static_cast<size_t>(c.p[i])] * g[i].squaredNorm();
      double dl;
      if (xpbd) {
        const double at = c.compliance / (h * h);
        if (wsum + at == 0.0) continue;
        dl = (-C - at * lambda[j]) / (wsum + at);
        lambda[j] += dl;
      } else {
        if (wsum == 0.0) continue;
        dl = -c.stiffness * C / wsum;
      }
      for (int i = 0; i < count; ++i) x[static_cast<size_t>(c.p[i])] += (w[static_cast<size_t>(c.p[i])] * dl) * g[i];
    }
  }
}

void BM_Plain(benchmark::State& bench, std::string scene, std::string solver) {
  const Warm& w = warm(scene);
  const Model& m = w.scene.model;
  std::vector<PlainConstraint> cs;
  for (const Constraint& c : m.constraints)
    cs.push_back({c.kind, {c.particles[0], c.particles[1], c.particles[2], c.particles[3]}, c.rest,
                  c.stiffness, c.compliance});
  // The predicted positions of the steady state: x + h v + h^2 g for the dynamic particles.
  const double h = w.dt / w.options.substeps;
  std::vector<Vec3> predicted(static_cast<size_t>(m.particle_count()));
  for (int i = 0; i < m.particle_count(); ++i) {
    predicted[static_cast<size_t>(i)] = w.state.x.row(i).transpose();
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      predicted[static_cast<size_t>(i)] += h * (Vec3(w.state.v.row(i).transpose()) + h * m.gravity);
  }
  std::vector<Vec3> x;
  std::vector<double> lambda;
  double wall = 0.0, cpu = 0.0;
  for (auto _ : bench) {
    bench.PauseTiming();
    x = predicted;
    lambda.assign(cs.size(), 0.0);
    bench.ResumeTiming();
    const double c0 = thread_cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    plain_sweeps(cs, m.inv_mass, x, lambda, solver == "xpbd", h, w.options.iterations);
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu += thread_cpu_seconds() - c0;
    benchmark::DoNotOptimize(x.data());
  }
  const double n = static_cast<double>(bench.iterations());
  const double projections = static_cast<double>(cs.size()) * w.options.iterations * n;
  bench.counters["Mproj_per_s"] = projections / wall * 1e-6;
  bench.counters["Mproj_per_cpu_s"] = projections / cpu * 1e-6;
  bench.counters["constraints"] = m.constraint_count();
  bench.counters["threads"] = 1;
}

// ---------------------------------------------------------------------------------------------
// The harness: a whole run (metrics, frames and HDF5 appends at the default logging) against the
// time inside solver.step(). overhead = (run wall time - solver time) / run wall time. `sets`
// may shorten the run (time.duration); without it the run is the scene's own (hanging_cloth:
// 2 s), over which the per-run costs (the file created with its model, the last publish synced
// to disk) are spread as in a user's run.
void BM_Harness(benchmark::State& bench, std::string scenario, std::vector<config::Override> sets,
                StepLogging logging) {
  const config::Config cfg = config::load(scenario, sets);
  RunControl control;
  control.logging = logging;
  const std::filesystem::path out =
      std::filesystem::temp_directory_path() / ("pbdbench_bench_harness_" + std::to_string(getpid()) + ".h5");
  double wall = 0.0, solver = 0.0, setup = 0.0, cpu = 0.0, process_cpu = 0.0, solver_cpu = 0.0, setup_cpu = 0.0;
  for (auto _ : bench) {
    const double c0 = thread_cpu_seconds(), p0 = process_cpu_seconds();
    const RunOutcome r = run_config(cfg, out, control);
    cpu += thread_cpu_seconds() - c0;
    process_cpu += process_cpu_seconds() - p0;
    wall += r.wall_time;
    solver += r.solver_time;
    setup += r.setup_time;
    solver_cpu += r.solver_cpu_time;
    setup_cpu += r.setup_cpu_time;
    std::filesystem::remove(out);
  }
  // In CPU time, which other processes on a shared machine move much less than wall time: the
  // logging's share of the process's CPU time (the run's thread, the step logger's when it has
  // one, and the frame worker; the xdmf export of the command line is not part of run_config).
  bench.counters["logging_cpu_pct"] = 100.0 * (process_cpu - solver_cpu - setup_cpu) / process_cpu;
  // The same on the run's thread alone (the step logger's thread and the frame worker's
  // deflating left out).
  bench.counters["logging_thread_cpu_pct"] = 100.0 * (cpu - solver_cpu - setup_cpu) / cpu;
  // Everything outside solver.step(), the setup included (the scene built, the solver
  // constructed: its colouring and compiled projections are the solver's cost, not the logging's).
  bench.counters["overhead_pct"] = 100.0 * (wall - solver) / wall;
  // The logging alone, what the 5 % names: metrics, frames and HDF5 (the file created,
  // rows and frames appended, published, finished), over the whole run.
  bench.counters["logging_pct"] = 100.0 * (wall - solver - setup) / wall;
  bench.counters["setup_s"] = setup / static_cast<double>(bench.iterations());
  bench.counters["run_s"] = wall / static_cast<double>(bench.iterations());
  // The run's thread's CPU time over its wall time: below 1 when the thread waited (for the
  // frame worker, for the disk) or other processes took its core.
  bench.counters["cpu_per_wall"] = cpu / wall;
}

// ---------------------------------------------------------------------------------------------
// One sample of the metrics (metrics/metrics.hpp, measure) of a cloth in steady state, what the
// run's logging does after every step: us_per_sample and ns_per_constraint in CPU time.
void BM_Measure(benchmark::State& bench, std::string scene) {
  const Warm& w = warm(scene);
  const MetricsBaseline baseline = measure_baseline(w.scene.model, w.scene.initial);
  double sink = 0.0;
  long samples = 0;
  const double c0 = thread_cpu_seconds();
  for (auto _ : bench) {
    const Sample s = measure(w.scene.model, w.state, baseline);
    sink += s.constraint_error_rms;
    ++samples;
  }
  const double cpu = thread_cpu_seconds() - c0;
  benchmark::DoNotOptimize(sink);
  bench.counters["us_per_sample"] = cpu / static_cast<double>(samples) * 1e6;
  bench.counters["ns_per_constraint"] =
      cpu / static_cast<double>(samples) / static_cast<double>(w.scene.model.constraints.size()) * 1e9;
}

// ---------------------------------------------------------------------------------------------
// A frame's deflating (runfile/frame_compressor.hpp, the frame worker's whole work): the
// positions and velocities of a cloth in steady state, by the writer's libdeflate at level 1
// (`libdeflate`) and by zlib's compress2 at level 1 (`zlib`, the common implementation of the
// same format, for comparison). MB_per_s: input bytes over CPU time; ratio: output over input bytes.
void BM_FrameDeflate(benchmark::State& bench, std::string scene, bool zlib) {
  const Warm& w = warm(scene);
  const size_t bytes = static_cast<size_t>(w.state.x.rows()) * 3 * sizeof(double);
  std::vector<unsigned char> out(compressBound(static_cast<uLong>(bytes)));
  size_t in = 0, written = 0;
  const double c0 = thread_cpu_seconds();
  for (auto _ : bench)
    for (const Points* p : {&w.state.x, &w.state.v}) {
      if (zlib) {
        uLongf n = static_cast<uLongf>(out.size());
        compress2(out.data(), &n, reinterpret_cast<const Bytef*>(p->data()), static_cast<uLong>(bytes), 1);
        written += n;
      } else {
        written += deflate_chunk(p->data(), bytes, 1).bytes.size();
      }
      in += bytes;
    }
  const double cpu = thread_cpu_seconds() - c0;
  bench.counters["MB_per_s"] = static_cast<double>(in) / cpu * 1e-6;
  bench.counters["ratio"] = static_cast<double>(written) / static_cast<double>(in);
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

// Appended part by part: GCC 12's -Wrestrict misfires on a chain of `+` of strings and literals.
std::string name_of(const SolverCase& c) {
  std::string n = "solver/";
  const auto part = [&n](std::string_view s) {
    n += s;
    n += '/';
  };
  part(c.scene);
  if (c.kind >= 0) part(to_string(static_cast<ConstraintKind>(c.kind)));
  part(c.solver);
  part(to_string(c.order));
  part(to_string(c.precision));
  n += 't';
  n += std::to_string(c.threads);
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  // The explicit table of what is measured.
  std::vector<SolverCase> cases;
  const std::vector<ProjectionOrder> orders = {ProjectionOrder::Sequential, ProjectionOrder::Colored,
                                               ProjectionOrder::Jacobi};
  for (const char* scene : {"cloth64_distance", "cloth64", "cloth256_distance", "cloth256"})
    for (const char* solver : {"pbd", "xpbd"})
      for (ProjectionOrder order : orders)
        for (Precision precision : {Precision::Double, Precision::Float})
          for (int threads : {1, 2}) cases.push_back({scene, solver, order, precision, threads});
  // solver.threads = 0, the default: each sweep on the cores or on one, whichever the run's
  // timings favour (solvers/sweep_threads.hpp), beside t1 and t2 on the large cloths.
  for (const char* scene : {"cloth256_distance", "cloth256"})
    for (const char* solver : {"pbd", "xpbd"})
      cases.push_back({scene, solver, ProjectionOrder::Colored, Precision::Double, 0});
  for (const char* scene : {"chain", "beam"})
    for (const char* solver : {"pbd", "xpbd"})
      for (ProjectionOrder order : orders)
        for (Precision precision : {Precision::Double, Precision::Float})
          cases.push_back({scene, solver, order, precision, 1});
  for (ProjectionOrder order : orders)
    for (Precision precision : {Precision::Double, Precision::Float})
      cases.push_back({"fem_beam", "xpbd", order, precision, 1});
  // Per kind: the steady state's positions with only the constraints of one kind.
  const std::vector<std::pair<const char*, ConstraintKind>> kinds = {
      {"cloth64", ConstraintKind::Distance}, {"cloth64", ConstraintKind::Bending},
      {"beam", ConstraintKind::Volume},      {"fem_beam", ConstraintKind::FemDeviatoric},
      {"fem_beam", ConstraintKind::FemHydrostatic}};
  for (const auto& [scene, kind] : kinds)
    for (const char* solver : {"pbd", "xpbd"}) {
      if (std::string(solver) == "pbd" && is_fem_kind(kind)) continue;
      for (ProjectionOrder order : {ProjectionOrder::Sequential, ProjectionOrder::Colored})
        for (Precision precision : {Precision::Double, Precision::Float})
          cases.push_back({scene, solver, order, precision, 1, static_cast<int>(kind)});
    }
  for (const SolverCase& c : cases)
    benchmark::RegisterBenchmark(name_of(c).c_str(), BM_Solver, c)->Unit(benchmark::kMillisecond)->UseRealTime();
  for (const char* scene : {"cloth64_distance", "cloth64", "cloth256_distance", "cloth256", "chain"})
    for (const char* solver : {"pbd", "xpbd"})
      benchmark::RegisterBenchmark(("plain/" + std::string(scene) + "/" + solver).c_str(), BM_Plain,
                                   std::string(scene), std::string(solver))
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  // The scene's own 2 s runs, and 0.5 s runs (quicker, where the setup weighs more).
  const std::vector<std::pair<std::string, std::vector<config::Override>>> runs = {
      {"cloth64", {}},
      {"cloth256", {{"scene.resolution", "[256, 256]"}}},
      {"cloth64_0.5s", {{"time.duration", "0.5"}}},
      {"cloth256_0.5s", {{"scene.resolution", "[256, 256]"}, {"time.duration", "0.5"}}}};
  // Each with the logging as a run has it (harness/step_logger.hpp: on a thread of its own on a
  // machine with a core to spare) and, as /inline, on the run's thread after every step.
  for (const auto& [id, sets] : runs)
    for (const bool inline_logging : {false, true})
      benchmark::RegisterBenchmark(("harness/" + id + (inline_logging ? "/inline" : "")).c_str(), BM_Harness,
                                   std::string("hanging_cloth"), sets,
                                   inline_logging ? StepLogging::Inline : StepLogging::Auto)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->Iterations(1);
  for (const char* scene : {"cloth64", "cloth256"})
    benchmark::RegisterBenchmark(("metrics/measure/" + std::string(scene)).c_str(), BM_Measure, std::string(scene))
        ->Unit(benchmark::kMicrosecond);
  for (const char* scene : {"cloth64", "cloth256"})
    for (const bool zlib : {false, true})
      benchmark::RegisterBenchmark(("frame_deflate/" + std::string(scene) + (zlib ? "/zlib" : "/libdeflate")).c_str(),
                                   BM_FrameDeflate, std::string(scene), zlib)
          ->Unit(benchmark::kMillisecond);
  benchmark::AddCustomContext("pbdbench_version", build_info().version);
  benchmark::AddCustomContext("git_commit", build_info().git_commit);
  benchmark::AddCustomContext("compiler", build_info().compiler);
  benchmark::AddCustomContext("build_type", build_info().build_type);
  benchmark::AddCustomContext("cxx_flags", build_info().cxx_flags);
  benchmark::AddCustomContext("cpu_model", cpu_model());
  benchmark::AddCustomContext("available_cores", std::to_string(available_cores()));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
