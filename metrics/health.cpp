#include "metrics/health.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace pbdbench {

namespace {

// The largest normalised constraint error of a state taken as satisfied (rest positions give
// round-off only).
constexpr double kSatisfied = 1e-9;

double dynamic_mass(const Model& model) {
  double m = 0.0;
  for (double w : model.inv_mass)
    if (w > 0.0) m += 1.0 / w;
  return m;
}

// Closest distance from c to the segment a-b.
double segment_distance(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((c - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + s * ab - c).norm();
}

}  // namespace

std::string RunWarning::line() const {
  return fmt::format("{} @{} (t = {:.4g} s): {}", code, step, time, message);
}

std::string HealthMargin::line() const {
  if (std::isnan(ratio)) return fmt::format("{} off", code);
  return fmt::format("{} {:.3g} @{}", code, ratio, step);
}

std::string symptom_of(const std::string& code) {
  static const std::map<std::string, std::string> symptoms = {
      {"overstretched", "a link stretched beyond twice its rest length"},
      {"inverted", "tets turned inside out"},
      {"left_region", "particles left the scene's region"},
      {"too_fast", "particles faster than the scene's energy and gravity explain"},
      {"energy_gain", "energy made by the solver"},
      {"penetration", "bodies staying inside each other or a collider"},
      {"not_settling", "a scene that should rest keeps trembling"},
      {"volume", "volume lost or gained"},
      {"error_growth", "constraint error growing through the run"},
      {"tunnelling", "particles through a collider"},
      {"solver_stop", "steps the solver did not finish"},
  };
  const auto it = symptoms.find(code);
  return it == symptoms.end() ? std::string() : it->second;
}

std::string warnings_text(const std::vector<RunWarning>& warnings) {
  std::string out;
  for (const RunWarning& w : warnings) {
    if (!out.empty()) out += '\n';
    out += w.line();
  }
  return out;
}

Tunnelled tunnelled_particles(const Model& model, const Points& x_prev, const Points& x, double t) {
  Tunnelled out;
  const Vec3 up = up_direction(model);
  std::vector<Vec3> centers;
  for (const SphereCollider& sphere : model.spheres) centers.push_back(sphere_center(model, sphere, t));
  for (int i = 0; i < model.particle_count(); ++i) {
    if (model.inv_mass[static_cast<size_t>(i)] == 0.0) continue;
    const Vec3 p = x.row(i);
    if (!p.allFinite()) continue;
    const double r = i < static_cast<int>(model.radius.size()) ? model.radius[static_cast<size_t>(i)] : 0.0;
    double deepest = -1.0;  // beyond the radius; < 0: not tunnelled
    for (const PlaneCollider& plane : model.planes) {
      const double nn = plane.normal.norm();
      if (!(nn > 0.0)) continue;
      const double below = -(plane.normal.dot(p) + plane.offset) / nn - r;
      if (below > 0.0) deepest = std::max(deepest, below);
    }
    for (size_t k = 0; k < model.spheres.size(); ++k) {
      const SphereCollider& sphere = model.spheres[k];
      const Vec3 d = p - centers[k];
      const double dist = d.norm();
      double beyond = -1.0;
      switch (sphere.side) {
        case SphereSide::Outside: {
          beyond = (sphere.radius - r) - dist;
          if (beyond <= 0.0 && x_prev.rows() == x.rows()) {
            const Vec3 a = x_prev.row(i);
            if (a.allFinite() && (a - centers[k]).norm() >= sphere.radius &&
                segment_distance(a, p, centers[k]) < sphere.radius - r)
              beyond = 0.0;  // went through and out again
          }
          break;
        }
        case SphereSide::Inside: beyond = dist - (sphere.radius + r); break;
        case SphereSide::Bowl: beyond = d.dot(up) < 0.0 ? dist - (sphere.radius + r) : -1.0; break;
      }
      if (beyond >= 0.0) deepest = std::max(deepest, beyond);
    }
    for (const MeshCollider& mesh : model.meshes) {
      const double beyond = -mesh_distance(mesh, p - mesh_offset(model, mesh, t)).distance - r;
      if (beyond >= 0.0) deepest = std::max(deepest, beyond);
    }
    if (deepest >= 0.0) {
      ++out.count;
      out.depth = std::max(out.depth, deepest);
    }
  }
  return out;
}

HealthMonitor::HealthMonitor(const Model& model, const State& initial, const Sample& s0,
                             long steps_planned, bool energy_sources, double dt,
                             HealthThresholds thresholds)
    : HealthMonitor(model, initial, s0, HealthRun{steps_planned, energy_sources, dt, false}, thresholds) {}

HealthMonitor::HealthMonitor(const Model& model, const State& initial, const Sample& s0, const HealthRun& run,
                             HealthThresholds thresholds)
    : model_(&model),
      th_(thresholds),
      steps_planned_(run.steps_planned),
      energy_sources_(run.energy_sources),
      dt_(run.dt),
      whole_energy_(run.whole_energy && std::isfinite(s0.elastic_energy)),
      e0_(s0.total_energy),
      x_prev_(initial.x) {
  // elastic_energy is NaN where the run does not simulate the scene's physical material (an
  // explicit k): E_el(0) is then 0 only when every constraint starts satisfied, whatever the
  // material; otherwise the bound E(0) is unknown and the energy check is off.
  double e_el0 = s0.elastic_energy;
  if (std::isnan(e_el0)) {
    e_el0 = s0.constraint_error_max <= kSatisfied ? 0.0 : std::numeric_limits<double>::quiet_NaN();
    e0_ = s0.kinetic_energy + s0.potential_energy + e_el0;
  }
  const double height = std::max(2.0 * s0.extent, 1e-3);
  const double mass = dynamic_mass(model);
  // The push-out of an initial overlap: at most 1/2 m (d0 / dt)^2 of kinetic energy.
  const double d0 = s0.penetration_max;
  const double push = dt_ > 0.0 && d0 > 0.0 ? 0.5 * mass * (d0 / dt_) * (d0 / dt_) : 0.0;
  if (std::isfinite(push)) e0_ += push;
  energy_scale_ = mass * model.gravity.norm() * height + std::abs(s0.kinetic_energy) +
                  (std::isfinite(e_el0) ? std::abs(e_el0) : 0.0) + (std::isfinite(push) ? push : 0.0);
  if (!(energy_scale_ > 0.0)) energy_scale_ = 1e-12;

  // The scene's region and the speeds it explains.
  region0_ = th_.region_factor * std::max(s0.extent, th_.region_floor);
  v0_ = std::isfinite(s0.max_speed) ? s0.max_speed : 0.0;
  g_ = model.gravity.norm();
  v_fall_ = std::sqrt(2.0 * g_ * height);
  double w_max = 0.0;
  for (size_t i = 0; i < model.inv_mass.size(); ++i) {
    const double w = model.inv_mass[i];
    if (!(w > 0.0)) continue;
    w_max = std::max(w_max, w);
    const double r = i < model.radius.size() ? model.radius[i] : 0.0;
    if (r > 0.0 && (radius_min_ == 0.0 || r < radius_min_)) radius_min_ = r;
  }
  const double stored = (std::isfinite(e_el0) ? std::max(e_el0, 0.0) : std::numeric_limits<double>::quiet_NaN()) +
                        (std::isfinite(push) ? push : 0.0);
  v_stored_ = w_max > 0.0 ? std::sqrt(2.0 * stored * w_max) : 0.0;  // NaN: E_el(0) unknown
  // A scene that starts with a link overstretched or a tet inverted shows it from its first
  // frame (an initial state that violates its constraints): named at step 0.
  const double t0 = initial.time;
  if (s0.link_stretch_max > th_.link_stretch) {
    stretch_ = {true, 0, t0, s0.link_stretch_max, 0};
    stretch_peak_ = {true, s0.link_stretch_max / th_.link_stretch, 0, s0.link_stretch_max, th_.link_stretch};
  }
  if (s0.tets_inverted > 0) {
    inverted_ = {true, 0, t0, static_cast<double>(s0.tets_inverted), 0};
    inverted_peak_ = {true, static_cast<double>(s0.tets_inverted), 0, static_cast<double>(s0.tets_inverted), 1.0};
  }
  colliders_ = !model.planes.empty() || !model.spheres.empty() || !model.meshes.empty() ||
               model.particle_contact || model.self_contact;
}

void HealthMonitor::peak(Peak& p, long step, double value, double bound) {
  if (!std::isfinite(value) || !(bound > 0.0)) return;
  const double ratio = value / bound;
  if (!p.on || ratio > p.ratio) {
    p.ratio = ratio;
    p.step = step;
    p.value = value;
    p.bound = bound;
  }
  p.on = true;
}

void HealthMonitor::observe_untrusted_stop(long step, double time, const std::string& reason) {
  if (!stop_.seen) {
    stop_.seen = true;
    stop_.first_step = step;
    stop_.first_time = time;
  }
  stop_.worst += 1.0;
  ++stops_[reason];
}

void HealthMonitor::observe(long step, const State& state, const Sample& s) {
  last_step_ = std::max(last_step_, step);
  auto note = [&](Worst& w, double value, bool crossed) {
    if (!crossed) return;
    if (!w.seen) {
      w.seen = true;
      w.first_step = step;
      w.first_time = state.time;
    }
    if (std::abs(value) > std::abs(w.worst)) {
      w.worst = value;
      w.worst_step = step;
    }
  };
  const double t = state.time;
  // Energy made by the solver (the header: the whole energy where the elastic energy means
  // something, else the motion energy against the initial total).
  const double energy = whole_energy_ ? s.total_energy : s.kinetic_energy + s.potential_energy;
  if (!energy_sources_ && std::isfinite(energy) && std::isfinite(e0_)) {
    const double gain = energy - e0_;
    const double bound = th_.energy_gain * energy_scale_;
    peak(energy_peak_, step, gain, bound);
    note(energy_, gain, gain > bound);
  }
  // Overstretched links and inverted tets.
  peak(stretch_peak_, step, s.link_stretch_max, th_.link_stretch);
  note(stretch_, s.link_stretch_max, s.link_stretch_max > th_.link_stretch);
  if (!model_->tets.empty()) {
    // The ratio: inverted tets against one (any is warned).
    peak(inverted_peak_, step, static_cast<double>(s.tets_inverted), 1.0);
    note(inverted_, s.tets_inverted, s.tets_inverted > 0);
  }
  // The scene's region and the speeds it explains.
  if (!energy_sources_) {
    const double region = region0_ + 2.0 * (v0_ * t + 0.5 * g_ * t * t);
    peak(region_peak_, step, s.distance_from_start_max, region);
    note(region_, s.distance_from_start_max / region, s.distance_from_start_max > region);
    if (std::isfinite(v_stored_)) {
      const double speed = th_.speed_factor * (v0_ + g_ * t + v_fall_ + v_stored_);
      peak(speed_peak_, step, s.max_speed, speed);
      note(speed_, s.max_speed / speed, s.max_speed > speed);
    }
  }
  for (const auto& [what, drift] : {std::pair<const char*, double>{"tet volume", s.volume_drift},
                                    {"enclosed surface volume", s.surface_volume_drift}}) {
    if (std::isfinite(drift) && std::abs(drift) > th_.volume_change) {
      if (std::abs(drift) > std::abs(volume_.worst)) volume_what_ = what;
      note(volume_, drift, true);
    }
  }
  if (steps_planned_ >= 8 && std::isfinite(s.constraint_error_rms)) {
    const long q = std::clamp((4 * (step - 1)) / steps_planned_, 0L, 3L);
    if (quarter_n_[q] == 0) {
      quarter_step_[q] = step;
      quarter_time_[q] = state.time;
    }
    quarter_sum_[q] += s.constraint_error_rms;
    ++quarter_n_[q];
  }
  // The last quarter of the planned steps (at least the last step): the smallest penetration and
  // the mean jitter.
  if (steps_planned_ > 0 && step > steps_planned_ - std::max(1L, steps_planned_ / 4)) {
    if (last_penetration_n_ == 0 && last_jitter_n_ == 0) {
      last_first_step_ = step;
      last_first_time_ = t;
    }
    const double p = std::isfinite(s.penetration_max) ? s.penetration_max : 0.0;
    last_penetration_min_ = last_penetration_n_ == 0 ? p : std::min(last_penetration_min_, p);
    ++last_penetration_n_;
    if (std::isfinite(s.velocity_hf_rms)) {
      last_jitter_sum_ += s.velocity_hf_rms;
      ++last_jitter_n_;
    }
  }
  if (!model_->planes.empty() || !model_->spheres.empty()) {
    const Tunnelled tn = tunnelled_particles(*model_, x_prev_, state.x, state.time);
    if (tn.count > 0) {
      tunnel_particles_ = std::max<long>(tunnel_particles_, tn.count);
      note(tunnel_, tn.depth, true);
    }
  }
  x_prev_ = state.x;
}

std::vector<HealthMargin> HealthMonitor::margins() const {
  constexpr double kOff = std::numeric_limits<double>::quiet_NaN();
  std::vector<HealthMargin> out;
  const auto add = [&](const char* code, const Peak& p) {
    out.push_back({code, p.on ? p.ratio : kOff, p.on ? p.step : 0});
  };
  add("overstretched", stretch_peak_);
  add("inverted", inverted_peak_);
  add("left_region", region_peak_);
  add("too_fast", speed_peak_);
  add("energy_gain", energy_peak_);
  // The last quarter's: the smallest penetration against its depth, the mean jitter against g dt.
  const double depth = th_.penetration * radius_min_;
  out.push_back({"penetration", colliders_ && last_penetration_n_ > 0 && depth > 0.0 ? last_penetration_min_ / depth : kOff,
                 last_first_step_});
  const double jitter = th_.jitter * g_ * dt_;
  out.push_back({"not_settling",
                 colliders_ && !energy_sources_ && steps_planned_ >= 8 && last_jitter_n_ > 0 && jitter > 0.0
                     ? last_jitter_sum_ / static_cast<double>(last_jitter_n_) / jitter
                     : kOff,
                 last_first_step_});
  return out;
}

std::vector<RunWarning> HealthMonitor::warnings() const {
  std::vector<RunWarning> out;
  if (stretch_.seen)
    out.push_back({"overstretched", stretch_.first_step, stretch_.first_time,
                   fmt::format("a link stretched to {:.3g} times its rest length (most at step {}{}); "
                               "threshold: {:.3g} times, |d - d0| / d0 = {}",
                               1.0 + stretch_.worst, stretch_.worst_step,
                               stretch_.worst_step == 0 ? ", the initial state" : "", 1.0 + th_.link_stretch,
                               th_.link_stretch)});
  if (inverted_.seen)
    out.push_back({"inverted", inverted_.first_step, inverted_.first_time,
                   fmt::format("{} of {} tets turned inside out at once (most at step {}; signed volume "
                               "below 0)",
                               static_cast<long>(inverted_.worst), model_->tets.size(), inverted_.worst_step)});
  if (region_.seen)
    out.push_back({"left_region", region_.first_step, region_.first_time,
                   fmt::format("a particle went {:.3g} m from where the scene started, {:.3g} times the "
                               "region its size, initial speeds and gravity allow ({:.3g} m at step {}; "
                               "{} x the initial extent + twice the distance v0 t + g t^2 / 2)",
                               region_peak_.value, region_.worst, region_peak_.bound, region_.worst_step,
                               th_.region_factor)});
  if (speed_.seen)
    out.push_back({"too_fast", speed_.first_step, speed_.first_time,
                   fmt::format("a particle moved at {:.3g} m/s, {:.3g} times the {:.3g} m/s the scene's "
                               "initial speeds, gravity and stored energy explain at step {} ({} x v0 + g t + "
                               "sqrt(2 g H) + sqrt(2 E_stored / m_min))",
                               speed_peak_.value, speed_.worst * th_.speed_factor, speed_peak_.bound / th_.speed_factor,
                               speed_.worst_step, th_.speed_factor)});
  if (energy_.seen)
    out.push_back({"energy_gain", energy_.first_step, energy_.first_time,
                   fmt::format("{} rose {:.3g} J above the initial total energy (most at step {}) with "
                               "no energy source; threshold {:.3g} J = {} x the energy scale {:.3g} J",
                               whole_energy_ ? "the total energy (kinetic + gravitational + elastic)"
                                             : "kinetic + gravitational energy",
                               energy_.worst, energy_.worst_step, th_.energy_gain * energy_scale_,
                               th_.energy_gain, energy_scale_)});
  for (const HealthMargin& m : margins()) {
    if (!(m.ratio > 1.0)) continue;
    if (m.code == "penetration")
      out.push_back({"penetration", last_first_step_, last_first_time_,
                     fmt::format("contacts stayed penetrated by at least {:.3g} m in every step of the "
                                 "run's last quarter (from step {}); threshold {:.3g} m = {} x the "
                                 "smallest particle radius {:.3g} m",
                                 last_penetration_min_, last_first_step_, th_.penetration * radius_min_,
                                 th_.penetration, radius_min_)});
    if (m.code == "not_settling")
      out.push_back({"not_settling", last_first_step_, last_first_time_,
                     fmt::format("the velocities kept trembling through the run's last quarter (from "
                                 "step {}): mean velocity_hf_rms {:.3g} m/s; threshold {:.3g} m/s = {} x "
                                 "g dt",
                                 last_first_step_, last_jitter_sum_ / static_cast<double>(last_jitter_n_),
                                 th_.jitter * g_ * dt_, th_.jitter)});
  }
  if (volume_.seen)
    out.push_back({"volume", volume_.first_step, volume_.first_time,
                   fmt::format("{} {} {:.3g} % (most at step {}); threshold {:.3g} %", volume_what_,
                               volume_.worst < 0.0 ? "lost" : "gained", 100.0 * std::abs(volume_.worst),
                               volume_.worst_step, 100.0 * th_.volume_change)});
  bool all_quarters = true;
  double mean[4];
  for (int q = 0; q < 4; ++q) {
    all_quarters = all_quarters && quarter_n_[q] > 0;
    mean[q] = quarter_n_[q] > 0 ? quarter_sum_[q] / static_cast<double>(quarter_n_[q]) : 0.0;
  }
  if (all_quarters && mean[0] < mean[1] && mean[1] < mean[2] && mean[2] < mean[3] &&
      mean[3] > th_.error_growth_ratio * mean[0] && mean[3] > th_.error_floor) {
    out.push_back({"error_growth", quarter_step_[1], quarter_time_[1],
                   fmt::format("the RMS constraint error grew in every quarter of the run: means "
                               "{:.3g}, {:.3g}, {:.3g}, {:.3g} (threshold: x{} and above {:.3g})",
                               mean[0], mean[1], mean[2], mean[3], th_.error_growth_ratio,
                               th_.error_floor)});
  }
  if (tunnel_.seen)
    out.push_back({"tunnelling", tunnel_.first_step, tunnel_.first_time,
                   fmt::format("up to {} particles in one step ended beyond a collider's surface by "
                               "more than their radius or passed through a sphere (deepest {:.3g} m "
                               "beyond the radius, at step {})",
                               tunnel_particles_, tunnel_.worst, tunnel_.worst_step)});
  if (stop_.seen) {
    std::string reasons;
    for (const auto& [reason, n] : stops_) reasons += fmt::format("{}{} {}", reasons.empty() ? "" : ", ", n, reason);
    out.push_back({"solver_stop", stop_.first_step, stop_.first_time,
                   fmt::format("the solver's step stopped short of what it claims in {} of {} "
                               "steps: {}", static_cast<long>(stop_.worst),
                               std::max(last_step_, stop_.first_step), reasons)});
  }
  return out;
}

}  // namespace pbdbench
