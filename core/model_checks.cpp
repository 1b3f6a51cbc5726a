// Soundness checks of a Model and a State (core/model_checks.hpp). Problems are reported in a
// fixed order: gravity, particles, topology (edges, triangles, tets), constraints, motions,
// attachments, colliders, particle contact coefficients.
#include "core/model_checks.hpp"

#include <algorithm>
#include <cmath>

#include "core/build_helpers.hpp"
#include "core/constraint_functions.hpp"

namespace pbdbench {

using namespace core::detail;  // core/build_helpers.hpp

namespace {

std::string num(double v) { return format_number(v, kShortDigits); }
std::string vec(const Vec3& v) { return format_vec3(v, kShortDigits); }

class Problems {
 public:
  void add(std::string what) { list_.push_back({std::move(what)}); }
  std::vector<ModelProblem> take() { return std::move(list_); }

 private:
  std::vector<ModelProblem> list_;
};

// Checks that the first `count` indices are in [0, n) and pairwise distinct; true when they are.
template <size_t K>
bool check_indices(Problems& out, const std::string& name, const std::array<int, K>& p, int count, int n) {
  for (int k = 0; k < count; ++k) {
    const int i = p[static_cast<size_t>(k)];
    if (i < 0 || i >= n) {
      out.add(name + " (particles " + index_list(p, count) + "): index " + std::to_string(i) +
              " is out of range [0, " + std::to_string(n) + ")");
      return false;
    }
  }
  for (int a = 0; a < count; ++a)
    for (int b = a + 1; b < count; ++b)
      if (p[static_cast<size_t>(a)] == p[static_cast<size_t>(b)]) {
        out.add(name + " (particles " + index_list(p, count) + ") repeats particle " +
                std::to_string(p[static_cast<size_t>(a)]));
        return false;
      }
  return true;
}

double max_edge(const std::vector<Vec3>& x) {
  double m = 0.0;
  for (size_t a = 0; a < x.size(); ++a)
    for (size_t b = a + 1; b < x.size(); ++b) m = std::max(m, (x[a] - x[b]).norm());
  return m;
}

void check_motion_index(Problems& out, const std::string& name, int motion, const Model& model) {
  if (motion < -1 || motion >= static_cast<int>(model.motions.size()))
    out.add(name + ": motion " + std::to_string(motion) + " is out of range [-1, " +
            std::to_string(model.motions.size()) + ")");
}

void check_coefficients(Problems& out, const std::string& name, double restitution, double friction) {
  if (!(restitution >= 0.0 && restitution <= 1.0))
    out.add(name + ": restitution " + num(restitution) + " is outside [0, 1]");
  if (!(friction >= 0.0) || !std::isfinite(friction))
    out.add(name + ": friction " + num(friction) + " is negative or not finite");
}

}  // namespace

std::vector<ModelProblem> check_model(const Model& model, const std::vector<int>& free_inverse_mass) {
  Problems out;
  const int n = model.particle_count();
  auto free_mass = [&](int i) {
    return std::find(free_inverse_mass.begin(), free_inverse_mass.end(), i) != free_inverse_mass.end();
  };

  if (!model.gravity.allFinite()) out.add("gravity " + vec(model.gravity) + " is not finite");

  // Particles. Per-particle checks need the arrays to agree in size.
  const bool sizes_ok = model.inv_mass.size() == static_cast<size_t>(n) &&
                        model.radius.size() == static_cast<size_t>(n);
  if (model.inv_mass.size() != static_cast<size_t>(n))
    out.add("inv_mass has " + std::to_string(model.inv_mass.size()) + " entries for " + std::to_string(n) +
            " particles");
  if (model.radius.size() != static_cast<size_t>(n))
    out.add("radius has " + std::to_string(model.radius.size()) + " entries for " + std::to_string(n) +
            " particles");
  if (!model.particle_body.empty() && model.particle_body.size() != static_cast<size_t>(n))
    out.add("particle_body has " + std::to_string(model.particle_body.size()) + " entries for " +
            std::to_string(n) + " particles");
  for (size_t i = 0; i < model.particle_body.size(); ++i)
    if (model.particle_body[i] < 0) {
      out.add("particle " + std::to_string(i) + ": body " + std::to_string(model.particle_body[i]) +
              " is negative");
      break;
    }
  for (int i = 0; i < n; ++i) {
    const Vec3 x = model.rest_positions.row(i);
    const std::string name = "particle " + std::to_string(i);
    if (!x.allFinite()) out.add(name + ": position " + vec(x) + " is not finite");
    if (!sizes_ok) continue;
    const double w = model.inv_mass[static_cast<size_t>(i)];
    if (!std::isfinite(w)) out.add(name + ": inverse mass " + num(w) + " is not finite");
    else if (w < 0.0 && !free_mass(i)) out.add(name + ": inverse mass " + num(w) + " is negative");
    const double r = model.radius[static_cast<size_t>(i)];
    if (!(r > 0.0) || !std::isfinite(r)) out.add(name + ": radius " + num(r) + " is not positive and finite");
  }

  // Topology.
  for (size_t e = 0; e < model.edges.size(); ++e)
    check_indices(out, "edge " + std::to_string(e), model.edges[e], 2, n);
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    const auto& tri = model.triangles[t];
    const std::string name = "triangle " + std::to_string(t);
    if (!check_indices(out, name, tri, 3, n)) continue;
    const std::vector<Vec3> x{model.rest_positions.row(tri[0]), model.rest_positions.row(tri[1]),
                              model.rest_positions.row(tri[2])};
    const double area = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]).norm();
    const double l = max_edge(x);
    // Degenerate: area <= 1e-12 (max edge)^2, scale-free.
    if (!(area > 1e-12 * l * l))
      out.add(name + " (particles " + index_list(tri, 3) + ") is degenerate: area " + num(area));
  }
  for (size_t t = 0; t < model.tets.size(); ++t) {
    const auto& tet = model.tets[t];
    const std::string name = "tet " + std::to_string(t);
    if (!check_indices(out, name, tet, 4, n)) continue;
    const std::vector<Vec3> x{model.rest_positions.row(tet[0]), model.rest_positions.row(tet[1]),
                              model.rest_positions.row(tet[2]), model.rest_positions.row(tet[3])};
    const double v = tet_signed_volume(x[0], x[1], x[2], x[3]);
    const double l = max_edge(x);
    // Degenerate: |V| <= 1e-9 (max edge)^3, scale-free. (A regular tet has V = 0.118 l^3.)
    if (!(std::abs(v) > 1e-9 * l * l * l))
      out.add(name + " (particles " + index_list(tet, 4) + ") is degenerate: volume " + num(v));
  }

  // Constraints.
  for (size_t c = 0; c < model.constraints.size(); ++c) {
    const Constraint& k = model.constraints[c];
    const std::string name = "constraint " + std::to_string(c) + " (" + to_string(k.kind) + ")";
    check_indices(out, name, k.particles, arity(k.kind), n);
    if (!std::isfinite(k.rest)) out.add(name + ": rest " + num(k.rest) + " is not finite");
    else if (k.kind == ConstraintKind::Distance && k.rest < 0.0)
      out.add(name + ": rest length " + num(k.rest) + " is negative");
    if (!(k.compliance >= 0.0) || !std::isfinite(k.compliance))
      out.add(name + ": compliance " + num(k.compliance) + " is negative or not finite");
    if (!(k.stiffness >= 0.0 && k.stiffness <= 1.0))
      out.add(name + ": stiffness " + num(k.stiffness) + " is outside [0, 1]");
    if (!(k.damping >= 0.0) || !std::isfinite(k.damping))
      out.add(name + ": damping " + num(k.damping) + " is negative or not finite");
    if (k.group >= model.group_names.size())
      out.add(name + ": group " + std::to_string(k.group) + " is out of range [0, " +
              std::to_string(model.group_names.size()) + ")");
  }

  // Motions.
  for (size_t m = 0; m < model.motions.size(); ++m) {
    const Motion& mo = model.motions[m];
    const std::string name = "motion " + std::to_string(m);
    if (!mo.velocity.allFinite() || !mo.amplitude.allFinite() || !mo.axis.allFinite() ||
        !std::isfinite(mo.radius) || !std::isfinite(mo.frequency) || !std::isfinite(mo.start) ||
        std::isnan(mo.stop))
      out.add(name + ": a parameter is not finite");
    if (mo.kind == MotionKind::Circle && !(mo.axis.norm() > 0.0)) out.add(name + ": circle axis is zero");
  }

  // Attachments.
  std::vector<int> attached;
  for (size_t a = 0; a < model.attachments.size(); ++a) {
    const Attachment& at = model.attachments[a];
    const std::string name = "attachment " + std::to_string(a);
    if (at.particle < 0 || at.particle >= n) {
      out.add(name + ": particle " + std::to_string(at.particle) + " is out of range [0, " + std::to_string(n) + ")");
    } else {
      if (sizes_ok && model.inv_mass[static_cast<size_t>(at.particle)] != 0.0)
        out.add(name + ": particle " + std::to_string(at.particle) + " has inverse mass " +
                num(model.inv_mass[static_cast<size_t>(at.particle)]) + ", not 0");
      attached.push_back(at.particle);
    }
    if (!at.anchor.allFinite()) out.add(name + ": anchor " + vec(at.anchor) + " is not finite");
    check_motion_index(out, name, at.motion, model);
  }
  std::sort(attached.begin(), attached.end());
  for (size_t i = 1; i < attached.size(); ++i)
    if (attached[i] == attached[i - 1] && (i < 2 || attached[i - 2] != attached[i]))
      out.add("particle " + std::to_string(attached[i]) + " is attached more than once");

  // Colliders.
  for (size_t p = 0; p < model.planes.size(); ++p) {
    const PlaneCollider& pl = model.planes[p];
    const std::string name = "plane " + std::to_string(p);
    if (!pl.normal.allFinite() || !std::isfinite(pl.offset))
      out.add(name + ": normal " + vec(pl.normal) + " or offset " + num(pl.offset) + " is not finite");
    else if (!(pl.normal.norm() > 0.0))
      out.add(name + ": normal is zero");
    check_coefficients(out, name, pl.restitution, pl.friction);
  }
  for (size_t s = 0; s < model.spheres.size(); ++s) {
    const SphereCollider& sp = model.spheres[s];
    const std::string name = "sphere " + std::to_string(s);
    if (!sp.center.allFinite()) out.add(name + ": centre " + vec(sp.center) + " is not finite");
    if (!(sp.radius > 0.0) || !std::isfinite(sp.radius))
      out.add(name + ": radius " + num(sp.radius) + " is not positive and finite");
    check_coefficients(out, name, sp.restitution, sp.friction);
    check_motion_index(out, name, sp.motion, model);
  }
  for (size_t k = 0; k < model.meshes.size(); ++k) {
    const MeshCollider& mc = model.meshes[k];
    const std::string name = "mesh " + std::to_string(k) + " ('" + mc.file + "')";
    if (mc.triangles.empty()) out.add(name + ": has no triangles");
    if (!mc.vertices.allFinite()) out.add(name + ": a vertex is not finite");
    check_coefficients(out, name, mc.restitution, mc.friction);
    check_motion_index(out, name, mc.motion, model);
  }
  check_coefficients(out, "particle contact", model.particle_restitution, model.particle_friction);
  return out.take();
}

std::vector<ModelProblem> check_state(const Model& model, const State& state) {
  Problems out;
  const int n = model.particle_count();
  if (!std::isfinite(state.time)) out.add("time " + num(state.time) + " is not finite");
  if (state.step < 0) out.add("step " + std::to_string(state.step) + " is negative");
  const bool x_ok = state.x.rows() == n, v_ok = state.v.rows() == n;
  if (!x_ok) out.add("x has " + std::to_string(state.x.rows()) + " rows for " + std::to_string(n) + " particles");
  if (!v_ok) out.add("v has " + std::to_string(state.v.rows()) + " rows for " + std::to_string(n) + " particles");
  if (state.lambda.size() != model.constraints.size())
    out.add("lambda has " + std::to_string(state.lambda.size()) + " entries for " +
            std::to_string(model.constraints.size()) + " constraints");
  for (int i = 0; i < n; ++i) {
    if (x_ok && !state.x.row(i).allFinite())
      out.add("particle " + std::to_string(i) + ": position " + vec(state.x.row(i)) + " is not finite");
    if (v_ok && !state.v.row(i).allFinite())
      out.add("particle " + std::to_string(i) + ": velocity " + vec(state.v.row(i)) + " is not finite");
  }
  for (size_t c = 0; c < state.lambda.size(); ++c)
    if (!std::isfinite(state.lambda[c]))
      out.add("constraint " + std::to_string(c) + ": lambda " + num(state.lambda[c]) + " is not finite");
  return out.take();
}

}  // namespace pbdbench
