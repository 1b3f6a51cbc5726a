// A small hand-made model and hand-made rows for the run-file tests and their helper programs
// (the kill-test writer, the fixture writer of the Python tests).
#pragma once

#include <cmath>
#include <numbers>
#include <string>

#include "core/model.hpp"
#include "metrics/metrics.hpp"
#include "runfile/run_file.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench::test {

// One positively oriented unit tetrahedron: 4 particles (particle 3 pinned), 6 edges, 4 outward
// triangles (a closed surface), 6 distance constraints (group "stretch"), 1 volume constraint
// (group "volume") and 1 bending constraint (group "bending", compliant).
inline Model fixture_model() {
  Model m;
  m.name = "fixture";
  m.rest_positions.resize(4, 3);
  m.rest_positions << 0, 0, 0,  //
      1, 0, 0,                  //
      0, 1, 0,                  //
      0, 0, 1;
  m.inv_mass = {1.0, 0.5, 2.0, 0.0};
  m.radius = {0.01, 0.02, 0.03, 0.04};
  m.gravity = Vec3(0.0, -9.81, 0.0);
  m.edges = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  m.tets = {{0, 1, 2, 3}};
  m.surface_closed = true;
  const std::uint16_t stretch = m.group_index("stretch");
  for (const auto& e : m.edges) {
    Constraint c;
    c.kind = ConstraintKind::Distance;
    c.particles = {e[0], e[1], -1, -1};
    c.rest = (m.rest_positions.row(e[1]) - m.rest_positions.row(e[0])).norm();
    c.compliance = 1e-4;
    c.stiffness = 0.9;
    c.damping = 0.01;
    c.group = stretch;
    m.constraints.push_back(c);
  }
  Constraint v;
  v.kind = ConstraintKind::Volume;
  v.particles = {0, 1, 2, 3};
  v.rest = 1.0 / 6.0;
  v.group = m.group_index("volume");
  m.constraints.push_back(v);
  Constraint b;
  b.kind = ConstraintKind::Bending;
  b.particles = {1, 2, 0, 3};
  b.rest = std::numbers::pi / 2;
  b.compliance = 0.5;
  b.group = m.group_index("bending");
  m.constraints.push_back(b);
  return m;
}

// A sample whose every field is a distinct function of the row index r, so that a value read
// back identifies both its series and its row.
inline Sample fixture_sample(long r, size_t groups) {
  const double x = static_cast<double>(r);
  Sample s;
  s.constraint_error_max = 1e-3 * (x + 1);
  s.constraint_error_rms = 5e-4 * (x + 1);
  for (size_t g = 0; g < groups; ++g)
    s.groups.push_back(GroupError{1e-3 * (x + 1) * (g + 1), 1e-4 * (x + 1) * (g + 1), 3});
  s.tet_volume = 1.0 / 6.0 + 1e-5 * x;
  s.volume_drift = 6e-5 * x;
  s.surface_volume = 1.0 / 6.0 + 2e-5 * x;
  s.surface_volume_drift = 1.2e-4 * x;
  s.kinetic_energy = 0.5 * x;
  s.potential_energy = -9.81 * x;
  s.elastic_energy = 0.01 * x;
  s.total_energy = s.kinetic_energy + s.potential_energy + s.elastic_energy;
  s.linear_momentum = Vec3(x, 2 * x, 3 * x);
  s.angular_momentum = Vec3(-x, -2 * x, -3 * x);
  s.penetration_max = 1e-4 * x;
  s.penetration_count = static_cast<int>(r % 5);
  s.max_speed = 0.1 * x;
  s.extent = 1.0 + 0.001 * x;
  s.tip_displacement = Vec3(0.0, -1e-3 * x, 0.0);
  s.support_force = Vec3(0.0, 9.81 + 1e-2 * x, 0.0);
  s.pendulum_angle = std::sin(0.1 * x);
  return s;
}

inline StepReport fixture_report(long r) {
  StepReport rep;
  if (r == 0) return rep;  // the initial row: a default report
  rep.substeps = 2;
  rep.iterations = 10;
  rep.contacts = static_cast<int>(r % 7);
  rep.active_contacts = static_cast<int>(r % 3);
  rep.skipped = 0;
  rep.residual_g = 1e-6 * static_cast<double>(r);
  rep.residual_h = 2e-6 * static_cast<double>(r);
  rep.time_predict = 1e-6;
  rep.time_contacts = 2e-6;
  rep.time_project = 3e-6;
  rep.time_velocity = 4e-6;
  return rep;
}

// Positions of frame f: the rest positions shifted by f mm along x.
inline Points fixture_frame(const Model& m, long f) {
  Points x = m.rest_positions;
  x.col(0).array() += 1e-3 * static_cast<double>(f);
  return x;
}

inline std::string fixture_config(const std::string& solver, int iterations, int substeps) {
  return "[scenario]\nname = \"fixture\"\n\n[solver]\nname = \"" + solver +
         "\"\niterations = " + std::to_string(iterations) + "\nsubsteps = " +
         std::to_string(substeps) + "\n\n[run]\ndt = 0.01\nsteps = 100\n";
}

// The header of a run of the fixture (xpbd, 10 iterations, 2 substeps, dt 0.01 s, 100 steps).
inline RunHeader fixture_header(const std::string& scenario_file = "scenarios/fixture.toml") {
  RunHeader h;
  h.scenario = "fixture";
  h.scenario_file = scenario_file;
  h.solver = "xpbd";
  h.config = fixture_config("xpbd", 10, 2);
  h.dt = 0.01;
  h.steps_planned = 100;
  return h;
}

}  // namespace pbdbench::test
