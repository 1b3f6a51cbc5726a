// What the run loop (harness/runner.hpp) does with each step once the solver has taken it: the
// metrics of the new state, its row, its frame when one is due, the health warnings and the
// explosion check. Either inline, on the run's thread, after every step; or on a thread of its
// own that works through copies of the states while the run's thread takes the next steps, so
// that a run with a core to spare does not wait for its logging (metrics, rows and frames cost
// several percent of a cloth run's wall time inline; harness/* of bench_solvers measures both).
//
// Both ways log the steps in order, one at a time, with the same code: the file is the same bits
// either way, its wall-clock columns aside. A logged step that ends the run (an explosion, a
// non-finite energy, a failure to write) ends it at that step whatever the run's thread computed
// after it: the later steps are dropped, as if they had not been taken.
#pragma once

#include <condition_variable>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "metrics/health.hpp"
#include "metrics/metrics.hpp"
#include "metrics/shadow.hpp"
#include "runfile/run_file.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// How a run logs its steps (RunControl::logging).
enum class StepLogging {
  Auto,    // on a thread of its own when the run has a core to spare and a model big enough
           // for its logging to cost more than handing it over (step_logging_threaded)
  Inline,  // on the run's thread, after each step
  Thread,  // on a thread of its own
};

// The first quantity of a sample that must be finite and is not ("total energy = inf J"), or "".
// NaN-by-design series (observables a scene does not have) are not looked at. elastic_defined:
// false where elastic_energy (and the total) is NaN by definition (MetricsBaseline::elastic_defined).
std::string non_finite_quantity(const Sample& s, bool elastic_defined);

// Auto's rule: `cores` the run may use (available_cores()), `solver_threads` those its solver
// steps on, and the model's particles and constraints.
bool step_logging_threaded(StepLogging logging, int cores, int solver_threads, const Model& model);

// One step as the run's thread hands it over.
struct StepRecord {
  long k = 0;                 // the step, 1-based
  State state;                // after the step
  StepReport report;
  double wall = 0.0;          // s, wall-clock time of solver.step()
  double cpu = 0.0;           // s, the run thread's CPU time in solver.step()
  ShadowSample shadow;        // NaN fields when the step was not shadowed
  bool frame_due = false;     // a frame is stored after this step
};

class StepLogger {
 public:
  struct Context {
    const Model* model = nullptr;
    const MetricsBaseline* baseline = nullptr;
    ExplosionLimits limits;
    RunFileWriter* writer = nullptr;
    HealthMonitor* health = nullptr;
    const Sample* initial_sample = nullptr;     // row 0's
    const Points* initial_velocities = nullptr;  // the initial state's
  };
  StepLogger(const Context& context, bool threaded);
  ~StepLogger();  // drains
  StepLogger(const StepLogger&) = delete;
  StepLogger& operator=(const StepLogger&) = delete;

  // Logs step k (inline) or hands it over (threaded: a copy of the state, waiting while every
  // slot is taken). Does nothing once the logger has stopped.
  void log(long k, const State& state, const StepReport& report, double wall, double cpu,
           const ShadowSample& shadow, bool frame_due);
  // A logged step ended the run: take no more steps.
  bool stopped() const;
  // Waits until every step handed over is logged or the logger has stopped; the thread ends.
  // The results below may be read after it.
  void drain();

  long steps_logged() const { return steps_logged_; }
  double solver_time() const { return solver_time_; }          // s, of the logged steps
  double solver_cpu_time() const { return solver_cpu_time_; }  // s
  const Sample& last_sample() const { return last_sample_; }   // the last step measured
  // Set when a logged step exploded (or its energy was not finite): the step, why, its time.
  long exploded_step() const { return exploded_step_; }
  const std::string& exploded_reason() const { return exploded_reason_; }
  double exploded_time() const { return exploded_time_; }
  // Set when logging a step threw (the writer could not write): rethrown by the caller.
  std::exception_ptr failure() const { return failure_; }

 private:
  // Logs the step of record r (its state: `state`, the record's own copy when threaded).
  void process(const StepRecord& r, const State& state);
  void work();

  Context c_;
  // The velocities after the two previous steps, for velocity_hf_rms from row 2 on.
  Points v_previous_, v_before_previous_;
  long steps_logged_ = 0;
  double solver_time_ = 0.0, solver_cpu_time_ = 0.0;
  Sample last_sample_;
  long exploded_step_ = -1;
  std::string exploded_reason_;
  double exploded_time_ = 0.0;
  std::exception_ptr failure_;

  StepRecord inline_record_;
  // Threaded: a ring of slots, [head_, head_ + filled_) handed over and not yet logged.
  bool threaded_ = false;
  std::vector<StepRecord> slots_;
  size_t head_ = 0, filled_ = 0;
  bool closing_ = false;
  bool stopped_ = false;
  mutable std::mutex mutex_;
  std::condition_variable work_, space_;
  std::thread thread_;
};

}  // namespace pbdbench
