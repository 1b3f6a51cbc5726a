#include "catalog/solver_catalog.hpp"
#include "harness/runner.hpp"

#include <chrono>
#include <cmath>
#include <exception>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <time.h>

#include "core/cancel.hpp"
#include "core/stage.hpp"
#include "harness/plan.hpp"
#include "harness/relax.hpp"
#include "harness/step_logger.hpp"
#include "metrics/health.hpp"
#include "metrics/shadow.hpp"
#include "solver_api/solver.hpp"
#include "solvers/pbd_material.hpp"

namespace pbdbench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The CPU time of the calling thread, s.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace

bool elastic_energy_resolved(const Model& model, double h) {
  // FEM elements: their stiffness is a matrix (Lame parameters, a compliance matrix per element)
  // that this rule does not read.
  if (!(h > 0.0) || !model.elements.empty()) return false;
  const std::vector<double> sums = pbd_inverse_mass_sums(model);
  for (std::size_t j = 0; j < model.constraints.size(); ++j) {
    const Constraint& c = model.constraints[j];
    if (is_fem_kind(c.kind)) return false;
    if (c.compliance > 0.0 && !(c.compliance / (h * h) >= sums[j])) return false;
  }
  return true;
}

void check_solver_names(const config::Config& config) {
  auto source_of = [&config](const std::string& key) {
    const config::Source& s = config.at(key).source;
    return s.file.empty() ? config::Source{config.file.string(), 0} : s;
  };
  std::vector<std::string> names, shadows;
  for (const SolverEntry& e : solver_catalog()) {
    names.push_back(e.name);
    if (e.can.shadow) shadows.push_back(e.name);
  }
  const std::string name = config.get_string("solver.name");
  if (find_solver(name) == nullptr) {
    std::string message = fmt::format("solver.name = '{}' is not one of {}", name, fmt::join(names, ", "));
    if (const std::string close = config::suggest_name(name, names); !close.empty())
      message += " (did you mean '" + close + "'?)";
    throw config::ConfigError(source_of("solver.name"), "solver.name", message);
  }
  const std::string shadow = config.get_string("shadow.solver");
  if (const SolverEntry* e = find_solver(shadow); !shadow.empty() && (e == nullptr || !e->can.shadow))
    throw config::ConfigError(source_of("shadow.solver"), "shadow.solver",
                              fmt::format("shadow.solver = '{}' is not one of the solvers that can run "
                                          "as a shadow: {} (or empty: no shadow)", shadow, fmt::join(shadows, ", ")));
}

RunOutcome run_config(const config::Config& config, const std::filesystem::path& out,
                      const RunControl& control) {
  const auto t_start = Clock::now();
  const double cpu_start = thread_cpu_seconds();
  // Everything that can be refused is refused before the file is created.
  set_stage("building the scene");
  Scene scene = config::build_scene(config);
  const SolverOptions solver_opts = config::solver_options(config);
  const config::RunOptions run = config::run_options(config);
  const Model& model = scene.model;
  State state = std::move(scene.initial);
  const std::string shadow_name = config.get_string("shadow.solver");
  // relax.frames (harness/relax.hpp): the solver steps a working copy of the model whose rest
  // values go from the initial state's to the model's over the first `relax_frames` steps.
  const long relax_frames = static_cast<long>(config.get_int("relax.frames"));
  if (relax_frames > 0) {
    const config::Source source = config.at("relax.frames").source.file.empty()
                                      ? config::Source{config.file.string(), 0}
                                      : config.at("relax.frames").source;
    if (!solver_supports_relaxation(solver_opts.name))
      throw config::ConfigError(
          source, "relax.frames",
          "relax.frames = " + std::to_string(relax_frames) + " needs a solver that reads the rest "
          "values from the model at every step (pbd, xpbd, pbd-seed); " + solver_opts.name +
          " builds its energy model once");
    if (!shadow_name.empty())
      throw config::ConfigError(
          source, "relax.frames",
          "relax.frames = " + std::to_string(relax_frames) + " cannot be combined with a shadow "
          "(shadow.solver = '" + shadow_name + "' builds its energy model once)");
  }
  // A solver that cannot run this scene is bad input (exit 2), found after parsing.
  check_solver_names(config);
  set_stage("building the solver");
  std::unique_ptr<Solver> solver;
  try {
    solver = control.make_solver ? control.make_solver(solver_opts, model) : make_solver(solver_opts, model);
  } catch (const std::invalid_argument& e) {
    throw config::ConfigError(config::Source{config.file.string(), 0}, "solver.name", e.what());
  }
  if (const SolverEntry* entry = find_solver(solver_opts.name); entry != nullptr && control.notice)
    for (const std::string& w : config::unread_solver_keys(config, entry->family))
      control.notice("warning: " + w);
  // The shadow: a global solver stepping a copy of the state from the same start.
  std::unique_ptr<Solver> shadow;
  const long shadow_every = static_cast<long>(config.get_int("shadow.every"));
  if (!shadow_name.empty()) {
    SolverOptions shadow_opts = solver_opts;
    shadow_opts.name = shadow_name;
    try {
      shadow = make_solver(shadow_opts, model);
    } catch (const std::invalid_argument& e) {
      throw config::ConfigError(config::Source{config.file.string(), 0}, "shadow.solver",
                                e.what());
    }
  }

  Model working;
  std::vector<double> relax_start;
  if (relax_frames > 0) {
    working = model;
    relax_start = initial_rest_values(model, state.x);
  }

  // The run as a whole, before anything is written: it must fit the machine (planned before the
  // initial state is measured: measuring finds its contacts, whose memory the plan bounds), and
  // its initial state must be measurable.
  set_stage("planning the run");
  const RunPlan plan = plan_run(model, solver_opts, run, control.exported);
  if (const std::string problems = plan_problems(plan, out); !problems.empty()) {
    if (!control.force)
      throw config::ConfigError(config::Source{config.file.string(), 0}, "",
                                "the planned run does not fit this machine: " + describe_plan(plan) +
                                    ": " + problems + " (estimates; --force runs it anyway)");
    if (control.notice) control.notice("running anyway (--force): " + problems);
  }
  if (plan.seconds > 60.0 && control.notice) control.notice("planned: " + describe_plan(plan));
  set_stage("measuring the initial state");
  MetricsBaseline baseline = measure_baseline(model, state);
  baseline.elastic_defined = elastic_energy_defined(model, solver_opts);
  Sample sample = measure(model, state, baseline);
  if (const std::string bad = non_finite_quantity(sample, baseline.elastic_defined); !bad.empty())
    throw config::ConfigError(config::Source{config.file.string(), 0}, "scene",
                              "the initial state cannot be measured: " + bad +
                                  " (masses, positions, velocities or gravity too large)");

  RunOutcome outcome;
  outcome.setup_time = seconds_since(t_start);
  outcome.setup_cpu_time = thread_cpu_seconds() - cpu_start;
  outcome.steps_planned = run.steps();
  const long frame_every = run.every_frame();

  if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path());
  RunHeader header;
  header.scenario = config.scenario_name;
  header.scenario_file = config.file.string();
  header.solver = solver->name();
  header.config = config.to_toml();
  header.dt = run.dt;
  header.steps_planned = outcome.steps_planned;
  header.material = material_text(model, solver_opts, run.dt);
  if (solver_opts.name == "pbd") {
    const double h = run.dt / solver_opts.substeps;
    header.pbd_stiffness = pbd_stiffness(model, solver_opts, pbd_inverse_mass_sums(model), h);
    header.pbd_stiffness_rule =
        solver_opts.pbd_material == PbdMaterial::Compliance
            ? fmt::format("derived from the compliance alpha by k = 1 - (1 + h^2 S / alpha)^(-1/n), "
                          "S = sum |w_i| |grad_i C|^2 at rest (Mueller et al. 2007's effective "
                          "stiffness; h = {} s, n = {})", h, solver_opts.iterations)
            : std::string("the explicit override, the *_stiffness keys (solver.pbd.material = "
                          "stiffness") + (solver_opts.pbd_stiffness_correction ? ", k' = 1 - (1 - k)^(1/n))" : ")");
  }
  set_stage("writing the run file's start");
  RunFileWriter writer(out, header, model);

  // Warnings (metrics/health.hpp). Energy comes in through moving kinematic particles or
  // colliders and through relaxing rest values: the energy check is off in such scenes.
  bool energy_sources = relax_frames > 0;
  for (const Attachment& a : model.attachments) energy_sources = energy_sources || a.motion >= 0;
  for (const SphereCollider& sp : model.spheres) energy_sources = energy_sources || sp.motion >= 0;
  for (const MeshCollider& mc : model.meshes) energy_sources = energy_sources || mc.motion >= 0;
  HealthMonitor health(model, state, sample,
                       HealthRun{outcome.steps_planned, energy_sources, run.dt,
                                 baseline.elastic_defined && elastic_energy_resolved(model, run.dt / solver_opts.substeps)});
  // Every way out records the warnings seen so far.
  auto record_warnings = [&] {
    for (const RunWarning& w : health.warnings()) outcome.warnings.push_back(w.line());
    outcome.health_margins = health.margins();
    outcome.health_whole_energy = health.whole_energy();
    writer.set_warnings(outcome.warnings);
  };

  const StepReport initial_report;
  writer.append({state.time, state.step, 0.0, &sample, &initial_report});
  writer.append_frame(state.time, state.x, &state.v);

  // Each step's metrics, row, frame and checks (harness/step_logger.hpp): on a thread of their
  // own when the run has a core to spare, in step order either way.
  StepLogger::Context logging;
  logging.model = &model;
  logging.baseline = &baseline;
  logging.limits = run.limits;
  logging.writer = &writer;
  logging.health = &health;
  logging.initial_sample = &sample;
  logging.initial_velocities = &state.v;
  const bool threaded = step_logging_threaded(control.logging, available_cores(), solver->threads(), model);
  StepLogger logger(logging, threaded);
  // The run ends (every way out waits for the logger first, then writes the file's end).
  auto end_run = [&](RunStatus status, const std::string& reason) -> void {
    outcome.status = status;
    outcome.reason = reason;
    outcome.steps_completed = logger.steps_logged();
    outcome.solver_time = logger.solver_time();
    outcome.solver_cpu_time = logger.solver_cpu_time();
    outcome.final_sample = logger.last_sample();
    outcome.wall_time = seconds_since(t_start);
    record_warnings();
  };
  // A logged step exploded: the run ends there, whatever the run's thread did after it.
  auto exploded = [&] {
    outcome.exploded_step = logger.exploded_step();
    end_run(RunStatus::Exploded, logger.exploded_reason());
    writer.finish(RunStatus::Exploded, outcome.reason, outcome.steps_completed, outcome.wall_time,
                  outcome.exploded_step, logger.exploded_time());
    return outcome;
  };
  // Something threw, on the run's thread or the logger's. Any failure while a cancellation is
  // pending is the cancellation's doing (core/cancel.hpp): the file keeps the steps before it.
  auto failed = [&](const std::exception& e) {
    if (dynamic_cast<const Cancelled*>(&e) != nullptr || cancel_requested()) {
      end_run(RunStatus::Incomplete,
              "interrupted during step " + std::to_string(logger.steps_logged() + 1) +
                  (dynamic_cast<const Cancelled*>(&e) != nullptr ? std::string(" (") + e.what() + ")" : ""));
      writer.finish(RunStatus::Incomplete, outcome.reason, outcome.steps_completed, outcome.wall_time);
      return outcome;
    }
    // std::bad_alloc says nothing of what ran out: the reason names it.
    end_run(RunStatus::Failed, dynamic_cast<const std::bad_alloc*>(&e) != nullptr
                                   ? std::string("out of memory (std::bad_alloc) while ") + current_stage()
                                   : std::string(e.what()));
    writer.finish(RunStatus::Failed, outcome.reason, outcome.steps_completed, outcome.wall_time);
    return outcome;
  };
  // The logger's own failure (the writer could not write), rethrown to be told like any other.
  auto logger_failed = [&]() -> RunOutcome {
    try {
      std::rethrow_exception(logger.failure());
    } catch (const std::exception& e) {
      return failed(e);
    }
  };

  State shadow_state;
  bool interrupted = false;
  set_stage("stepping the solver and logging the steps");
  try {
    for (long k = 1; k <= outcome.steps_planned && !logger.stopped(); ++k) {
      const bool shadowed = shadow && (k - 1) % shadow_every == 0;
      if (shadowed) shadow_state = state;
      const bool relaxing = k <= relax_frames;
      if (relaxing)
        blend_rest_values(model, relax_start,
                          static_cast<double>(k) / static_cast<double>(relax_frames), working);
      const auto t0 = Clock::now();
      const double cpu0 = thread_cpu_seconds();
      const StepReport report = solver->step(relaxing ? working : model, state, run.dt);
      const double cpu = thread_cpu_seconds() - cpu0;
      const double wall = seconds_since(t0);
      ShadowSample shadow_sample;
      if (shadowed) {
        const auto ts = Clock::now();
        const StepReport sr = shadow->step(model, shadow_state, run.dt);
        shadow_sample = measure_shadow(model, state, shadow_state);
        shadow_sample.time = seconds_since(ts);
        shadow_sample.cost_ratio = shadow_sample.time / wall;
        shadow_sample.residual_g = sr.residual_g;
        shadow_sample.residual_h = sr.residual_h;
        shadow_sample.residual_position = sr.residual_position;
        shadow_sample.iterations = static_cast<double>(sr.newton_iterations);
      }
      logger.log(k, state, report, wall, cpu, shadow_sample,
                 k % frame_every == 0 || k == outcome.steps_planned);
      if (control.progress) control.progress(k, outcome.steps_planned);
      const bool stop = (control.stop != nullptr && control.stop->load()) || cancel_requested();
      if (stop && k < outcome.steps_planned) {
        interrupted = true;
        break;
      }
    }
  } catch (const std::exception& e) {
    logger.drain();
    if (logger.exploded_step() >= 0) return exploded();
    if (logger.failure()) return logger_failed();
    return failed(e);
  }
  logger.drain();
  if (logger.exploded_step() >= 0) return exploded();
  if (logger.failure()) return logger_failed();
  if (interrupted) {
    // The run's thread stopped after the last step it handed over, which is logged now.
    try {
      writer.append_frame(state.time, state.x, &state.v);
    } catch (const std::exception& e) {
      return failed(e);
    }
    end_run(RunStatus::Incomplete, "interrupted after step " + std::to_string(logger.steps_logged()));
    writer.finish(RunStatus::Incomplete, outcome.reason, outcome.steps_completed, outcome.wall_time);
    return outcome;
  }
  end_run(RunStatus::Complete, "");
  writer.finish(RunStatus::Complete, "", outcome.steps_completed, outcome.wall_time);
  return outcome;
}

}  // namespace pbdbench
