#include "harness/step_logger.hpp"

#include <cmath>
#include <utility>

namespace pbdbench {

namespace {

// Auto: a thread when the model has at least this many particles and constraints together. A
// judgement, not a measurement: below it a step's logging is small (tens of microseconds), of
// the order of handing it over (a copy of the state and a wake-up of the thread).
constexpr long kThreadedFrom = 2048;
// Threaded: steps handed over and not yet logged, at most (each a copy of the state).
constexpr size_t kSlots = 3;

}  // namespace

std::string non_finite_quantity(const Sample& s, bool elastic_defined) {
  const std::pair<const char*, double> scalars[] = {
      {"kinetic energy", s.kinetic_energy}, {"potential energy", s.potential_energy},
      {"elastic energy", s.elastic_energy}, {"total energy", s.total_energy}};
  const std::size_t checked = elastic_defined ? 4 : 2;  // the elastic and total energies last
  for (std::size_t i = 0; i < checked; ++i)
    if (!std::isfinite(scalars[i].second))
      return std::string(scalars[i].first) + " = " + std::to_string(scalars[i].second) + " J";
  if (!s.linear_momentum.allFinite()) return "linear momentum not finite";
  if (!s.angular_momentum.allFinite()) return "angular momentum not finite";
  return "";
}

bool step_logging_threaded(StepLogging logging, int cores, int solver_threads, const Model& model) {
  switch (logging) {
    case StepLogging::Inline: return false;
    case StepLogging::Thread: return true;
    case StepLogging::Auto: break;
  }
  const long size = static_cast<long>(model.particle_count()) + static_cast<long>(model.constraints.size());
  return cores > solver_threads && size >= kThreadedFrom;
}

StepLogger::StepLogger(const Context& context, bool threaded) : c_(context), threaded_(threaded) {
  v_previous_ = *c_.initial_velocities;
  last_sample_ = *c_.initial_sample;
  if (threaded_) {
    slots_.resize(kSlots);
    thread_ = std::thread([this] { work(); });
  }
}

StepLogger::~StepLogger() { drain(); }

void StepLogger::process(const StepRecord& r, const State& state) {
  const Model& model = *c_.model;
  const MetricsBaseline& baseline = *c_.baseline;
  Sample sample = measure(model, state, baseline);
  if (r.k >= 2) sample.velocity_hf_rms = velocity_hf_rms(model, state.v, v_previous_, v_before_previous_);
  v_before_previous_.swap(v_previous_);
  v_previous_ = state.v;
  last_sample_ = sample;
  c_.writer->append({state.time, state.step, r.wall, &sample, &r.report, &r.shadow});
  steps_logged_ = r.k;
  solver_time_ += r.wall;
  solver_cpu_time_ += r.cpu;
  c_.health->observe(r.k, state, sample);
  if (const StopReasonInfo& why = stop_reason_info(r.report.stop); !why.trusted)
    c_.health->observe_untrusted_stop(r.k, state.time, why.name);
  std::string why = explosion_reason(model, state, sample, c_.limits, baseline);
  if (why.empty()) why = non_finite_quantity(sample, baseline.elastic_defined);
  if (!why.empty()) {
    c_.writer->append_frame(state.time, state.x, &state.v);
    exploded_step_ = r.k;
    exploded_reason_ = why;
    exploded_time_ = state.time;
    return;
  }
  if (r.frame_due) c_.writer->append_frame(state.time, state.x, &state.v);
}

void StepLogger::log(long k, const State& state, const StepReport& report, double wall, double cpu,
                     const ShadowSample& shadow, bool frame_due) {
  // Everything of the step but its state.
  const auto fill = [&](StepRecord& r) {
    r.k = k;
    r.report = report;
    r.wall = wall;
    r.cpu = cpu;
    r.shadow = shadow;
    r.frame_due = frame_due;
  };
  if (!threaded_) {
    if (stopped_) return;
    // Inline: the caller's state itself, not a copy (its record's state stays empty).
    StepRecord& r = inline_record_;
    fill(r);
    try {
      process(r, state);
    } catch (...) {
      failure_ = std::current_exception();
      stopped_ = true;
    }
    if (exploded_step_ >= 0) stopped_ = true;
    return;
  }
  size_t slot = 0;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    space_.wait(lock, [this] { return filled_ < slots_.size() || stopped_; });
    if (stopped_) return;
    slot = (head_ + filled_) % slots_.size();
  }
  // The slot is the run thread's until it is counted as filled.
  StepRecord& r = slots_[slot];
  fill(r);
  r.state.time = state.time;
  r.state.step = state.step;
  r.state.x = state.x;
  r.state.v = state.v;
  r.state.lambda = state.lambda;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++filled_;
  }
  work_.notify_one();
}

bool StepLogger::stopped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stopped_;
}

void StepLogger::work() {
  for (;;) {
    size_t slot = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      work_.wait(lock, [this] { return filled_ > 0 || closing_; });
      if (filled_ == 0) return;  // closing, everything logged
      slot = head_;
    }
    bool stop = false;
    try {
      process(slots_[slot], slots_[slot].state);
      stop = exploded_step_ >= 0;
    } catch (...) {
      failure_ = std::current_exception();
      stop = true;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      head_ = (head_ + 1) % slots_.size();
      --filled_;
      if (stop) {
        stopped_ = true;
        filled_ = 0;  // the steps after it are dropped
      }
    }
    space_.notify_one();
    if (stop) return;
  }
}

void StepLogger::drain() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closing_ = true;
  }
  work_.notify_one();
  thread_.join();
}

}  // namespace pbdbench
