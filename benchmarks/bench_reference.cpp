// Cost of the reference integrators against mesh size: one backward-Euler step (ref-be) of a
// stable neo-Hookean beam clamped at one end, from about 1k to about 100k tetrahedra. Reported per
// size: time per step, Newton iterations, linear setups and solves, and the time spent in the
// Jacobian and the sparse direct solver (counters). scripts/fit_growth.py fits the growth exponent
// of each against the number of tetrahedra from this program's JSON output:
//
//   build/benchmarks/bench_reference --benchmark_out=cost.json --benchmark_out_format=json
//   /usr/bin/python3 scripts/fit_growth.py cost.json
//
// Also global-cholmod: one step of cantilever_beam and hanging_cloth (setup not timed), and the
// projection of its Hessian blocks onto the positive semi-definite cone (reference/
// global_newton.cpp) in the fixed-size eigen-solve it uses against a heap-allocating dynamic one
// (written here as the baseline), on the same random blocks, side by side;
// global-cholmod's steady state (a step after a warm-up run), and the fast projections of
// core/psd_projection.hpp beside the general 12 x 12 eigen-solve on the same blocks (and the
// bending hinges' 8 x 8 path beside the 9 x 9 one):
//
//   build/benchmarks/bench_reference --benchmark_filter='global|psd' --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <utility>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "core/constraint_functions.hpp"
#include "core/psd_projection.hpp"
#include "reference/energy.hpp"
#include "runfile/build_info.hpp"
#include "solver_api/solver.hpp"

using namespace pbdbench;

namespace {

// A beam of n x m x m cells (6 tets a cell), 10 m : 1 m : 1 m, E = 1e7 Pa, nu = 0.3, clamped at
// x_min, under gravity.
config::Config beam(int n, int m, const char* solver) {
  const std::string text = fmt::format(R"(
[time]
dt = 0.016666666666666666
duration = 0.016666666666666666
[solver]
name = "{}"
[scene]
kind = "tet_block"
cells = [{}, {}, {}]
size = [10.0, 1.0, 1.0]
fixed = "x_min"
edges = false
volumes = false
material = "stable_neo_hookean"
youngs_modulus = 1e7
poisson_ratio = 0.3
)",
                                       solver, n, m, m);
  return config::load_text(text, "bench_reference.toml");
}

void BM_ReferenceStep(benchmark::State& bench, int n, int m, const char* solver) {
  const config::Config cfg = beam(n, m, solver);
  const Scene scene = config::build_scene(cfg);
  const double dt = config::run_options(cfg).dt;
  StepReport last;
  double newton = 0, setups = 0, solves = 0, linear = 0;
  long steps = 0;
  for (auto _ : bench) {
    bench.PauseTiming();
    auto s = make_solver(config::solver_options(cfg), scene.model);  // setup is not timed
    State state = scene.initial;
    bench.ResumeTiming();
    last = s->step(scene.model, state, dt);
    benchmark::DoNotOptimize(state.x.data());
    newton += static_cast<double>(last.newton_iterations);
    setups += static_cast<double>(last.linear_setups);
    solves += static_cast<double>(last.linear_solves);
    linear += last.time_linear;
    ++steps;
  }
  const double k = steps > 0 ? 1.0 / static_cast<double>(steps) : 0.0;
  bench.counters["tets"] = 6.0 * n * m * m;
  bench.counters["dofs"] = 3.0 * ((n + 1) * (m + 1) * (m + 1) - (m + 1) * (m + 1));
  bench.counters["newton_iterations"] = newton * k;
  bench.counters["linear_setups"] = setups * k;
  bench.counters["linear_solves"] = solves * k;
  bench.counters["linear_seconds"] = linear * k;
}

// Newton iterations and linear-solve seconds per timed step, as benchmark counters.
struct NewtonCounters {
  double linear = 0.0, newton = 0.0;
  long steps = 0;
  void add(const StepReport& r) {
    linear += r.time_linear;
    newton += static_cast<double>(r.newton_iterations);
    ++steps;
  }
  void write(benchmark::State& bench) const {
    const double k = steps > 0 ? 1.0 / static_cast<double>(steps) : 0.0;
    bench.counters["newton_iterations"] = newton * k;
    bench.counters["linear_seconds"] = linear * k;
  }
};

// global-cholmod: one step of a catalog scenario from its initial state.
void BM_GlobalStep(benchmark::State& bench, const char* scenario) {
  config::Config cfg = config::load(scenario, {{"solver.name", "\"global-cholmod\""}});
  const Scene scene = config::build_scene(cfg);
  const double dt = config::run_options(cfg).dt;
  NewtonCounters counters;
  for (auto _ : bench) {
    bench.PauseTiming();
    auto s = make_solver(config::solver_options(cfg), scene.model);
    State state = scene.initial;
    bench.ResumeTiming();
    const StepReport r = s->step(scene.model, state, dt);
    benchmark::DoNotOptimize(state.x.data());
    counters.add(r);
  }
  counters.write(bench);
}

// global-cholmod in the steady state: the solver built once and the scene run for `warmup`
// steps (not timed; the cloth has left flat by then, so its bending blocks are not the flat ones),
// then each timed iteration is the next step of that run.
void BM_GlobalSteadyStep(benchmark::State& bench, const char* scenario, int warmup) {
  config::Config cfg = config::load(scenario, {{"solver.name", "\"global-cholmod\""}});
  const Scene scene = config::build_scene(cfg);
  const double dt = config::run_options(cfg).dt;
  auto s = make_solver(config::solver_options(cfg), scene.model);
  State state = scene.initial;
  for (int k = 0; k < warmup; ++k) s->step(scene.model, state, dt);
  NewtonCounters counters;
  for (auto _ : bench) {
    const StepReport r = s->step(scene.model, state, dt);
    benchmark::DoNotOptimize(state.x.data());
    counters.add(r);
  }
  counters.write(bench);
}

// Random symmetric K x K blocks shaped as global-cholmod's: g g^T / eps - l H, H symmetric.
template <int K>
std::vector<Eigen::Matrix<double, K, K>> psd_blocks() {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Eigen::Matrix<double, K, K>> out(512);
  for (auto& H : out) {
    Eigen::Matrix<double, K, 1> g;
    Eigen::Matrix<double, K, K> A;
    for (int i = 0; i < K; ++i) g(i) = n(rng);
    for (int i = 0; i < K; ++i)
      for (int j = 0; j < K; ++j) A(i, j) = n(rng);
    H = g * g.transpose() * 1e3 - 0.5 * (A + A.transpose());
  }
  return out;
}

// Fixed: Eigen::SelfAdjointEigenSolver<Matrix<double, K, K>> (global_newton.cpp now). Dynamic:
// the K x K corner copied to a MatrixXd and solved there (global_newton.cpp before, for K < 12).
template <int K, bool Dynamic>
void BM_Psd(benchmark::State& bench) {
  const auto blocks = psd_blocks<K>();
  double sink = 0.0;
  for (auto _ : bench) {
    for (const auto& B : blocks) {
      if constexpr (Dynamic) {
        const Eigen::MatrixXd sub = B;
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(sub);
        const Eigen::MatrixXd P =
            eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
        sink += P(0, 0);
      } else {
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, K, K>> eig(B);
        const Eigen::Matrix<double, K, K> P =
            eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
        sink += P(0, 0);
      }
    }
  }
  benchmark::DoNotOptimize(sink);
  bench.counters["blocks_per_s"] = benchmark::Counter(static_cast<double>(blocks.size()) * bench.iterations(),
                                                      benchmark::Counter::kIsRate);
}

// The projection of core/psd_projection: Eigen's solver (project_psd) against the fixed-size
// tridiagonal QL (project_psd_tridiagonal_ql), on the same indefinite blocks.
template <int K, bool Ql>
void BM_PsdProject(benchmark::State& bench) {
  const auto blocks = psd_blocks<K>();
  double sink = 0.0;
  for (auto _ : bench)
    for (auto H : blocks) {
      if constexpr (Ql) psd::project_psd_tridiagonal_ql<K>(H);
      else psd::project_psd<K>(H);
      sink += H(0, 0);
    }
  benchmark::DoNotOptimize(sink);
  bench.counters["blocks_per_s"] = benchmark::Counter(static_cast<double>(blocks.size()) * bench.iterations(),
                                                      benchmark::Counter::kIsRate);
}

// Translation-free 12 x 12 blocks (bending, FEM elements: zero on the translations), indefinite:
// the general 12 x 12 eigen-solve against the 9 x 9 restriction (core/psd_projection.hpp).
std::vector<Eigen::Matrix<double, 12, 12>> translation_free_blocks() {
  std::vector<Eigen::Matrix<double, 12, 12>> out = psd_blocks<12>();
  Eigen::Matrix<double, 12, 12> P = Eigen::Matrix<double, 12, 12>::Identity();
  for (int v = 0; v < 4; ++v)
    for (int w = 0; w < 4; ++w) P.block<3, 3>(3 * v, 3 * w) -= Eigen::Matrix3d::Identity() / 4.0;
  for (auto& H : out) H = P * H * P;
  return out;
}

template <bool Fast>
void BM_PsdTranslationFree(benchmark::State& bench) {
  const auto blocks = translation_free_blocks();
  double sink = 0.0;
  for (auto _ : bench)
    for (auto H : blocks) {
      if constexpr (Fast) psd::project_psd_translation_free(H);
      else psd::project_psd<12>(H);
      sink += H(0, 0);
    }
  benchmark::DoNotOptimize(sink);
  bench.counters["blocks_per_s"] = benchmark::Counter(static_cast<double>(blocks.size()) * bench.iterations(),
                                                      benchmark::Counter::kIsRate);
}

// The volume term of cantilever_beam's tets, stretched and compressed: its 12 x 12 Hessian
// built and projected by the general eigen-solve, against the analytic eigensystem.
template <bool Fast>
void BM_PsdVolume(benchmark::State& bench) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  std::vector<std::array<Vec3, 4>> tets(512);
  std::vector<double> rest(tets.size());
  for (size_t t = 0; t < tets.size(); ++t) {
    tets[t] = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0, 0.1, 0), Vec3(0, 0, 0.1)};
    for (Vec3& p : tets[t]) p += Vec3(u(rng), u(rng), u(rng));
    rest[t] = 0.1 * 0.1 * 0.1 / 6.0;
  }
  const double alpha = 4e-11;
  double sink = 0.0;
  for (auto _ : bench)
    for (size_t t = 0; t < tets.size(); ++t) {
      const auto& x = tets[t];
      Eigen::Matrix<double, 12, 12> H;
      if constexpr (Fast) {
        H = psd::volume_term_hessian_psd(x[0], x[1], x[2], x[3], rest[t], alpha);
      } else {
        const ConstraintEval e = eval_volume(x[0], x[1], x[2], x[3], rest[t]);
        Eigen::Matrix<double, 12, 1> g;
        for (int i = 0; i < 4; ++i) g.segment<3>(3 * i) = e.grad[static_cast<size_t>(i)];
        H = (g * g.transpose() + e.C * volume_constraint_hessian(x[0], x[1], x[2], x[3])) / alpha;
        psd::project_psd<12>(H);
      }
      sink += H(0, 0);
    }
  benchmark::DoNotOptimize(sink);
  bench.counters["blocks_per_s"] = benchmark::Counter(static_cast<double>(tets.size()) * bench.iterations(),
                                                      benchmark::Counter::kIsRate);
}

// Bending hinges shaped as the 64 x 64 cloth's while it hangs (wings 1/63 m, within 0.3 rad of
// flat, the tips jittered), their exact blocks (grad phi grad phi^T - C s hess phi) / alpha from
// reference/energy.cpp (rest pi, alpha = 100): the 9 x 9 translation-free path (before) against
// the hinge's 8 x 8 one (core/psd_projection.hpp, project_psd_hinge).
struct HingeBlocks {
  std::vector<Eigen::Matrix<double, 12, 12>> H;
  std::vector<std::array<Vec3, 4>> x;
};

HingeBlocks hinge_blocks() {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 1.0 / 63.0;
  HingeBlocks out;
  for (int k = 0; k < 512; ++k) {
    const double fold = 0.3 * u(rng);
    std::array<Vec3, 4> x = {Vec3(0, 0, 0), Vec3(h, 0, 0), Vec3(0.5 * h, h, 0),
                             Vec3(0.5 * h, -h * std::cos(fold), h * std::sin(fold))};
    for (Vec3& p : x) p += 0.1 * h * Vec3(u(rng), u(rng), u(rng));
    Model m;
    m.gravity = Vec3::Zero();
    m.rest_positions.resize(4, 3);
    for (int i = 0; i < 4; ++i) m.rest_positions.row(i) = x[static_cast<size_t>(i)].transpose();
    m.inv_mass.assign(4, 1.0);
    m.radius.assign(4, 0.01);
    Constraint c;
    c.kind = ConstraintKind::Bending;
    c.particles = {0, 1, 2, 3};
    c.rest = 3.141592653589793;
    c.compliance = 100.0;
    m.constraints.push_back(c);
    const EnergyModel E(m);
    std::vector<double> values;
    E.hessian(m.rest_positions, values);
    const SparsityPattern& p = E.hessian_pattern();
    Eigen::Matrix<double, 12, 12> H = Eigen::Matrix<double, 12, 12>::Zero();
    for (int col = 0; col < p.n; ++col)
      for (std::int64_t e = p.column_start[static_cast<size_t>(col)]; e < p.column_start[static_cast<size_t>(col) + 1]; ++e)
        H(static_cast<int>(p.row[static_cast<size_t>(e)]), col) = values[static_cast<size_t>(e)];
    out.H.push_back(H);
    out.x.push_back(x);
  }
  return out;
}

template <bool Hinge>
void BM_PsdHinge(benchmark::State& bench) {
  const HingeBlocks blocks = hinge_blocks();
  double sink = 0.0;
  for (auto _ : bench)
    for (size_t k = 0; k < blocks.H.size(); ++k) {
      Eigen::Matrix<double, 12, 12> H = blocks.H[k];
      const auto& x = blocks.x[k];
      if constexpr (Hinge) psd::project_psd_hinge(H, x[0], x[1], x[2], x[3]);
      else psd::project_psd_translation_free(H);
      sink += H(0, 0);
    }
  benchmark::DoNotOptimize(sink);
  bench.counters["blocks_per_s"] = benchmark::Counter(static_cast<double>(blocks.H.size()) * bench.iterations(),
                                                      benchmark::Counter::kIsRate);
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

}  // namespace

int main(int argc, char** argv) {
  // (cells along the beam, cells across): 6 n m^2 tets, from 1,536 to 96,768.
  const int sizes[][2] = {{16, 4}, {32, 6}, {48, 8}, {64, 10}, {112, 12}};
  for (const auto& sz : sizes)
    benchmark::RegisterBenchmark(fmt::format("ref-be/beam/{}tets", 6 * sz[0] * sz[1] * sz[1]).c_str(),
                                 BM_ReferenceStep, sz[0], sz[1], "ref-be")
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1)
        ->Repetitions(3);
  for (const char* scenario : {"cantilever_beam", "hanging_cloth"})
    benchmark::RegisterBenchmark(fmt::format("global-cholmod/{}", scenario).c_str(), BM_GlobalStep, scenario)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  // Warm-up: 60 steps (1 s) of the beam; 20 (1/3 s) of the cloth, which has left flat by then
  // and whose steps cost seconds each.
  for (const auto& [scenario, warmup] : {std::pair{"cantilever_beam", 60}, std::pair{"hanging_cloth", 20}})
    benchmark::RegisterBenchmark(fmt::format("global-cholmod-steady/{}", scenario).c_str(),
                                 BM_GlobalSteadyStep, scenario, warmup)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  benchmark::RegisterBenchmark("psd/12/translation_free/eigen12", BM_PsdTranslationFree<false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/hinge/restricted9", BM_PsdHinge<false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/hinge/hinge8", BM_PsdHinge<true>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/12/translation_free/restricted9", BM_PsdTranslationFree<true>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/volume/eigen12", BM_PsdVolume<false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/volume/analytic", BM_PsdVolume<true>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/9/eigen", BM_PsdProject<9, false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/9/tridiagonal_ql", BM_PsdProject<9, true>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/12/eigen", BM_PsdProject<12, false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/12/tridiagonal_ql", BM_PsdProject<12, true>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/6/fixed", BM_Psd<6, false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/6/dynamic", BM_Psd<6, true>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/12/fixed", BM_Psd<12, false>)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("psd/12/dynamic", BM_Psd<12, true>)->Unit(benchmark::kMicrosecond);
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
