// build_scene: the Model and initial State of each scene kind, from a validated Config, through
// the generators of core/generators.hpp and the mesh readers of core/mesh_io.hpp. Whatever they or
// the model checks refuse becomes a ConfigError naming the responsible key.
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

#include "config/config.hpp"
#include "config/internal.hpp"
#include "core/fem.hpp"
#include "core/generators.hpp"
#include "core/mesh_io.hpp"
#include "core/model_checks.hpp"
#include "solvers/ordering.hpp"

namespace pbdbench::config {

namespace {

using EntryMap = std::map<std::string, Entry>;

// ---------------------------------------------------------------------------------------------
// Reading entries (of the Config or of one collider).
const Entry& entry(const EntryMap& m, const std::string& path) {
  auto it = m.find(path);
  if (it == m.end()) throw ConfigError(Source{}, path, "internal: no key '" + path + "' resolved");
  return it->second;
}
double real(const EntryMap& m, const std::string& path) {
  const Value& v = entry(m, path).value;
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  return std::get<double>(v);
}
std::int64_t whole(const EntryMap& m, const std::string& path) {
  return std::get<std::int64_t>(entry(m, path).value);
}
bool flag(const EntryMap& m, const std::string& path) { return std::get<bool>(entry(m, path).value); }
const std::string& word(const EntryMap& m, const std::string& path) {
  return std::get<std::string>(entry(m, path).value);
}
Vec3 vec(const EntryMap& m, const std::string& path) {
  const auto& v = std::get<std::vector<double>>(entry(m, path).value);
  return Vec3(v[0], v[1], v[2]);
}

std::string join(const std::string& prefix, const std::string& suffix) {
  if (!prefix.empty() && prefix.back() == '.') return prefix + suffix;
  return prefix + "_" + suffix;
}

ConstraintParams params(const EntryMap& m, const std::string& prefix) {
  ConstraintParams p;
  p.compliance = real(m, join(prefix, "compliance"));
  p.stiffness = real(m, join(prefix, "stiffness"));
  p.damping = real(m, join(prefix, "damping"));
  return p;
}

Motion read_motion(const EntryMap& m, const std::string& prefix) {
  const std::vector<std::string> p = detail::motion_key_paths(prefix);
  Motion motion;
  const std::string& kind = word(m, p[0]);
  motion.kind = kind == "linear"      ? MotionKind::Linear
                : kind == "oscillate" ? MotionKind::Oscillate
                : kind == "circle"    ? MotionKind::Circle
                                      : MotionKind::Static;
  motion.velocity = vec(m, p[1]);
  motion.amplitude = vec(m, p[2]);
  const Vec3 axis = vec(m, p[3]);
  motion.axis = axis.norm() > 0.0 ? Vec3(axis.normalized()) : Vec3::UnitY();
  motion.radius = real(m, p[4]);
  motion.frequency = real(m, p[5]);
  motion.start = real(m, p[6]);
  motion.stop = real(m, p[7]);
  return motion;
}

// The unit direction at angle_deg from the direction of gravity, turning towards +x (in the plane
// of gravity and +x). Without gravity "down" is -y.
Vec3 direction_from_angle(const Model& model, double angle_deg) {
  const Vec3 down = -up_direction(model);
  Vec3 side = Vec3::UnitX() - Vec3::UnitX().dot(down) * down;
  if (side.norm() < 1e-9) side = Vec3::UnitZ() - Vec3::UnitZ().dot(down) * down;  // gravity along x
  side.normalize();
  const double a = angle_deg * std::numbers::pi / 180.0;
  return (std::cos(a) * down + std::sin(a) * side).normalized();
}

// ---------------------------------------------------------------------------------------------
class SceneBuilder {
 public:
  explicit SceneBuilder(const Config& config) : c_(config), m_(config.entries) {
    kind_ = config.get_string("scene.kind");
    model_.name = config.scenario_name;
    model_.gravity = config.get_vec3("gravity");
    if (kind_ == "mesh") {
      responsible_key_ = "scene.file";
      responsible_ = source_or_file(config.at("scene.file").source);
    } else {
      responsible_key_ = "scene";
      responsible_ = source_or_file(config.at("scene.kind").source);
    }
  }

  Scene build() {
    try {
      if (kind_ == "particle") particle();
      else if (kind_ == "spring") spring();
      else if (kind_ == "pendulum") pendulum();
      else if (kind_ == "chain") chain();
      else if (kind_ == "cloth") cloth();
      else if (kind_ == "tet_block") tet_block();
      else if (kind_ == "tri_block") tri_block();
      else if (kind_ == "spheres") spheres();
      else if (kind_ == "mesh") mesh();
      else throw ConfigError(responsible_, "scene.kind", "scene.kind = '" + kind_ + "' is not a scene kind");
    } catch (const MeshError& e) {
      throw ConfigError(responsible_, responsible_key_,
                        fmt::format("scene.file = '{}': {}", c_.get_string("scene.file"), e.what()));
    } catch (const std::invalid_argument& e) {
      throw ConfigError(responsible_, responsible_key_,
                        fmt::format("the {} scene cannot be built: {}", kind_, e.what()));
    }
    colliders();

    Scene scene;
    scene.initial = rest_state(model_);
    // Initial velocities: the scene's for free particles, the motion's for driven ones.
    if (velocity_) {
      for (int i = 0; i < model_.particle_count(); ++i)
        if (model_.inv_mass[static_cast<std::size_t>(i)] > 0.0) scene.initial.v.row(i) = velocity_->transpose();
    }
    for (const Attachment& a : model_.attachments)
      if (a.motion >= 0)
        scene.initial.v.row(a.particle) =
            motion_velocity(model_.motions[static_cast<std::size_t>(a.motion)], 0.0).transpose();
    for (const auto& [particle, x] : initial_positions_) scene.initial.x.row(particle) = x.transpose();

    const std::vector<int> free_inverse_mass = apply_defects(scene.initial);
    check(check_model(model_, free_inverse_mass), "model");
    check(check_state(model_, scene.initial), "initial state");
    scene.model = std::move(model_);
    return scene;
  }

 private:
  Source source_or_file(const Source& s) const {
    return s.file.empty() ? Source{c_.file.string(), 0} : s;
  }

  [[noreturn]] void refuse(const std::string& key, const std::string& message) const {
    throw ConfigError(source_or_file(c_.at(key).source), key, message);
  }

  void check(const std::vector<ModelProblem>& problems, const char* what) const {
    if (problems.empty()) return;
    std::string list;
    const std::size_t shown = std::min<std::size_t>(problems.size(), 5);
    for (std::size_t i = 0; i < shown; ++i) list += (i ? "; " : "") + problems[i].what;
    if (problems.size() > shown) list += fmt::format("; and {} more", problems.size() - shown);
    std::string subject = kind_ == "mesh"
                              ? fmt::format("scene.file = '{}'", c_.get_string("scene.file"))
                              : fmt::format("the {} scene", kind_);
    throw ConfigError(responsible_, responsible_key_,
                      fmt::format("{}: the {} is unsound: {}", subject, what, list));
  }

  // Pins `particles` (model indices) and drives them with the scene's pin motion, if any.
  void pin(const std::vector<int>& particles) {
    const int motion = pin_motion(!particles.empty());
    std::set<int> attached;
    for (Attachment& a : model_.attachments) {
      attached.insert(a.particle);
      if (std::find(particles.begin(), particles.end(), a.particle) != particles.end()) a.motion = motion;
    }
    for (int p : particles) {
      if (attached.count(p)) continue;
      attached.insert(p);
      model_.inv_mass[static_cast<std::size_t>(p)] = 0.0;
      Attachment a;
      a.particle = p;
      a.anchor = model_.rest_positions.row(p).transpose();
      a.motion = motion;
      model_.attachments.push_back(a);
    }
  }

  // The index of the pin motion in model.motions, or -1 when static.
  int pin_motion(bool have_pins) {
    if (!m_.count("scene.pin_motion") || word(m_, "scene.pin_motion") == "static") return -1;
    if (!have_pins)
      refuse("scene.pin_motion", fmt::format("scene.pin_motion = '{}' drives the pinned particles, "
                                             "but this scene pins none",
                                             word(m_, "scene.pin_motion")));
    model_.motions.push_back(read_motion(m_, "scene.pin_motion"));
    return static_cast<int>(model_.motions.size()) - 1;
  }

  // Indices of scene.pin_indices, each checked against the particle count.
  std::vector<int> pin_indices(int count) const {
    std::vector<int> out;
    const auto& list = std::get<std::vector<std::int64_t>>(c_.at("scene.pin_indices").value);
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (list[i] >= count)
        refuse("scene.pin_indices",
               fmt::format("scene.pin_indices[{}] = {} is out of range: the scene has {} particles "
                           "(indices 0 to {})",
                           i, list[i], count, count - 1));
      out.push_back(static_cast<int>(list[i]));
    }
    return out;
  }

  void particle() {
    add_particle(model_, vec(m_, "scene.position"), real(m_, "scene.mass"), real(m_, "scene.radius"));
    velocity_ = vec(m_, "scene.velocity");
  }

  void spring() {
    const Vec3 direction = vec(m_, "scene.direction").normalized();
    ChainSpec s;
    s.links = 1;
    s.link_length = real(m_, "scene.rest_length");
    s.top = vec(m_, "scene.anchor");
    s.direction = direction;
    s.mass = real(m_, "scene.mass");
    s.end_mass = 0.0;
    s.radius = real(m_, "scene.radius");
    s.pin_top = true;
    s.link = params(m_, "scene.");
    const ParticleRange r = add_chain(model_, s);
    initial_positions_.emplace_back(r.begin + 1, s.top + real(m_, "scene.initial_length") * direction);
  }

  void pendulum() {
    ChainSpec s;
    s.links = 1;
    s.link_length = real(m_, "scene.length");
    s.top = vec(m_, "scene.pivot");
    s.direction = direction_from_angle(model_, real(m_, "scene.angle_deg"));
    s.mass = real(m_, "scene.mass");
    s.end_mass = 0.0;
    s.radius = real(m_, "scene.radius");
    s.pin_top = true;
    s.link = params(m_, "scene.");
    const ParticleRange r = add_chain(model_, s);
    model_.observables.bob = r.begin + 1;
    model_.observables.pivot = s.top;
  }

  void chain() {
    ChainSpec s;
    s.links = static_cast<int>(whole(m_, "scene.links"));
    s.link_length = real(m_, "scene.link_length");
    s.top = vec(m_, "scene.top");
    s.direction = direction_from_angle(model_, real(m_, "scene.angle_deg"));
    s.mass = real(m_, "scene.mass");
    s.end_mass = real(m_, "scene.end_mass");
    s.radius = real(m_, "scene.radius");
    s.pin_top = flag(m_, "scene.pin_top");
    s.link = params(m_, "scene.");
    const ParticleRange r = add_chain(model_, s);
    pin(s.pin_top ? std::vector<int>{r.begin} : std::vector<int>{});
  }

  void cloth() {
    const auto& res = std::get<std::vector<std::int64_t>>(c_.at("scene.resolution").value);
    const auto& size = c_.get_floats("scene.size");
    ClothSpec s;
    s.nx = static_cast<int>(res[0]);
    s.ny = static_cast<int>(res[1]);
    if (res[0] * res[1] > 10'000'000)
      refuse("scene.resolution", fmt::format("scene.resolution = [{}, {}] makes {} particles; at most "
                                             "10000000 are allowed",
                                             res[0], res[1], res[0] * res[1]));
    s.width = size[0];
    s.height = size[1];
    s.origin = vec(m_, "scene.origin");
    s.plane = word(m_, "scene.plane");
    s.mass = real(m_, "scene.mass");
    s.radius = real(m_, "scene.radius");
    s.shear = flag(m_, "scene.shear");
    s.bending = flag(m_, "scene.bending");
    s.bending_model = word(m_, "scene.bending_model") == "distance" ? BendingModel::Distance
                                                                     : BendingModel::Dihedral;
    s.stretch = params(m_, "scene.stretch");
    s.shear_params = params(m_, "scene.shear");
    s.bending_params = params(m_, "scene.bending");
    const ParticleRange r = add_cloth(model_, s);
    const int nx = s.nx, ny = s.ny;
    auto id = [&](int i, int j) { return r.begin + j * nx + i; };
    std::vector<int> pins;
    const std::string& which = word(m_, "scene.pins");
    if (which == "top_corners") pins = {id(0, 0), id(nx - 1, 0)};
    else if (which == "top_edge")
      for (int i = 0; i < nx; ++i) pins.push_back(id(i, 0));
    else if (which == "corners")
      pins = {id(0, 0), id(nx - 1, 0), id(0, ny - 1), id(nx - 1, ny - 1)};
    for (int p : pin_indices(r.size())) pins.push_back(r.begin + p);
    pin(pins);
    velocity_ = vec(m_, "scene.velocity");
  }

  // scene.fixed of a box (tet_block) or rectangle (tri_block) spanning `extent` from `origin`:
  // the particles of r on that face or edge are pinned, those on the opposite one are the tip (a
  // beam's free end, Model::observables).
  void fix_side(const Vec3& origin, const Vec3& extent, const ParticleRange& r) {
    std::vector<int> pins;
    const std::string& side = word(m_, "scene.fixed");
    if (side != "none") {
      const int axis = side[0] - 'x';
      const bool at_max = side.substr(2) == "max";
      const double target = origin[axis] + (at_max ? extent[axis] : 0.0);
      const double opposite = origin[axis] + (at_max ? 0.0 : extent[axis]);
      const double tolerance = 1e-9 * extent.maxCoeff();  // the generators' vertices are exact up to rounding
      for (int p = r.begin; p < r.end; ++p) {
        if (std::abs(model_.rest_positions(p, axis) - target) <= tolerance) pins.push_back(p);
        if (std::abs(model_.rest_positions(p, axis) - opposite) <= tolerance) model_.observables.tip.push_back(p);
      }
    }
    pin(pins);
  }

  void tet_block() {
    const auto& cells = c_.get_ints("scene.cells");
    TetBlockSpec s;
    if (cells[0] * cells[1] * cells[2] > 2'000'000)
      refuse("scene.cells", fmt::format("scene.cells = [{}, {}, {}] makes {} cells; at most 2000000 "
                                        "are allowed",
                                        cells[0], cells[1], cells[2], cells[0] * cells[1] * cells[2]));
    s.cells = {static_cast<int>(cells[0]), static_cast<int>(cells[1]), static_cast<int>(cells[2])};
    s.size = vec(m_, "scene.size");
    s.origin = vec(m_, "scene.origin");
    s.density = real(m_, "scene.density");
    s.radius = real(m_, "scene.radius");
    s.tets_per_cell = static_cast<int>(whole(m_, "scene.tets_per_cell"));
    s.edges = flag(m_, "scene.edges");
    s.volumes = flag(m_, "scene.volumes");
    s.edge = params(m_, "scene.edge");
    s.volume = params(m_, "scene.volume");
    const std::size_t first_tet = model_.tets.size();
    const ParticleRange r = add_tet_block(model_, s);
    add_material(first_tet, "the tet_block scene");

    fix_side(s.origin, s.size, r);
    velocity_ = vec(m_, "scene.velocity");
  }

  void spheres() {
    const auto& count = c_.get_ints("scene.count");
    PackedSpheresSpec s;
    if (count[0] * count[1] * count[2] > 10'000'000)
      refuse("scene.count", fmt::format("scene.count = [{}, {}, {}] makes {} spheres; at most 10000000 "
                                        "are allowed",
                                        count[0], count[1], count[2], count[0] * count[1] * count[2]));
    s.count = {static_cast<int>(count[0]), static_cast<int>(count[1]), static_cast<int>(count[2])};
    s.radius = real(m_, "scene.radius");
    s.gap = real(m_, "scene.gap");
    s.origin = vec(m_, "scene.origin");
    s.mass = real(m_, "scene.mass");
    s.jitter = real(m_, "scene.jitter");
    s.seed = static_cast<std::uint64_t>(whole(m_, "scene.seed"));
    if (word(m_, "scene.layout") == "ring") {
      // count[0] spheres on a horizontal circle (normal to gravity) around scene.origin; they may
      // start overlapping, which is what the layout is for.
      if (count[1] != 1 || count[2] != 1)
        refuse("scene.count",
               fmt::format("scene.count = [{}, {}, {}]: the ring layout puts count[0] spheres on "
                           "its circle; count[1] and count[2] must be 1",
                           count[0], count[1], count[2]));
      s.layout = SpheresLayout::Ring;
      s.ring_radius = real(m_, "scene.ring_radius");
      s.up = up_direction(model_);
    } else if (!(s.jitter < s.radius * s.gap))
      refuse("scene.jitter",
             fmt::format("scene.jitter = {} m must be below radius * gap = {} m, so that neighbouring "
                         "spheres cannot start overlapping",
                         s.jitter, s.radius * s.gap));
    add_packed_spheres(model_, s);
    model_.particle_contact = flag(m_, "scene.particle_contact");
    model_.particle_restitution = real(m_, "scene.restitution");
    model_.particle_friction = real(m_, "scene.friction");
    velocity_ = vec(m_, "scene.velocity");
  }

  void mesh() {
    const std::string& name = word(m_, "scene.file");
    const std::filesystem::path path = c_.file.parent_path() / name;
    std::string format = word(m_, "scene.format");
    if (format == "auto") {
      const std::string ext = path.extension().string();
      if (ext == ".obj") format = "obj";
      else if (ext == ".node" || ext == ".ele") format = "tetgen";
      else if (ext == ".msh") format = "gmsh";
      else
        refuse("scene.file", fmt::format("scene.file = '{}': cannot tell the format from the "
                                         "extension '{}' (.obj, .node, .ele or .msh); set scene.format",
                                         name, ext));
    }
    const double scale = real(m_, "scene.scale");
    const Vec3 translate = vec(m_, "scene.translate");
    auto place = [&](Points& v) {
      for (Eigen::Index i = 0; i < v.rows(); ++i) v.row(i) = (scale * v.row(i).transpose() + translate).transpose();
    };
    ParticleRange r;
    if (format == "obj") {
      if (word(m_, "scene.material") != "none")
        refuse("scene.material",
               fmt::format("scene.material = '{}' needs a tet mesh (.node/.ele or .msh); scene.file "
                           "= '{}' is a surface mesh",
                           word(m_, "scene.material"), name));
      SurfaceMesh mesh = read_obj(path.string());
      place(mesh.vertices);
      SurfaceBodySpec s;
      s.mass = real(m_, "scene.mass");
      s.radius = real(m_, "scene.radius");
      s.bending = flag(m_, "scene.bending");
      s.stretch = params(m_, "scene.stretch");
      s.bending_params = params(m_, "scene.bending");
      r = add_surface_mesh(model_, mesh, s, path.string());
    } else {
      TetMesh mesh = format == "tetgen" ? read_tetgen(path.string()) : read_gmsh(path.string());
      place(mesh.vertices);
      TetBodySpec s;
      s.density = real(m_, "scene.density");
      s.radius = real(m_, "scene.radius");
      s.reorient = flag(m_, "scene.reorient");
      s.edges = flag(m_, "scene.edges");
      s.volumes = flag(m_, "scene.volumes");
      s.edge = params(m_, "scene.edge");
      s.volume = params(m_, "scene.volume");
      const std::size_t first_tet = model_.tets.size();
      r = add_tet_mesh(model_, mesh, s, path.string());
      add_material(first_tet, fmt::format("scene.file = '{}'", name),
                   s.reorient ? "" : " (scene.reorient = false keeps negatively oriented tets as "
                                     "they are; set it to true to flip them)");
    }
    std::vector<int> pins;
    for (int p : pin_indices(r.size())) pins.push_back(r.begin + p);
    pin(pins);
    velocity_ = vec(m_, "scene.velocity");
  }

  void tri_block() {
    const auto& cells = c_.get_ints("scene.cells");
    const auto& size = c_.get_floats("scene.size");
    if (cells[0] * cells[1] > 2'000'000)
      refuse("scene.cells", fmt::format("scene.cells = [{}, {}] makes {} cells; at most 2000000 are "
                                        "allowed",
                                        cells[0], cells[1], cells[0] * cells[1]));
    TriBlockSpec s;
    s.cells = {static_cast<int>(cells[0]), static_cast<int>(cells[1])};
    s.size = {size[0], size[1]};
    s.origin = vec(m_, "scene.origin");
    s.density = real(m_, "scene.density");
    s.thickness = real(m_, "scene.thickness");
    s.radius = real(m_, "scene.radius");
    s.edges = flag(m_, "scene.edges");
    s.edge = params(m_, "scene.edge");
    const std::size_t first_triangle = model_.triangles.size();
    const ParticleRange r = add_tri_block(model_, s);
    if (word(m_, "scene.material") == "stvk") {
      const std::vector<std::array<int, 3>> triangles(
          model_.triangles.begin() + static_cast<std::ptrdiff_t>(first_triangle), model_.triangles.end());
      try {
        fem::add_fem_triangles(model_, triangles, Material::StVK, real(m_, "scene.youngs_modulus"),
                               real(m_, "scene.poisson_ratio"), s.thickness);
      } catch (const std::invalid_argument& e) {
        refuse("scene.material", fmt::format("scene.material = 'stvk' cannot be built on the "
                                             "tri_block scene: {}",
                                             e.what()));
      }
    }
    fix_side(s.origin, Vec3(s.size[0], s.size[1], 0.0), r);
    velocity_ = vec(m_, "scene.velocity");
  }

  // scene.material: one FEM element per tet of the body just built (its tets are those from
  // first_tet on), with scene.youngs_modulus and scene.poisson_ratio (core/fem.hpp). A tet the
  // elements refuse (negatively oriented, degenerate) is refused naming scene.material.
  void add_material(std::size_t first_tet, const std::string& subject, const std::string& hint = "") {
    const std::string& name = word(m_, "scene.material");
    if (name == "none") return;
    const Material material = name == "corotated" ? Material::Corotated
                              : name == "stvk"    ? Material::StVK
                              : name == "linear"  ? Material::Linear
                                                  : Material::StableNeoHookean;
    const std::vector<std::array<int, 4>> tets(model_.tets.begin() + static_cast<std::ptrdiff_t>(first_tet),
                                               model_.tets.end());
    try {
      fem::add_fem_elements(model_, tets, material, real(m_, "scene.youngs_modulus"),
                            real(m_, "scene.poisson_ratio"));
    } catch (const std::invalid_argument& e) {
      refuse("scene.material", fmt::format("scene.material = '{}' cannot be built on {}: {}{}", name,
                                           subject, e.what(), hint));
    }
  }

  // ---------------------------------------------------------------------------------------------
  // [defects]: deliberate faults for failure studies, applied to the model and the initial state
  // of whatever scene kind was built. Returns the particles whose inverse mass a defect set (the
  // model checks accept any finite value for them).
  std::vector<int> apply_defects(State& initial) {
    // Rest lengths.
    const int m = model_.constraint_count();
    auto distance_indices = [&](const std::string& key) {
      std::vector<std::size_t> out;
      const auto& list = c_.get_ints(key);
      for (std::size_t i = 0; i < list.size(); ++i) {
        if (list[i] >= m)
          refuse(key, fmt::format("{}[{}] = {} is out of range: the scene has {} constraints", key, i,
                                  list[i], m));
        const Constraint& c = model_.constraints[static_cast<std::size_t>(list[i])];
        if (c.kind != ConstraintKind::Distance)
          refuse(key, fmt::format("{}[{}] = {}: constraint {} is a {} constraint, not a distance "
                                  "constraint",
                                  key, i, list[i], list[i], to_string(c.kind)));
        out.push_back(static_cast<std::size_t>(list[i]));
      }
      return out;
    };
    for (std::size_t j : distance_indices("defects.zero_rest_length")) model_.constraints[j].rest = 0.0;
    const double rest_scale = c_.get_double("defects.rest_scale");
    std::vector<std::size_t> scaled = distance_indices("defects.rest_scale_constraints");
    if (c_.get_ints("defects.rest_scale_constraints").empty())
      for (std::size_t j = 0; j < model_.constraints.size(); ++j)
        if (model_.constraints[j].kind == ConstraintKind::Distance) scaled.push_back(j);
    std::sort(scaled.begin(), scaled.end());
    scaled.erase(std::unique(scaled.begin(), scaled.end()), scaled.end());  // each scaled once
    if (rest_scale != 1.0)
      for (std::size_t j : scaled) model_.constraints[j].rest *= rest_scale;

    // Inverse masses.
    const int n = model_.particle_count();
    const auto& particles = c_.get_ints("defects.inverse_mass_particles");
    const auto& values = c_.get_floats("defects.inverse_mass_values");
    if (particles.size() != values.size())
      refuse(values.empty() ? "defects.inverse_mass_particles" : "defects.inverse_mass_values",
             fmt::format("defects.inverse_mass_values has {} values for the {} particles of "
                         "defects.inverse_mass_particles: give one value per particle",
                         values.size(), particles.size()));
    std::vector<int> free_inverse_mass;
    for (std::size_t i = 0; i < particles.size(); ++i) {
      if (particles[i] >= n)
        refuse("defects.inverse_mass_particles",
               fmt::format("defects.inverse_mass_particles[{}] = {} is out of range: the scene has {} "
                           "particles",
                           i, particles[i], n));
      const int p = static_cast<int>(particles[i]);
      if (std::find(free_inverse_mass.begin(), free_inverse_mass.end(), p) != free_inverse_mass.end())
        refuse("defects.inverse_mass_particles",
               fmt::format("defects.inverse_mass_particles[{}] = {} repeats a particle", i, p));
      free_inverse_mass.push_back(p);
      model_.inv_mass[static_cast<std::size_t>(p)] = values[i];
      // A pinned particle given a non-zero inverse mass loses its pin: its inverse mass alone
      // decides, as in a listing that pins by inv_mass = 0.
      if (values[i] != 0.0)
        std::erase_if(model_.attachments, [p](const Attachment& a) { return a.particle == p; });
    }

    // Tets with inconsistently oriented volume constraints.
    const auto& flip = c_.get_ints("defects.flip_tets");
    const std::int64_t every = c_.get_int("defects.flip_every");
    if (!flip.empty() || every > 0) {
      const std::string key = flip.empty() ? "defects.flip_every" : "defects.flip_tets";
      const std::size_t tets = model_.tets.size();
      if (tets == 0)
        refuse(key, fmt::format("{} flips tets, but the {} scene has none", key, kind_));
      std::set<std::size_t> chosen;
      for (std::size_t i = 0; i < flip.size(); ++i) {
        if (static_cast<std::size_t>(flip[i]) >= tets)
          refuse("defects.flip_tets", fmt::format("defects.flip_tets[{}] = {} is out of range: the "
                                                  "scene has {} tets",
                                                  i, flip[i], tets));
        chosen.insert(static_cast<std::size_t>(flip[i]));
      }
      if (every > 0)
        for (std::size_t t = 0; t < tets; t += static_cast<std::size_t>(every)) chosen.insert(t);
      // The volume constraints of each tet, found by their particle sets.
      std::map<std::array<int, 4>, std::vector<std::size_t>> volume_of;
      for (std::size_t j = 0; j < model_.constraints.size(); ++j) {
        const Constraint& c = model_.constraints[j];
        if (c.kind != ConstraintKind::Volume) continue;
        std::array<int, 4> k = c.particles;
        std::sort(k.begin(), k.end());
        volume_of[k].push_back(j);
      }
      for (std::size_t t : chosen) {
        std::array<int, 4> k = model_.tets[t];
        std::sort(k.begin(), k.end());
        const auto it = volume_of.find(k);
        if (it == volume_of.end())
          refuse(key, fmt::format("{}: tet {} has no volume constraint to flip (scene.volumes = "
                                  "false?)",
                                  key, t));
        for (std::size_t j : it->second) {
          Constraint& c = model_.constraints[j];
          std::swap(c.particles[0], c.particles[1]);
          c.rest = std::abs(c.rest);
        }
      }
    }

    // The initial state: scaled about the dynamic particles' centroid, then jittered.
    auto dynamic = [&](int i) { return model_.inv_mass[static_cast<std::size_t>(i)] != 0.0; };
    const double scale = c_.get_double("defects.initial_scale");
    if (scale != 1.0) {
      Vec3 centroid = Vec3::Zero();
      int count = 0;
      for (int i = 0; i < n; ++i)
        if (dynamic(i)) {
          centroid += initial.x.row(i).transpose();
          ++count;
        }
      if (count > 0) {
        centroid /= static_cast<double>(count);
        for (int i = 0; i < n; ++i)
          if (dynamic(i))
            initial.x.row(i) = (centroid + scale * (initial.x.row(i).transpose() - centroid)).transpose();
      }
    }
    const double jitter = c_.get_double("defects.initial_jitter");
    if (jitter > 0.0) {
      // One seeded generator for the whole state; a uniform double in [0, 1) from the top 53 bits
      // of each draw (portable, unlike std::uniform_real_distribution).
      std::mt19937_64 gen =
          sweep_generator(static_cast<std::uint64_t>(c_.get_int("defects.initial_seed")), 0, 0, 0);
      for (int i = 0; i < n; ++i) {
        if (!dynamic(i)) continue;
        for (int a = 0; a < 3; ++a) {
          const double u = static_cast<double>(gen() >> 11) * 0x1.0p-53;
          initial.x(i, a) += jitter * (2.0 * u - 1.0);
        }
      }
    }
    return free_inverse_mass;
  }

  // A [[collider]] of type mesh: the OBJ read, placed (x = position + R (scale x_file)), checked
  // and given its BVH. Whatever is wrong names the file's line and the collider's file key.
  MeshCollider mesh_collider(const EntryMap& c, std::size_t index) const {
    const std::string key = "collider." + std::to_string(index) + ".file";
    const Entry& file_entry = entry(c, "collider.file");
    const Source where = source_or_file(file_entry.source);
    const std::string& name = word(c, "collider.file");
    const std::filesystem::path path = c_.file.parent_path() / name;
    try {
      SurfaceMesh obj = read_obj(path.string());
      const double scale = real(c, "collider.scale");
      const Vec3 rv = vec(c, "collider.rotation") * (std::numbers::pi / 180.0);
      const Mat3 R = rv.norm() > 0.0 ? Mat3(Eigen::AngleAxisd(rv.norm(), rv.normalized()))
                                     : Mat3(Mat3::Identity());
      const Vec3 position = vec(c, "collider.position");
      for (Eigen::Index i = 0; i < obj.vertices.rows(); ++i)
        obj.vertices.row(i) = (position + R * (scale * obj.vertices.row(i).transpose())).transpose();
      const std::vector<int> lines = obj.triangle_lines;
      try {
        MeshCollider m = make_mesh_collider(std::move(obj.vertices), std::move(obj.triangles));
        m.file = name;
        return m;
      } catch (const MeshColliderError& e) {
        const int line = e.triangle() >= 0 && static_cast<std::size_t>(e.triangle()) < lines.size()
                             ? lines[static_cast<std::size_t>(e.triangle())]
                             : 0;
        throw MeshError(path.string(), line, e.what());
      }
    } catch (const MeshError& e) {
      throw ConfigError(where, key, fmt::format("{} = '{}': {}", key, name, e.what()));
    }
  }

  void colliders() {
    for (std::size_t index = 0; index < c_.colliders.size(); ++index) {
      const EntryMap& c = c_.colliders[index];
      if (word(c, "collider.type") == "mesh") {
        MeshCollider m = mesh_collider(c, index);
        m.restitution = real(c, "collider.restitution");
        m.friction = real(c, "collider.friction");
        if (word(c, "collider.motion") != "static") {
          model_.motions.push_back(read_motion(c, "collider.motion"));
          m.motion = static_cast<int>(model_.motions.size()) - 1;
        }
        model_.meshes.push_back(std::move(m));
      } else if (word(c, "collider.type") == "plane") {
        PlaneCollider p;
        p.normal = vec(c, "collider.normal");
        p.offset = real(c, "collider.offset");
        p.restitution = real(c, "collider.restitution");
        p.friction = real(c, "collider.friction");
        model_.planes.push_back(p);
      } else {
        SphereCollider s;
        s.center = vec(c, "collider.center");
        s.radius = real(c, "collider.radius");
        const std::string& side = word(c, "collider.side");
        s.side = side == "inside" ? SphereSide::Inside : side == "bowl" ? SphereSide::Bowl : SphereSide::Outside;
        s.restitution = real(c, "collider.restitution");
        s.friction = real(c, "collider.friction");
        if (word(c, "collider.motion") != "static") {
          model_.motions.push_back(read_motion(c, "collider.motion"));
          s.motion = static_cast<int>(model_.motions.size()) - 1;
        }
        model_.spheres.push_back(s);
      }
    }
  }

  const Config& c_;
  const EntryMap& m_;
  std::string kind_;
  std::string responsible_key_;
  Source responsible_;
  Model model_;
  std::optional<Vec3> velocity_;
  std::vector<std::pair<int, Vec3>> initial_positions_;
};


// ---------------------------------------------------------------------------------------------
// [[body]] entries: each is built as a scene of its kind from its own keys, placed (rotated about
// its centroid, translated), given its initial velocity, and appended to the scene's model with
// its indices shifted. Particle contact is switched on, so that the bodies (and the scene's own
// body) collide with each other, particle against particle.

// A ConfigError of a body's sub-scene, renamed: "scene.size" becomes "body.<i>.size".
[[noreturn]] void rethrow_for_body(const ConfigError& e, std::size_t index) {
  std::string message = e.what();
  const Source& s = e.source();
  const std::string prefix =
      s.file.empty() ? "" : (s.line > 0 ? s.file + ":" + std::to_string(s.line) + ": " : s.file + ": ");
  if (!prefix.empty() && message.rfind(prefix, 0) == 0) message = message.substr(prefix.size());
  std::string key = e.key();
  if (key.rfind("scene.", 0) == 0) key = key.substr(6);
  else if (key == "scene") key = "kind";
  throw ConfigError(s, "body." + std::to_string(index) + "." + key,
                    fmt::format("[[body]] entry {}: {}", index, message));
}

void append_body(const Config& config, std::size_t index, Scene& scene) {
  const std::map<std::string, Entry>& b = config.bodies[index];
  Config sub = config;
  sub.colliders.clear();
  sub.bodies.clear();
  for (auto it = sub.entries.begin(); it != sub.entries.end();)
    it = it->first.rfind("scene.", 0) == 0 ? sub.entries.erase(it) : std::next(it);
  for (const auto& [path, e] : b) {
    if (detail::find_key(body_placement_keys(), path) && path != "body.kind") continue;
    sub.entries["scene." + path.substr(5)] = e;
  }
  // A kind key that is also a placement key (velocity) keeps its kind's default: the placement
  // applies it.
  if (const SceneKindInfo* info = detail::find_kind(word(b, "body.kind")))
    for (const KeySpec& k : info->keys)
      if (!sub.entries.count(k.path)) sub.entries[k.path] = Entry{k.default_value, Source{}};
  Scene body;
  try {
    body = SceneBuilder(sub).build();
  } catch (const ConfigError& e) {
    rethrow_for_body(e, index);
  }
  Model& m = scene.model;
  const Model& bm = body.model;
  const int np = m.particle_count(), nb = bm.particle_count();
  const int motion0 = static_cast<int>(m.motions.size());
  const int element0 = static_cast<int>(m.elements.size());

  // Placement: x' = R (x - c) + c + position, c the centroid of the body's rest positions.
  const Vec3 position = vec(b, "body.position");
  const Vec3 rv = vec(b, "body.rotation") * (std::numbers::pi / 180.0);
  const Mat3 R = rv.norm() > 0.0 ? Mat3(Eigen::AngleAxisd(rv.norm(), rv.normalized())) : Mat3(Mat3::Identity());
  const Vec3 c = bm.rest_positions.colwise().mean().transpose();
  auto place = [&](const Vec3& x) { return Vec3(R * (x - c) + c + position); };
  const Vec3 v0 = vec(b, "body.velocity"), w0 = vec(b, "body.angular_velocity");
  const Vec3 c_placed = c + position;

  m.rest_positions.conservativeResize(np + nb, 3);
  State& st = scene.initial;
  st.x.conservativeResize(np + nb, 3);
  st.v.conservativeResize(np + nb, 3);
  for (int i = 0; i < nb; ++i) {
    m.rest_positions.row(np + i) = place(bm.rest_positions.row(i).transpose()).transpose();
    const Vec3 x = place(body.initial.x.row(i).transpose());
    st.x.row(np + i) = x.transpose();
    Vec3 v = R * body.initial.v.row(i).transpose();
    if (bm.inv_mass[static_cast<std::size_t>(i)] > 0.0) v += v0 + w0.cross(x - c_placed);
    st.v.row(np + i) = v.transpose();
    m.inv_mass.push_back(bm.inv_mass[static_cast<std::size_t>(i)]);
    m.radius.push_back(bm.radius[static_cast<std::size_t>(i)]);
    m.particle_body.push_back(static_cast<int>(index) + 1);
  }
  for (auto e : bm.edges) m.edges.push_back({e[0] + np, e[1] + np});
  for (auto t : bm.triangles) m.triangles.push_back({t[0] + np, t[1] + np, t[2] + np});
  for (auto t : bm.tets) m.tets.push_back({t[0] + np, t[1] + np, t[2] + np, t[3] + np});
  m.surface_closed = (m.triangles.size() == bm.triangles.size() || m.surface_closed) && bm.surface_closed;
  for (Constraint con : bm.constraints) {
    for (int k = 0; k < arity(con.kind); ++k) con.particles[static_cast<std::size_t>(k)] += np;
    if (con.element >= 0) con.element += element0;
    con.group = m.group_index(bm.group_names[con.group]);
    m.constraints.push_back(con);
  }
  for (FemElement el : bm.elements) {
    for (int k = 0; k < el.vertices; ++k) el.particles[static_cast<std::size_t>(k)] += np;
    // Dm' = R Dm, so Dm'^-1 = Dm^-1 R^T: the placed body is at rest (F = I), not rotated.
    el.rest_inverse = el.rest_inverse * R.transpose();
    m.elements.push_back(el);
  }
  for (const Motion& mo : bm.motions) m.motions.push_back(mo);
  for (Attachment a : bm.attachments) {
    a.particle += np;
    a.anchor = place(a.anchor);
    if (a.motion >= 0) a.motion += motion0;
    m.attachments.push_back(a);
  }
  m.particle_contact = true;
  st.lambda.resize(static_cast<std::size_t>(m.constraint_count()), 0.0);
}

}  // namespace

Scene build_scene(const Config& config) {
  Scene scene = SceneBuilder(config).build();
  scene.model.surface_contact = config.get_bool("scene.surface_contact");
  scene.model.self_contact = config.get_bool("scene.self_contact");
  scene.model.surface_friction = config.get_double("scene.surface_friction");
  if (config.bodies.empty()) return scene;
  scene.model.particle_body.assign(static_cast<std::size_t>(scene.model.particle_count()), 0);
  for (std::size_t i = 0; i < config.bodies.size(); ++i) append_body(config, i, scene);
  State fresh = rest_state(scene.model);  // every array of the state sized for the whole model
  fresh.x = scene.initial.x;
  fresh.v = scene.initial.v;
  scene.initial = fresh;
  const std::vector<ModelProblem> problems = check_model(scene.model, {});
  if (!problems.empty())
    throw ConfigError(config.bodies.front().at("body.kind").source, "body",
                      "the scene with its [[body]] entries is unsound: " + problems.front().what);
  return scene;
}

}  // namespace pbdbench::config
