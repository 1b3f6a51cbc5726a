// The broad phase of contact between surfaces (core/surface_contact.hpp): finding the
// vertex-triangle and edge-edge contacts over a sequence of moving positions, with the BVHs
// built anew at every call ("rebuild", as before the cache) and kept and refit
// (SurfaceContactCache: "refit", rebuilt by its area rule). The contacts found are the same
// (tests/core/test_surface_contact.cpp); this measures what the refit saves.
//
//   PBDBENCH_SCENARIOS=scenarios build/benchmarks/bench_surface_contact --benchmark_repetitions=10
//       --benchmark_enable_random_interleaving=true
//
// The sequences: a catalog scene run by xpbd with its substeps as steps (dt / substeps, one
// substep a step, the positions of every substep recorded), from 0.5 s to 0.75 s (120 substeps:
// the cloth falling onto and folding over the pole; draped over the block). One benchmark
// iteration finds the contacts at every position of the sequence in order, at the scene's
// contact margin; the counters say how many trees were built and refit per sequence.
//
// One run (2-core AMD EPYC, Release build; 5 repetitions interleaved, CPU time, median and
// coefficient of variation) with the command above and --benchmark_min_time=0.2: cloth_over_block rebuild 709 ms (2.6 %), refit
// 603 ms (2.1 %), the same 3954 contacts; cloth_on_pole rebuild 369 ms (4.8 %), refit 298 ms
// (4.0 %); 2 trees built and 238 refits a sequence (the area rule never rebuilt).
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "core/contacts.hpp"
#include "core/surface_contact.hpp"
#include "solver_api/solver.hpp"

using namespace pbdbench;

namespace {

struct Sequence {
  Scene scene;
  double margin = 0.0;
  std::vector<Points> x;
};

const Sequence& sequence(const std::string& scenario) {
  static std::vector<std::pair<std::string, Sequence>> cache;
  for (const auto& [name, s] : cache)
    if (name == scenario) return s;
  const config::Config cfg = config::load(scenario, {{"solver.name", "xpbd"}});
  Sequence seq{config::build_scene(cfg), 0.0, {}};
  SolverOptions o = config::solver_options(cfg);
  const double h = config::run_options(cfg).dt / o.substeps;
  o.substeps = 1;
  seq.margin = o.contact_margin;
  auto solver = make_solver(o, seq.scene.model);
  State s = seq.scene.initial;
  const int start = static_cast<int>(0.5 / h + 0.5), count = 120;
  for (int k = 0; k < start + count; ++k) {
    solver->step(seq.scene.model, s, h);
    if (k >= start) seq.x.push_back(s.x);
  }
  cache.emplace_back(scenario, std::move(seq));
  return cache.back().second;
}

void run(benchmark::State& state, const std::string& scenario, bool refit) {
  const Sequence& seq = sequence(scenario);
  const Model& m = seq.scene.model;
  long contacts = 0, builds = 0, refits = 0;
  for (auto _ : state) {
    SurfaceContactCache cache;
    for (const Points& x : seq.x) {
      const auto vt = find_surface_contacts(m, x, seq.margin, refit ? &cache : nullptr);
      const auto ee = find_edge_contacts(m, x, seq.margin, refit ? &cache : nullptr);
      contacts += static_cast<long>(vt.size() + ee.size());
      benchmark::DoNotOptimize(vt.data());
      benchmark::DoNotOptimize(ee.data());
    }
    builds += cache.builds();
    refits += cache.refits();
  }
  const double it = static_cast<double>(state.iterations());
  state.counters["contacts_per_seq"] = static_cast<double>(contacts) / it;
  state.counters["trees_built_per_seq"] = static_cast<double>(builds) / it;
  state.counters["trees_refit_per_seq"] = static_cast<double>(refits) / it;
  state.counters["positions_per_seq"] = static_cast<double>(seq.x.size());
}

const int registered = [] {
  for (const char* scenario : {"cloth_on_pole", "cloth_over_block"})
    for (bool refit : {false, true})
      benchmark::RegisterBenchmark(
          (std::string("surface_contact/") + scenario + (refit ? "/refit" : "/rebuild")).c_str(),
          [scenario, refit](benchmark::State& st) { run(st, scenario, refit); })
          ->Unit(benchmark::kMillisecond);
  return 0;
}();

}  // namespace

BENCHMARK_MAIN();
