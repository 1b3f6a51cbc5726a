// The step logger (harness/step_logger.hpp): a run logged on a thread of its own writes the same
// file as one logged inline, whichever way it ends; Auto's rule.
#include <unistd.h>
#include <gtest/gtest.h>

#include <atomic>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "config/config.hpp"
#include "core/cancel.hpp"
#include "core/generators.hpp"
#include "harness/runner.hpp"
#include "harness/step_logger.hpp"
#include "runfile/run_file.hpp"

namespace fs = std::filesystem;
using namespace pbdbench;

namespace {

fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_step_logger_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

// A 12 x 12 cloth pinned at two corners: 144 particles, enough rows and frames to overlap.
const char* kCloth = R"(
name = "logger_cloth"
[time]
dt = 0.01
duration = 0.6
[output]
frame_every = 3
[solver]
name = "xpbd"
iterations = 5
[scene]
kind = "cloth"
resolution = [12, 12]
)";

bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// Everything but the wall-clock columns and attributes, bit for bit.
void expect_same_file(const fs::path& inline_file, const fs::path& threaded_file) {
  RunFileParts parts;
  parts.frames = RunFileParts::Frames::All;
  const RunFileData a = read_run_file(inline_file, parts), b = read_run_file(threaded_file, parts);
  EXPECT_EQ(a.status(), b.status());
  EXPECT_EQ(a.attributes.at("status_reason"), b.attributes.at("status_reason"));
  EXPECT_EQ(a.warnings(), b.warnings());
  for (const char* n : {"steps_completed", "exploded_step", "exploded_time"})
    if (a.numbers.count(n) != 0 || b.numbers.count(n) != 0) {
      EXPECT_TRUE(same_bits(a.numbers.at(n), b.numbers.at(n))) << n;
    }
  ASSERT_EQ(a.series.size(), b.series.size());
  for (const auto& [name, values] : a.series) {
    if (a.nondeterministic.count(name) != 0) continue;
    const std::vector<double>& other = b.series.at(name);
    ASSERT_EQ(values.size(), other.size()) << name;
    for (size_t i = 0; i < values.size(); ++i) ASSERT_TRUE(same_bits(values[i], other[i])) << name << " row " << i;
  }
  for (const auto& [name, values] : a.series3) {
    if (a.nondeterministic.count(name) != 0) continue;
    const Points& other = b.series3.at(name);
    ASSERT_EQ(values.rows(), other.rows()) << name;
    for (Eigen::Index i = 0; i < values.size(); ++i)
      ASSERT_TRUE(same_bits(values.data()[i], other.data()[i])) << name;
  }
  ASSERT_EQ(a.frame_time.size(), b.frame_time.size());
  for (size_t f = 0; f < a.frame_time.size(); ++f) {
    EXPECT_TRUE(same_bits(a.frame_time[f], b.frame_time[f]));
    ASSERT_EQ(a.frames[f].size(), b.frames[f].size());
    for (Eigen::Index i = 0; i < a.frames[f].size(); ++i) {
      ASSERT_TRUE(same_bits(a.frames[f].data()[i], b.frames[f].data()[i])) << "frame " << f;
      ASSERT_TRUE(same_bits(a.velocities[f].data()[i], b.velocities[f].data()[i])) << "frame " << f;
    }
  }
}

// Runs `cfg` both ways and compares the files; returns the threaded run's outcome.
RunOutcome both_ways(const config::Config& cfg, const std::string& name, RunControl control = {}) {
  const fs::path a = temp_file(name + "_inline.h5"), b = temp_file(name + "_thread.h5");
  control.logging = StepLogging::Inline;
  const RunOutcome inline_run = run_config(cfg, a, control);
  clear_cancel();
  control.logging = StepLogging::Thread;
  const RunOutcome threaded = run_config(cfg, b, control);
  clear_cancel();
  EXPECT_EQ(inline_run.status, threaded.status);
  EXPECT_EQ(inline_run.reason, threaded.reason);
  EXPECT_EQ(inline_run.steps_completed, threaded.steps_completed);
  EXPECT_EQ(inline_run.exploded_step, threaded.exploded_step);
  EXPECT_TRUE(same_bits(inline_run.final_sample.total_energy, threaded.final_sample.total_energy));
  expect_same_file(a, b);
  return threaded;
}

// Steps like a free fall; from step `from` on the velocity is so large that the kinetic energy
// overflows (positions finite), or the step throws, as asked.
class Breaks final : public Solver {
 public:
  enum class How { Overflows, Throws, Cancels };
  Breaks(long from, How how) : from_(from), how_(how) {}
  StepReport step(const Model&, State& state, double dt) override {
    if (state.step + 1 >= from_) {
      switch (how_) {
        case How::Overflows: state.v(5, 0) = 1.3e154; break;  // particle 5 is not pinned
        case How::Throws: throw std::runtime_error("the test solver broke at step " + std::to_string(state.step + 1));
        case How::Cancels:
          request_cancel();
          throw_if_cancelled("a test loop");
      }
    }
    for (Eigen::Index i = 0; i < state.x.rows(); ++i) state.x(i, 1) -= dt * 0.1;
    state.time += dt;
    state.step += 1;
    return {};
  }
  std::string name() const override { return "breaks"; }

 private:
  long from_;
  How how_;
};

}  // namespace

TEST(StepLogger, AThreadedRunWritesTheFileAnInlineRunWrites) {
  const config::Config cfg = config::load_text(kCloth, "logger_cloth.toml");
  const RunOutcome r = both_ways(cfg, "complete");
  EXPECT_EQ(r.status, RunStatus::Complete);
  EXPECT_EQ(r.steps_completed, 60);
  EXPECT_GT(r.solver_time, 0.0);
}

TEST(StepLogger, AThreadedRunExplodesAtTheStepAnInlineRunDoes) {
  // The cloth falls freely (no pins): its speed crosses 0.5 m/s at step 6 (g t = 0.59 m/s);
  // the run's thread may have taken steps after it when the logger sees the explosion.
  const config::Config cfg = config::load_text(kCloth, "logger_cloth.toml",
                                               {{"limits.max_speed", "0.5"}, {"scene.pins", "none"}});
  const RunOutcome r = both_ways(cfg, "exploded");
  EXPECT_EQ(r.status, RunStatus::Exploded);
  EXPECT_EQ(r.exploded_step, 6);
  EXPECT_EQ(r.steps_completed, 6);
}

TEST(StepLogger, ANonFiniteEnergyAThrowingStepAndACancellationEndTheRunAsInline) {
  // 3 kg a particle: 3 kg (1.3e154 m/s)^2 / 2 overflows, the speed stays within the limit.
  const config::Config cfg = config::load_text(kCloth, "logger_cloth.toml",
                                               {{"scene.mass", "432"}, {"limits.max_speed", "1e300"}});
  RunControl control;
  control.make_solver = [](const SolverOptions&, const Model&) { return std::make_unique<Breaks>(7, Breaks::How::Overflows); };
  RunOutcome r = both_ways(cfg, "overflow", control);
  EXPECT_EQ(r.status, RunStatus::Exploded);
  EXPECT_EQ(r.exploded_step, 7);
  EXPECT_NE(r.reason.find("kinetic energy"), std::string::npos) << r.reason;
  control.make_solver = [](const SolverOptions&, const Model&) { return std::make_unique<Breaks>(9, Breaks::How::Throws); };
  r = both_ways(cfg, "throws", control);
  EXPECT_EQ(r.status, RunStatus::Failed);
  EXPECT_EQ(r.steps_completed, 8);
  EXPECT_NE(r.reason.find("broke at step 9"), std::string::npos) << r.reason;
  control.make_solver = [](const SolverOptions&, const Model&) { return std::make_unique<Breaks>(4, Breaks::How::Cancels); };
  r = both_ways(cfg, "cancelled", control);
  EXPECT_EQ(r.status, RunStatus::Incomplete);
  EXPECT_EQ(r.steps_completed, 3);
  EXPECT_NE(r.reason.find("interrupted during step 4"), std::string::npos) << r.reason;
}

TEST(StepLogger, AStopFlagEndsAThreadedRunAfterTheStepItWasSeen) {
  const config::Config cfg = config::load_text(kCloth, "logger_cloth.toml");
  std::atomic<bool> stop{false};
  RunControl control;
  control.stop = &stop;
  control.progress = [&](long done, long) { stop = done >= 10; };
  const RunOutcome r = both_ways(cfg, "stopped", control);
  EXPECT_EQ(r.status, RunStatus::Incomplete);
  EXPECT_EQ(r.steps_completed, 10);
}

TEST(StepLogger, AutoUsesAThreadOnlyWithACoreToSpareAndAModelWorthIt) {
  Model big, small;
  ClothSpec cloth;
  cloth.nx = cloth.ny = 32;  // 1024 particles, about 6000 constraints
  add_cloth(big, cloth);
  cloth.nx = cloth.ny = 8;  // 64 particles, about 300 constraints
  add_cloth(small, cloth);
  EXPECT_TRUE(step_logging_threaded(StepLogging::Auto, 2, 1, big));
  EXPECT_FALSE(step_logging_threaded(StepLogging::Auto, 1, 1, big));  // one core (sweep --jobs)
  EXPECT_FALSE(step_logging_threaded(StepLogging::Auto, 2, 2, big));  // the solver's threads use them
  EXPECT_FALSE(step_logging_threaded(StepLogging::Auto, 2, 1, small));
  EXPECT_TRUE(step_logging_threaded(StepLogging::Thread, 1, 1, small));
  EXPECT_FALSE(step_logging_threaded(StepLogging::Inline, 8, 1, big));
}
