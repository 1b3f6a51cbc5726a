// The run loop: a run file per run, explosion detection and stop, interruption, determinism.
#include <unistd.h>
#include <gtest/gtest.h>

#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>
#include <stdexcept>

#include "config/config.hpp"
#include "core/cancel.hpp"
#include "harness/runner.hpp"
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"
#include "core/constraint_functions.hpp"
#include "solvers/pbd_material.hpp"

namespace fs = std::filesystem;
using namespace pbdbench;

namespace {

fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_runner_" + std::to_string(::getpid()));  // one folder per test process: sessions sharing /tmp do not collide
  fs::create_directories(dir);
  return dir / name;
}

const char* kFreeFall = R"(
name = "free_fall_test"
gravity = [0, -10, 0]
[time]
dt = 0.01
duration = 1.0
[solver]
name = "xpbd"
[scene]
kind = "particle"
position = [0, 100, 0]
velocity = [0, 0, 0]
)";

}  // namespace

TEST(Runner, CompleteRunWritesEveryStep) {
  const config::Config cfg = config::load_text(kFreeFall, "free_fall_test.toml");
  const fs::path out = temp_file("complete.h5");
  const RunOutcome r = run_config(cfg, out);
  EXPECT_EQ(r.status, RunStatus::Complete);
  EXPECT_EQ(r.steps_planned, 100);
  EXPECT_EQ(r.steps_completed, 100);
  const RunFileData d = read_run_file(out);
  EXPECT_EQ(d.status(), "complete");
  ASSERT_EQ(d.series.at("time").size(), 101u);  // the initial state, then one row a step
  EXPECT_NEAR(d.series.at("time").back(), 1.0, 1e-12);
  EXPECT_EQ(d.attributes.at("solver"), "xpbd");
  EXPECT_EQ(d.attributes.at("config"), cfg.to_toml());
  // Free fall: kinetic energy after 1 s of g = 10 from rest is 1/2 m (g t)^2 = 50 J (m = default mass).
  const double m = cfg.get_double("scene.mass");
  EXPECT_NEAR(d.series.at("kinetic_energy").back(), 0.5 * m * 100.0, 1e-9 * m * 100.0);
}

TEST(Runner, ExplosionStopsTheRunAtTheStepItIsDetected) {
  // With dt = 0.01 and symplectic Euler the speed after step k is v_k = 10 * 0.01 k m/s, which
  // first exceeds 5.05 m/s at k = 51 (the limit sits between v_50 and v_51, clear of round-off).
  const config::Config cfg =
      config::load_text(kFreeFall, "free_fall_test.toml", {{"limits.max_speed", "5.05"}});
  const fs::path out = temp_file("exploded.h5");
  const RunOutcome r = run_config(cfg, out);
  EXPECT_EQ(r.status, RunStatus::Exploded);
  EXPECT_EQ(r.exploded_step, 51);
  EXPECT_NE(r.reason.find("limits.max_speed"), std::string::npos) << r.reason;
  const RunFileData d = read_run_file(out);
  EXPECT_EQ(d.status(), "exploded");
  EXPECT_EQ(d.numbers.at("exploded_step"), 51);
  EXPECT_EQ(d.series.at("time").size(), 52u);  // everything up to the explosion is kept
  EXPECT_GT(d.series.at("max_speed").back(), 5.0);
}

TEST(Runner, StopFlagLeavesAnIncompleteFile) {
  const config::Config cfg = config::load_text(kFreeFall, "free_fall_test.toml");
  const fs::path out = temp_file("interrupted.h5");
  std::atomic<bool> stop{false};
  RunControl control;
  control.stop = &stop;
  control.progress = [&](long done, long) {
    if (done == 10) stop = true;
  };
  const RunOutcome r = run_config(cfg, out, control);
  EXPECT_EQ(r.status, RunStatus::Incomplete);
  EXPECT_EQ(r.steps_completed, 10);
  const RunFileData d = read_run_file(out);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_EQ(d.series.at("time").size(), 11u);
}

TEST(Runner, RefusedConfigurationWritesNoFile) {
  const fs::path out = temp_file("refused.h5");
  fs::remove(out);
  EXPECT_THROW(config::load_text(kFreeFall, "free_fall_test.toml", {{"scene.mass", "-1"}}),
               config::ConfigError);
  EXPECT_FALSE(fs::exists(out));
}

// Determinism: the same inputs give the same results, bit for bit, on the same build. Every
// catalog scenario, every solver, a shuffled order included, shortened to a few steps.
TEST(Runner, SameInputsGiveIdenticalSeries) {
  for (const auto& info : config::list_scenarios()) {
    for (const char* solver : {"pbd-seed", "pbd", "xpbd"}) {
      std::vector<config::Override> o = {{"solver.name", solver},
                                         {"solver.order", "shuffled"},
                                         {"time.duration", "0.1"},
                                         {"time.dt", "0.02"}};
      const config::Config cfg = config::load(info.file.string(), o);
      const fs::path a = temp_file("det_a.h5"), b = temp_file("det_b.h5");
      const Model model = config::build_scene(cfg).model;
      if (std::string(solver) != "xpbd" && !model.elements.empty()) {
        // pbd and pbd-seed have no FEM material: they refuse the FEM scenes, as bad input (exit 2).
        EXPECT_THROW(run_config(cfg, a), config::ConfigError) << info.name << " " << solver;
        continue;
      }
      if (std::string(solver) == "pbd-seed" && (model.surface_contact || model.self_contact)) {
        // The seed's listing has no vertex-triangle contact: refused, as bad input (exit 2).
        EXPECT_THROW(run_config(cfg, a), config::ConfigError) << info.name << " " << solver;
        continue;
      }
      run_config(cfg, a);
      run_config(cfg, b);
      const RunFileData da = read_run_file(a), db = read_run_file(b);
      ASSERT_EQ(da.status(), db.status()) << info.name << " " << solver;
      for (const SeriesSpec& s : series_table()) {
        if (!s.deterministic) continue;
        const std::string name(s.name);
        // Bitwise: the same bits, so that NaN (an exploded run) equals itself.
        if (s.width == 1) {
          const auto& x = da.series.at(name);
          const auto& y = db.series.at(name);
          ASSERT_EQ(x.size(), y.size());
          for (size_t k = 0; k < x.size(); ++k)
            ASSERT_EQ(std::bit_cast<std::uint64_t>(x[k]), std::bit_cast<std::uint64_t>(y[k]))
                << info.name << " " << solver << " " << name << "[" << k << "]: " << x[k] << " vs " << y[k];
        } else {
          const Points& x = da.series3.at(name);
          const Points& y = db.series3.at(name);
          ASSERT_EQ(x.size(), y.size());
          ASSERT_EQ(std::memcmp(x.data(), y.data(), sizeof(double) * static_cast<size_t>(x.size())), 0)
              << info.name << " " << solver << " " << name;
        }
      }
    }
  }
}

// The shadow (shadow.solver): the global solver's converged step from the same start as every
// k-th step, logged beside the run without changing it. Its gap shrinks as the run's iterations
// grow, the run's own series are those of a run without a shadow, and the steps without a shadow
// solve hold NaN.
TEST(Runner, ShadowGapShrinksAsIterationsGrowAndLeavesTheRunAlone) {
  auto shadow_run = [](int iterations, int every, const std::string& tag) {
    std::vector<config::Override> o = {{"solver.iterations", std::to_string(iterations)},
                                       {"time.duration", "0.5"},
                                       {"shadow.solver", "global-cholmod"},
                                       {"shadow.every", std::to_string(every)}};
    const fs::path out = temp_file("shadow_" + tag + ".h5");
    EXPECT_EQ(run_config(config::load("hanging_chain", o), out).status, RunStatus::Complete);
    return read_run_file(out);
  };
  double previous = std::numeric_limits<double>::infinity();
  for (int iterations : {1, 5, 20, 100}) {
    const RunFileData d = shadow_run(iterations, 1, std::to_string(iterations));
    const auto& gap = d.series.at("shadow_gap_rms");
    EXPECT_TRUE(std::isnan(gap[0]));  // the initial row
    double mean = 0.0;
    for (size_t k = 1; k < gap.size(); ++k) mean += gap[k] / static_cast<double>(gap.size() - 1);
    EXPECT_LT(mean, previous) << iterations << " iterations";
    previous = mean;
    for (size_t k = 1; k < gap.size(); ++k)
      EXPECT_LE(d.series.at("shadow_residual_position")[k], 1e-9);
  }
  // Every other step, and the run unchanged by its shadow.
  const RunFileData sparse = shadow_run(5, 2, "every2");
  const auto& gap = sparse.series.at("shadow_gap_rms");
  for (size_t k = 1; k < gap.size(); ++k) EXPECT_EQ(std::isnan(gap[k]), k % 2 == 0) << k;
  const fs::path plain = temp_file("shadow_none.h5");
  run_config(config::load("hanging_chain", {{"solver.iterations", "5"}, {"time.duration", "0.5"}}),
             plain);
  const RunFileData d0 = read_run_file(plain);
  const auto& a = d0.series.at("constraint_error_max");
  const auto& b = sparse.series.at("constraint_error_max");
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k)
    EXPECT_EQ(std::bit_cast<std::uint64_t>(a[k]), std::bit_cast<std::uint64_t>(b[k]));
}

// config/ stands below the catalogue: the names are checked against it when the run starts (and
// by whatever validates runs before starting any), naming the key and where it was set.
TEST(Runner, ShadowMustBeAGlobalSolver) {
  const config::Config cfg = config::load("hanging_chain", {{"shadow.solver", "xpbd"}});
  const fs::path out = temp_file("shadow_xpbd.h5");
  try {
    (void)run_config(cfg, out);
    ADD_FAILURE() << "a shadow that is not a global solver was accepted";
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.key(), "shadow.solver");
    EXPECT_EQ(e.source().file, "--set shadow.solver=xpbd");
    EXPECT_NE(std::string(e.what()).find("global-cholmod, global-cg, global-ceres"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(Runner, SolverNameMustBeInTheCatalogue) {
  const config::Config cfg = config::load_text("[solver]\nname = \"xbpd\"\n[scene]\nkind = \"chain\"\n", "bad_solver.toml");
  try {
    check_solver_names(cfg);
    ADD_FAILURE() << "an unknown solver was accepted";
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.key(), "solver.name");
    EXPECT_EQ(e.source().file, "bad_solver.toml");
    EXPECT_EQ(e.source().line, 2);
    EXPECT_NE(std::string(e.what()).find("(did you mean 'xpbd'?)"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(check_solver_names(config::load("hanging_chain", {{"shadow.solver", "global-cg"}})));
}

// ---------------------------------------------------------------------------------------------
// The failure detectors in the run file, and relax.frames (harness/relax.hpp).

TEST(Runner, DetectorSeriesAppearInTheRunFile) {
  // The free fall from y = 100 under a plane y = 150 (normal +y, offset -150) that the particle
  // starts 50 m below: sunk 50 m at t = 0. The contact then throws it onto the plane.
  const std::string text = std::string(kFreeFall) + R"(
[[collider]]
type = "plane"
normal = [0.0, 1.0, 0.0]
offset = -150.0
)";
  const config::Config cfg = config::load_text(text, "free_fall_test.toml", {{"time.duration", "0.1"}});
  const fs::path out = temp_file("detectors.h5");
  ASSERT_EQ(run_config(cfg, out).status, RunStatus::Complete);
  const RunFileData d = read_run_file(out);
  const auto& height = d.series.at("height_min");
  const auto& count = d.series.at("sunk_count");
  const auto& depth = d.series.at("sunk_depth");
  const auto& jitter = d.series.at("velocity_hf_rms");
  ASSERT_EQ(height.size(), 11u);
  ASSERT_EQ(jitter.size(), 11u);
  EXPECT_EQ(height[0], 100.0);
  EXPECT_EQ(count[0], 1.0);
  EXPECT_EQ(depth[0], 50.0);
  // After the first step the particle is on the plane (its centre at 150 + radius).
  EXPECT_EQ(count[1], 0.0);
  EXPECT_EQ(depth[1], 0.0);
  EXPECT_GT(height[1], 150.0);
  // Rows 0 and 1 have no two earlier velocities; then the jitter is finite.
  EXPECT_TRUE(std::isnan(jitter[0]));
  EXPECT_TRUE(std::isnan(jitter[1]));
  for (size_t k = 2; k < jitter.size(); ++k) EXPECT_TRUE(std::isfinite(jitter[k])) << k;
}

TEST(Runner, JitterOfAFreeFallIsZeroUpToRoundOff) {
  // v_n = -g n dt: a constant acceleration, whose second difference is 0 up to the round-off of
  // the velocities (about 1e-16 of 10 m/s).
  const config::Config cfg = config::load_text(kFreeFall, "free_fall_test.toml");
  const fs::path out = temp_file("jitter_free_fall.h5");
  ASSERT_EQ(run_config(cfg, out).status, RunStatus::Complete);
  const RunFileData d = read_run_file(out);
  const auto& jitter = d.series.at("velocity_hf_rms");
  for (size_t k = 2; k < jitter.size(); ++k) EXPECT_LT(jitter[k], 1e-13) << k;
}

TEST(Runner, NegativeInverseMassRunsWithThePbdSolvers) {
  for (const char* solver : {"pbd", "xpbd", "pbd-seed"}) {
    SCOPED_TRACE(solver);
    const config::Config cfg = config::load("failures/negative_inverse_mass",
                                            {{"solver.name", solver}, {"time.duration", "0.25"}});
    const fs::path out = temp_file(std::string("negative_mass_") + solver + ".h5");
    const RunOutcome r = run_config(cfg, out);
    EXPECT_NE(r.status, RunStatus::Failed) << r.reason;
    EXPECT_GE(read_run_file(out).series.at("time").size(), 2u);
  }
}

// A spring of rest length 1 started at length 1.5, without gravity: one PBD projection with
// k = 1 (or an XPBD one with compliance 0) puts the single link exactly at the rest value it is
// given. Relaxed over 4 steps the solver's rest value is 1.5 - 0.5 (k + 1) / 4 at step k, so the
// error measured against the true rest length falls 0.375, 0.25, 0.125, 0; unrelaxed it is 0
// after the first step.
TEST(Runner, RelaxationBlendsTheRestValuesOverTheFirstSteps) {
  const char* spring = R"(
gravity = [0, 0, 0]
[scene]
kind = "spring"
rest_length = 1.0
initial_length = 1.5
compliance = 0.0
[time]
dt = 0.01
duration = 0.08
[solver]
iterations = 1
)";
  for (const char* solver : {"pbd", "xpbd"}) {
    SCOPED_TRACE(solver);
    const fs::path relaxed = temp_file(std::string("relaxed_") + solver + ".h5");
    const fs::path plain = temp_file(std::string("unrelaxed_") + solver + ".h5");
    ASSERT_EQ(run_config(config::load_text(spring, "spring.toml", {{"solver.name", solver}, {"relax.frames", "4"}}), relaxed).status,
              RunStatus::Complete);
    ASSERT_EQ(run_config(config::load_text(spring, "spring.toml", {{"solver.name", solver}}), plain).status,
              RunStatus::Complete);
    const RunFileData d = read_run_file(relaxed), d0 = read_run_file(plain);
    const auto& e = d.series.at("constraint_error_max");
    const auto& e0 = d0.series.at("constraint_error_max");
    ASSERT_EQ(e.size(), 9u);
    const double expected[] = {0.5, 0.375, 0.25, 0.125, 0.0};
    for (size_t k = 0; k < 5; ++k) EXPECT_NEAR(e[k], expected[k], 1e-12) << k;
    EXPECT_NEAR(e0[0], 0.5, 1e-12);
    EXPECT_NEAR(e0[1], 0.0, 1e-12);
  }
  // pbd-seed reads its rest values from the model it is given too: it runs relaxed.
  const fs::path seed = temp_file("relaxed_seed.h5");
  EXPECT_NE(run_config(config::load_text(spring, "spring.toml", {{"solver.name", "pbd-seed"}, {"relax.frames", "4"}}), seed).status,
            RunStatus::Failed);
}

TEST(Runner, RelaxationIsRefusedForSolversThatCacheTheModel) {
  const fs::path out = temp_file("relax_refused.h5");
  for (const char* solver : {"global-cholmod", "ref-bdf"}) {
    fs::remove(out);
    const config::Config cfg = config::load("hanging_chain", {{"solver.name", solver}, {"relax.frames", "8"}});
    try {
      run_config(cfg, out);
      ADD_FAILURE() << solver << ": expected a ConfigError";
    } catch (const config::ConfigError& e) {
      EXPECT_EQ(e.key(), "relax.frames") << solver;
      EXPECT_NE(std::string(e.what()).find("pbd, xpbd, pbd-seed"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(out)) << solver;
  }
  const config::Config shadowed =
      config::load("hanging_chain", {{"relax.frames", "8"}, {"shadow.solver", "global-cholmod"}});
  try {
    run_config(shadowed, out);
    ADD_FAILURE() << "expected a ConfigError";
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.key(), "relax.frames");
  }
}

// ---------------------------------------------------------------------------------------------
// Interrupts inside a step, results that become non-finite, plans beyond the machine.

namespace {

// A solver whose step 3 asks for a cancellation half-way (as a signal would) and then polls, as
// the projection loops do; other steps move the particle like a free fall.
class CancelsInStep3 final : public Solver {
 public:
  StepReport step(const Model&, State& state, double dt) override {
    if (state.step + 1 == 3) {
      state.x(0, 1) = -1e9;  // a half-done step: must never reach the file
      request_cancel();
      throw_if_cancelled("a test loop");
    }
    state.x(0, 1) -= dt;
    state.time += dt;
    state.step += 1;
    return {};
  }
  std::string name() const override { return "cancels-in-step-3"; }
};

// A solver whose velocities become so large after step 2 that the kinetic energy overflows to
// infinity, while every position, speed and extent stays finite and within the limits.
class OverflowsEnergy final : public Solver {
 public:
  StepReport step(const Model&, State& state, double dt) override {
    if (state.step + 1 >= 3) state.v(0, 0) = 1.3e154;  // v^2 = 1.7e308 is finite, 3 kg * v^2 / 2 is not
    state.time += dt;
    state.step += 1;
    return {};
  }
  std::string name() const override { return "overflows-energy"; }
};

}  // namespace

TEST(Runner, CancellationInsideAStepEndsTheRunIncompleteWithTheStepsBefore) {
  clear_cancel();
  const config::Config cfg = config::load_text(kFreeFall, "free_fall_test.toml");
  const fs::path out = temp_file("cancelled.h5");
  RunControl control;
  control.make_solver = [](const SolverOptions&, const Model&) { return std::make_unique<CancelsInStep3>(); };
  const RunOutcome r = run_config(cfg, out, control);
  clear_cancel();
  EXPECT_EQ(r.status, RunStatus::Incomplete);
  EXPECT_EQ(r.steps_completed, 2);
  EXPECT_NE(r.reason.find("interrupted during step 3"), std::string::npos) << r.reason;
  EXPECT_NE(r.reason.find("a test loop"), std::string::npos) << r.reason;
  const RunFileData d = read_run_file(out);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_EQ(d.series.at("step").size(), 3u);  // rows 0, 1, 2
  EXPECT_EQ(d.numbers.at("steps_completed"), 2);
}

TEST(Runner, ANonFiniteEnergyEndsTheRunAsExploded) {
  const std::string text = std::string(kFreeFall) + "mass = 3.0\n[limits]\nmax_speed = 1e300\n";
  const config::Config cfg = config::load_text(text, "free_fall_test.toml");
  const fs::path out = temp_file("overflow.h5");
  RunControl control;
  control.make_solver = [](const SolverOptions&, const Model&) { return std::make_unique<OverflowsEnergy>(); };
  const RunOutcome r = run_config(cfg, out, control);
  EXPECT_EQ(r.status, RunStatus::Exploded);
  EXPECT_EQ(r.exploded_step, 3);
  EXPECT_NE(r.reason.find("kinetic energy"), std::string::npos) << r.reason;
  EXPECT_EQ(read_run_file(out, false).status(), "exploded");
}

TEST(Runner, APlanBeyondTheMachineIsRefusedBeforeAnyFileUnlessForced) {
  // 10^5 links and 10^5 iterations: 10^10 projections a step, 1200 steps: about 43 hours at the
  // plan's 13 ns a distance projection, beyond its one-day limit.
  const config::Config cfg = config::load_text(
      "[scene]\nkind = \"chain\"\nlinks = 100000\n[solver]\niterations = 100000\n[time]\nduration = 20.0\n",
      "huge.toml");
  const fs::path out = temp_file("huge.h5");
  fs::remove(out);
  try {
    run_config(cfg, out);
    ADD_FAILURE() << "the plan was not refused";
  } catch (const config::ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("does not fit this machine"), std::string::npos) << what;
    EXPECT_NE(what.find("more than a day"), std::string::npos) << what;
    EXPECT_NE(what.find("--force"), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(out));
}

// A soft stable neo-Hookean bar (E = 2e5 Pa, nu = 0.45) under xpbd with one step
// of 10 iterations per frame collapses (a third of its volume in the first steps) and gains
// energy without crossing any explosion limit, some of its tets inside out: the run is complete
// and says so with warnings, and its FEM elements count in the constraint error. The same bar
// with 40 substeps of one iteration (the catalog's setting) keeps its volume and gets no volume
// warning.
TEST(Runner, CollapsingFemBarIsWarnedNotSilentlyComplete) {
  const std::vector<config::Override> bar = {{"scene.youngs_modulus", "2e5"},
                                             {"scene.poisson_ratio", "0.45"},
                                             {"time.duration", "0.5"}};
  std::vector<config::Override> collapsing = bar;
  collapsing.push_back({"solver.substeps", "1"});
  collapsing.push_back({"solver.iterations", "10"});
  const fs::path out = temp_file("collapsing_bar.h5");
  const RunOutcome r = run_config(config::load(PBDBENCH_SOURCE_DIR "/scenarios/cantilever_fem.toml", collapsing), out);
  EXPECT_EQ(r.status, RunStatus::Complete);
  const RunFileData d = read_run_file(out);
  const std::vector<std::string> w = d.warnings();
  ASSERT_EQ(w.size(), 3u) << d.attributes.at("warnings");
  EXPECT_EQ(w[0].rfind("inverted @", 0), 0u) << w[0];  // tets turned inside out (metrics/health.hpp)
  EXPECT_EQ(w[1].rfind("energy_gain @", 0), 0u) << w[1];
  EXPECT_EQ(w[2].rfind("volume @1 ", 0), 0u) << w[2];
  EXPECT_EQ(d.numbers.at("warning_count"), 3.0);
  EXPECT_EQ(r.warnings, w);
  EXPECT_GT(d.series.at("constraint_error_max").back(), 0.1) << "the FEM elements count";

  const fs::path ok = temp_file("holding_bar.h5");
  run_config(config::load(PBDBENCH_SOURCE_DIR "/scenarios/cantilever_fem.toml", bar), ok);
  const RunFileData held = read_run_file(ok);
  EXPECT_EQ(held.attributes.at("warnings").find("volume"), std::string::npos) << held.attributes.at("warnings");
}

// One material (solvers/pbd_material.hpp, docs/solvers.md): elastic_energy is the scene's
// physical material's energy, sum C^2 / (2 alpha), whatever the solver, measured at the run's own
// positions; NaN where the run does not simulate that material (pbd with an explicit k). The run
// file says what pbd used: the root attribute "material" and /model/pbd_stiffness.
TEST(Runner, ElasticEnergyIsTheSceneMaterialsWhateverTheSolver) {
  const std::vector<config::Override> base = {{"scene.links", "5"},
                                              {"scene.compliance", "0.002"},
                                              {"scene.angle_deg", "40"},
                                              {"time.duration", "0.2"}};
  for (const char* solver : {"pbd", "xpbd"}) {
    SCOPED_TRACE(solver);
    std::vector<config::Override> o = base;
    o.push_back({"solver.name", solver});
    const config::Config cfg = config::load("hanging_chain", o);
    const fs::path out = temp_file(std::string("elastic_") + solver + ".h5");
    ASSERT_EQ(run_config(cfg, out).status, RunStatus::Complete);
    RunFileParts parts;
    parts.frames = RunFileParts::Frames::Last;
    parts.model = true;
    const RunFileData d = read_run_file(out, parts);
    // The formula at the last frame's positions.
    double energy = 0.0;
    for (const Constraint& c : d.model.constraints) {
      const double C = eval_constraint(c, d.frames.back()).C;
      energy += C * C / (2.0 * c.compliance);
    }
    const double series = d.series.at("elastic_energy").back();
    EXPECT_GT(energy, 0.0);
    EXPECT_NEAR(series, energy, 1e-12 * energy);
    EXPECT_NEAR(d.series.at("total_energy").back(),
                d.series.at("kinetic_energy").back() + d.series.at("potential_energy").back() + energy,
                1e-9 * std::abs(d.series.at("total_energy").back()) + 1e-12);
    const std::string material = d.attributes.at("material");
    if (std::string(solver) == "pbd") {
      EXPECT_NE(material.find("derived from alpha = 0.002"), std::string::npos) << material;
      const SolverOptions so = config::solver_options(cfg);
      const std::vector<double> S = pbd_inverse_mass_sums(d.model);
      ASSERT_EQ(d.pbd_stiffness.size(), d.model.constraints.size());
      for (size_t j = 0; j < S.size(); ++j)
        EXPECT_EQ(d.pbd_stiffness[j], pbd_stiffness_from_compliance(0.002, S[j], 1.0 / 60.0 / so.substeps,
                                                                    so.iterations));
    } else {
      EXPECT_NE(material.find("alpha = 0.002"), std::string::npos) << material;
      EXPECT_TRUE(d.pbd_stiffness.empty());
    }
  }
  // The explicit override: pbd does not simulate the compliance, and the energy is NaN (the run
  // is complete, not an explosion).
  std::vector<config::Override> o = base;
  o.push_back({"solver.name", "pbd"});
  o.push_back({"solver.pbd.material", "stiffness"});
  o.push_back({"scene.stiffness", "0.5"});
  const fs::path out = temp_file("elastic_pbd_override.h5");
  ASSERT_EQ(run_config(config::load("hanging_chain", o), out).status, RunStatus::Complete);
  RunFileParts parts;
  parts.model = true;
  const RunFileData d = read_run_file(out, parts);
  for (double e : d.series.at("elastic_energy")) EXPECT_TRUE(std::isnan(e));
  EXPECT_NE(d.attributes.at("material").find("k = 0.5 (explicit override"), std::string::npos);
  for (double k : d.pbd_stiffness) EXPECT_EQ(k, 0.5);
}
