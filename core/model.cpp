#include "core/model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace pbdbench {

const char* to_string(ConstraintKind kind) {
  switch (kind) {
    case ConstraintKind::Distance: return "distance";
    case ConstraintKind::Volume: return "volume";
    case ConstraintKind::Bending: return "bending";
    case ConstraintKind::FemDeviatoric: return "fem_deviatoric";
    case ConstraintKind::FemHydrostatic: return "fem_hydrostatic";
    case ConstraintKind::FemStrainTriangle: return "fem_strain_triangle";
    case ConstraintKind::FemStrainTet: return "fem_strain_tet";
  }
  return "unknown";
}

const char* to_string(Material material) {
  switch (material) {
    case Material::StableNeoHookean: return "stable_neo_hookean";
    case Material::Corotated: return "corotated";
    case Material::StVK: return "stvk";
    case Material::Linear: return "linear";
  }
  return "unknown";
}

std::uint16_t Model::group_index(const std::string& group_name) {
  auto it = std::find(group_names.begin(), group_names.end(), group_name);
  if (it != group_names.end()) return static_cast<std::uint16_t>(it - group_names.begin());
  group_names.push_back(group_name);
  return static_cast<std::uint16_t>(group_names.size() - 1);
}

namespace {

// Orthonormal pair (u, v) perpendicular to the unit vector a, with u x v = a.
void perpendicular_pair(const Vec3& a, Vec3& u, Vec3& v) {
  const Vec3 helper = std::abs(a.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  u = a.cross(helper).normalized();
  v = a.cross(u);
}

}  // namespace

Vec3 motion_offset(const Motion& m, double t) {
  const double s = t - m.start;
  switch (m.kind) {
    case MotionKind::Static: return Vec3::Zero();
    case MotionKind::Linear: {
      const double active = std::clamp(t, m.start, std::max(m.start, m.stop)) - m.start;
      return m.velocity * active;
    }
    case MotionKind::Oscillate:
      if (s <= 0.0) return Vec3::Zero();
      return m.amplitude * std::sin(2.0 * std::numbers::pi * m.frequency * s);
    case MotionKind::Circle: {
      if (s <= 0.0) return Vec3::Zero();
      Vec3 u, v;
      perpendicular_pair(m.axis.normalized(), u, v);
      const double w = 2.0 * std::numbers::pi * m.frequency;
      return m.radius * (std::cos(w * s) - 1.0) * u + m.radius * std::sin(w * s) * v;
    }
  }
  return Vec3::Zero();
}

Vec3 motion_velocity(const Motion& m, double t) {
  const double s = t - m.start;
  switch (m.kind) {
    case MotionKind::Static: return Vec3::Zero();
    case MotionKind::Linear: return (t >= m.start && t < m.stop) ? m.velocity : Vec3::Zero();
    case MotionKind::Oscillate: {
      if (s <= 0.0) return Vec3::Zero();
      const double w = 2.0 * std::numbers::pi * m.frequency;
      return m.amplitude * w * std::cos(w * s);
    }
    case MotionKind::Circle: {
      if (s <= 0.0) return Vec3::Zero();
      Vec3 u, v;
      perpendicular_pair(m.axis.normalized(), u, v);
      const double w = 2.0 * std::numbers::pi * m.frequency;
      return m.radius * w * (-std::sin(w * s) * u + std::cos(w * s) * v);
    }
  }
  return Vec3::Zero();
}

Vec3 attachment_target(const Model& model, const Attachment& a, double t) {
  if (a.motion < 0) return a.anchor;
  return a.anchor + motion_offset(model.motions[static_cast<size_t>(a.motion)], t);
}

Vec3 sphere_center(const Model& model, const SphereCollider& s, double t) {
  if (s.motion < 0) return s.center;
  return s.center + motion_offset(model.motions[static_cast<size_t>(s.motion)], t);
}

Vec3 mesh_offset(const Model& model, const MeshCollider& mesh, double t) {
  if (mesh.motion < 0) return Vec3::Zero();
  return motion_offset(model.motions[static_cast<size_t>(mesh.motion)], t);
}

Vec3 up_direction(const Model& model) {
  const double g = model.gravity.norm();
  if (g == 0.0) return Vec3::UnitY();
  return -model.gravity / g;
}

}  // namespace pbdbench
