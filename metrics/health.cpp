#include "metrics/health.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

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
    : model_(&model),
      th_(thresholds),
      steps_planned_(steps_planned),
      energy_sources_(energy_sources),
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
  // The push-out of an initial overlap: at most 1/2 m (d0 / dt)^2 of kinetic energy.
  const double d0 = s0.penetration_max;
  const double push = dt > 0.0 && d0 > 0.0 ? 0.5 * dynamic_mass(model) * (d0 / dt) * (d0 / dt) : 0.0;
  if (std::isfinite(push)) e0_ += push;
  energy_scale_ = dynamic_mass(model) * model.gravity.norm() * height + std::abs(s0.kinetic_energy) +
                  (std::isfinite(e_el0) ? std::abs(e_el0) : 0.0) + (std::isfinite(push) ? push : 0.0);
  if (!(energy_scale_ > 0.0)) energy_scale_ = 1e-12;
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
  // The motion energy (kinetic + gravitational) against the initial total energy: with no source,
  // K + U_g = E(0) - E_el <= E(0) since E_el >= 0, whatever the elastic energy's accounting
  // (an unconverged stiff constraint's C^2 / 2 alpha is large without any motion gained).
  const double motion = s.kinetic_energy + s.potential_energy;
  if (!energy_sources_ && std::isfinite(motion) && std::isfinite(e0_)) {
    const double gain = motion - e0_;
    note(energy_, gain, gain > th_.energy_gain * energy_scale_);
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
  if (!model_->planes.empty() || !model_->spheres.empty()) {
    const Tunnelled t = tunnelled_particles(*model_, x_prev_, state.x, state.time);
    if (t.count > 0) {
      tunnel_particles_ = std::max<long>(tunnel_particles_, t.count);
      note(tunnel_, t.depth, true);
    }
  }
  x_prev_ = state.x;
}

std::vector<RunWarning> HealthMonitor::warnings() const {
  std::vector<RunWarning> out;
  if (energy_.seen)
    out.push_back({"energy_gain", energy_.first_step, energy_.first_time,
                   fmt::format("kinetic + gravitational energy rose {:.3g} J above the initial total "
                               "energy (most at step {}) with no energy source; threshold {:.3g} J = {} x "
                               "the energy scale {:.3g} J",
                               energy_.worst, energy_.worst_step, th_.energy_gain * energy_scale_,
                               th_.energy_gain, energy_scale_)});
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
