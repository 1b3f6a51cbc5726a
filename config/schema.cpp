// The schema: every key a scenario file may hold, with its type, default, units, bounds and doc.
// Defaults of the solver, run and limit keys are read from the structs they fill
// (SolverOptions, RunOptions, ExplosionLimits), so each default has one source; geometry defaults
// of the scene kinds come from the generator specs (core/generators.hpp, core/mesh_io.hpp).
#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <system_error>

#include <fmt/format.h>

#include "config/config.hpp"
#include "config/internal.hpp"
#include "core/generators.hpp"
#include "core/mesh_io.hpp"

namespace pbdbench::config {

const char* to_string(Type type) {
  switch (type) {
    case Type::Bool: return "bool";
    case Type::Int: return "int";
    case Type::Float: return "float";
    case Type::String: return "string";
    case Type::Vec3: return "vec3";
    case Type::FloatList: return "float list";
    case Type::IntList: return "int list";
    case Type::StringList: return "string list";
  }
  return "unknown";
}

namespace {

// ---------------------------------------------------------------------------------------------
// Small constructors so that each table row reads as one line of data.
struct Range {
  double min = -1e308;
  double max = 1e308;
  bool min_exclusive = false;
  bool max_exclusive = false;
};
const Range kAny{};
// The world a scenario may place things in. Coordinates within 1e6 m keep a double's spacing
// below 1.2e-10 m, under every tolerance the harness uses (1e-8 m); speeds up to 1e6 m/s cross
// that world in a second; rotations up to 1e6 degrees (2,778 turns) keep their sines exact to
// 1e-11. A value beyond these is a typing error, and refusing it here names the key and line,
// where the scene builder would only see the degenerate triangles or NaN positions it makes.
const Range kCoordinate{-1e6, 1e6, false, false};      // m
const Range kSpeed{-1e6, 1e6, false, false};           // m/s
const Range kAngle{-1e6, 1e6, false, false};           // deg
const Range kAngularSpeed{-1e6, 1e6, false, false};    // rad/s
const Range kScale{0, 1e6, true, false};               // a uniform scale factor, 1
Range at_least(double v) { return {v, 1e308, false, false}; }
Range above(double v) { return {v, 1e308, true, false}; }
Range within(double lo, double hi) { return {lo, hi, false, false}; }
Range above_upto(double lo, double hi) { return {lo, hi, true, false}; }

KeySpec make(std::string path, Type type, Value def, std::string units, Range r, std::string doc) {
  KeySpec k;
  k.path = std::move(path);
  k.type = type;
  k.default_value = std::move(def);
  k.units = std::move(units);
  k.min = r.min;
  k.max = r.max;
  k.min_exclusive = r.min_exclusive;
  k.max_exclusive = r.max_exclusive;
  k.doc = std::move(doc);
  return k;
}

KeySpec real(std::string path, double def, std::string units, Range r, std::string doc) {
  return make(std::move(path), Type::Float, def, std::move(units), r, std::move(doc));
}
KeySpec integer(std::string path, std::int64_t def, Range r, std::string doc) {
  return make(std::move(path), Type::Int, def, "", r, std::move(doc));
}
KeySpec boolean(std::string path, bool def, std::string doc) {
  return make(std::move(path), Type::Bool, def, "", kAny, std::move(doc));
}
KeySpec text(std::string path, std::string def, std::vector<std::string> choices, std::string doc) {
  KeySpec k = make(std::move(path), Type::String, std::move(def), "", kAny, std::move(doc));
  k.choices = std::move(choices);
  return k;
}
KeySpec vec3(std::string path, const Vec3& def, std::string units, Range r, std::string doc) {
  return make(std::move(path), Type::Vec3, std::vector<double>{def.x(), def.y(), def.z()},
              std::move(units), r, std::move(doc));
}
KeySpec floats(std::string path, std::vector<double> def, std::size_t length, std::string units,
               Range r, std::string doc) {
  KeySpec k = make(std::move(path), Type::FloatList, std::move(def), std::move(units), r, std::move(doc));
  k.length = length;
  return k;
}
KeySpec ints(std::string path, std::vector<std::int64_t> def, std::size_t length, Range r,
             std::string doc) {
  KeySpec k = make(std::move(path), Type::IntList, std::move(def), "", r, std::move(doc));
  k.length = length;
  return k;
}
void append(std::vector<KeySpec>& to, std::vector<KeySpec> more) {
  for (KeySpec& k : more) to.push_back(std::move(k));
}

// "scene." + "compliance" -> "scene.compliance"; "scene.stretch" + "compliance" ->
// "scene.stretch_compliance".
std::string join(const std::string& prefix, const std::string& suffix) {
  if (!prefix.empty() && prefix.back() == '.') return prefix + suffix;
  return prefix + "_" + suffix;
}

// The material keys of one constraint group (ConstraintParams).
std::vector<KeySpec> group_keys(const std::string& prefix, const std::string& what,
                                const std::string& compliance_units, const ConstraintParams& def) {
  return {
      real(join(prefix, "compliance"), def.compliance, compliance_units, at_least(0),
           "XPBD compliance alpha of the " + what + " (inverse stiffness; 0 = rigid)"),
      real(join(prefix, "stiffness"), def.stiffness, "1", within(0, 1),
           "PBD's per-iteration stiffness k of the " + what + " (Mueller et al. 2007, sec. 3.3): "
           "read by pbd-seed, and by pbd only with solver.pbd.material = stiffness"),
      real(join(prefix, "damping"), def.damping, "s/(" + compliance_units + ")", at_least(0),
           "XPBD damping coefficient beta of the " + what +
               " (Macklin et al. 2016, eq. 26: gamma = alpha beta / h is dimensionless)"),
  };
}

// Young's modulus (default `youngs_modulus` Pa) and Poisson's ratio of an FEM material.
std::vector<KeySpec> modulus_keys(double youngs_modulus) {
  return {
      real("scene.youngs_modulus", youngs_modulus, "Pa", above(0),
           "Young's modulus E of the material (used when scene.material is not none)"),
      real("scene.poisson_ratio", 0.3, "1", within(0, 0.499),
           "Poisson's ratio nu of the material (used when scene.material is not none)"),
  };
}

// The FEM material keys of a tet body (core/fem.hpp, fem::add_fem_elements).
std::vector<KeySpec> fem_keys(const std::string& what) {
  std::vector<KeySpec> keys = {
      text("scene.material", "none", {"none", "stable_neo_hookean", "corotated", "stvk", "linear"},
           what + ": a hyperelastic FEM element per tet (core/fem.hpp): stable_neo_hookean (xpbd "
           "simulates it as two constraints per tet, Macklin and Mueller 2021), stvk (St Venant-"
           "Kirchhoff: the linear isotropic law on the Green strain) or linear (small-strain linear "
           "elasticity, not invariant under rotation), which xpbd simulates as one strain-vector "
           "constraint per tet with the compliance matrix of Macklin et al. 2016, sec. 6.3, "
           "corotated (reference solvers only), or none; pbd and pbd-seed refuse them all; needs "
           "positively oriented tets"),
  };
  append(keys, modulus_keys(1e6));
  return keys;
}

const std::vector<std::string> kMotionSuffixes = {"",       "_velocity",  "_amplitude", "_axis",
                                                  "_radius", "_frequency", "_start",     "_stop"};

// Scripted motion keys (Motion): `prefix` is "collider.motion" or "scene.pin_motion".
std::vector<KeySpec> motion_keys(const std::string& prefix, const std::string& what) {
  const Motion m;
  return {
      text(prefix, "static", {"static", "linear", "oscillate", "circle"},
           "scripted motion of " + what +
               ": static, linear (velocity), oscillate (amplitude, frequency), circle (axis, "
               "radius, frequency)"),
      vec3(prefix + "_velocity", m.velocity, "m/s", kSpeed,
           "velocity of a linear motion: offset = velocity (t - start) until stop"),
      vec3(prefix + "_amplitude", m.amplitude, "m", kCoordinate,
           "amplitude of an oscillation: offset = amplitude sin(2 pi frequency (t - start))"),
      vec3(prefix + "_axis", m.axis, "1", kAny,
           "axis of a circular motion (non-zero when the motion is circle; normalised)"),
      real(prefix + "_radius", m.radius, "m", at_least(0), "radius of a circular motion"),
      real(prefix + "_frequency", m.frequency, "Hz", at_least(0),
           "frequency of an oscillation or a circular motion"),
      real(prefix + "_start", m.start, "s", kAny, "time at which the motion begins"),
      real(prefix + "_stop", m.stop, "s", kAny,
           "time at which a linear motion stops and holds its offset"),
  };
}

std::vector<std::string> kind_names() {
  std::vector<std::string> names;
  for (const SceneKindInfo& k : scene_kinds()) names.push_back(k.name);
  return names;
}

// The [solver] keys, one per option row of solver_api/options.hpp: key, type, default (the
// row's value in SolverOptions{}), units, bounds, choices and doc all come from the row.
// solver.name and shadow.solver have no list of choices here: config/ stands below the
// catalogue (catalog/), and the harness refuses a name the catalogue does not have (or one that
// cannot run as a shadow) with the file and line that set it.
std::vector<KeySpec> solver_keys() {
  const SolverOptions defaults;
  std::vector<KeySpec> keys;
  for (const OptionRow& r : solver_option_rows()) {
    KeySpec k;
    k.path = r.key;
    switch (r.type) {
      case OptionType::Bool: k.type = Type::Bool; break;
      case OptionType::Int: k.type = Type::Int; break;
      case OptionType::Float: k.type = Type::Float; break;
      case OptionType::String: k.type = Type::String; break;
      case OptionType::StringList: k.type = Type::StringList; break;
    }
    k.default_value = std::visit([](const auto& v) -> Value { return v; }, r.get(defaults));
    k.units = r.units;
    k.min = r.bounds.min;
    k.max = r.bounds.max;
    k.min_exclusive = r.bounds.min_exclusive;
    k.max_exclusive = r.bounds.max_exclusive;
    k.choices = r.choices;
    k.doc = r.doc;
    // A shared [solver] key that not every family reads says which do (the [solver.<family>]
    // tables say it in their docs); describe hides it from the others.
    const bool family_table = std::count(r.key.begin(), r.key.end(), '.') > 1;
    if (!family_table && r.families != kAllFamilies) k.doc += " (read by " + families_text(r) + ")";
    keys.push_back(std::move(k));
  }
  return keys;
}

// ---------------------------------------------------------------------------------------------
// The scene kinds.

SceneKindInfo particle_kind() {
  return {"particle",
          "one free particle in flight (closed-form reference: ballistic motion)",
          {
              vec3("scene.position", Vec3::Zero(), "m", kCoordinate, "initial position"),
              vec3("scene.velocity", Vec3::Zero(), "m/s", kSpeed, "initial velocity"),
              real("scene.mass", 1.0, "kg", above(0), "mass of the particle"),
              real("scene.radius", 0.01, "m", above(0), "radius of the particle (contacts only)"),
          }};
}

SceneKindInfo spring_kind() {
  std::vector<KeySpec> keys = {
      vec3("scene.anchor", Vec3::Zero(), "m", kCoordinate, "position of the fixed anchor particle"),
      vec3("scene.direction", Vec3::UnitX(), "1", kAny,
           "direction from the anchor to the particle (non-zero; normalised)"),
      real("scene.rest_length", 1.0, "m", above(0), "rest length of the link"),
      real("scene.initial_length", 1.5, "m", above(0),
           "distance of the particle from the anchor at t = 0 (it starts at rest)"),
      real("scene.mass", 1.0, "kg", above(0), "mass of the moving particle"),
  };
  append(keys, group_keys("scene.", "link", "m/N", ConstraintParams{0.001, 1.0, 0.0}));
  keys.push_back(real("scene.radius", 0.01, "m", above(0), "radius of both particles (contacts only)"));
  return {"spring",
          "a particle on a compliant distance constraint to a fixed anchor (Macklin et al. 2016, "
          "fig. 2)",
          std::move(keys)};
}

SceneKindInfo pendulum_kind() {
  std::vector<KeySpec> keys = {
      vec3("scene.pivot", Vec3::Zero(), "m", kCoordinate, "position of the fixed pivot particle"),
      real("scene.length", 1.0, "m", above(0), "length of the rod"),
      real("scene.angle_deg", 30.0, "deg", within(-179.9, 179.9),
           "release angle from the downward vertical (the direction of gravity), in the plane of "
           "gravity and +x; the bob starts at rest"),
      real("scene.mass", 1.0, "kg", above(0), "mass of the bob"),
  };
  append(keys, group_keys("scene.", "rod", "m/N", ConstraintParams{0.0, 1.0, 0.0}));
  keys.push_back(real("scene.radius", 0.01, "m", above(0), "radius of the particles (contacts only)"));
  return {"pendulum", "a simple pendulum: one bob on a rod from a fixed pivot, released at rest",
          std::move(keys)};
}

SceneKindInfo chain_kind() {
  const ChainSpec c;
  std::vector<KeySpec> keys = {
      vec3("scene.top", c.top, "m", kCoordinate, "position of the first (top) particle"),
      integer("scene.links", c.links, within(1, 100000), "number of links (particles = links + 1)"),
      real("scene.link_length", c.link_length, "m", above(0), "rest length of each link"),
      real("scene.mass", c.mass, "kg", above(0), "mass of each particle"),
      real("scene.end_mass", c.end_mass, "kg", at_least(0),
           "mass of the last particle; 0 = the same as mass"),
      real("scene.angle_deg", 0.0, "deg", within(-180, 180),
           "direction of the chain from the top: 0 = hanging along gravity, 90 = horizontal along "
           "+x (in the plane of gravity and +x)"),
      boolean("scene.pin_top", c.pin_top, "pin the top particle"),
  };
  append(keys, group_keys("scene.", "links", "m/N", c.link));
  keys.push_back(real("scene.radius", c.radius, "m", above(0), "radius of each particle (contacts only)"));
  append(keys, motion_keys("scene.pin_motion", "the pinned top particle"));
  return {"chain", "a chain of particles joined by distance constraints, hanging from a pinned top",
          std::move(keys)};
}

const std::vector<std::string> kPinChoices = {"top_corners", "top_edge", "corners", "none"};
const std::vector<std::string> kFaceChoices = {"none",  "x_min", "x_max", "y_min",
                                               "y_max", "z_min", "z_max"};

SceneKindInfo cloth_kind() {
  const ClothSpec c;
  std::vector<KeySpec> keys = {
      ints("scene.resolution", {c.nx, c.ny}, 2, within(2, 10000),
           "particles along the two axes of the plane [nx, ny]; particle (i, j) has index j nx + i"),
      floats("scene.size", {c.width, c.height}, 2, "m", above(0),
             "width and height [w, h] along the two axes of the plane"),
      vec3("scene.origin", c.origin, "m", kCoordinate, "position of particle (0, 0)"),
      text("scene.plane", c.plane, {"xz", "xy"},
           "xz: horizontal, rows along +z; xy: vertical, row j = 0 on top, rows going down"),
      real("scene.mass", c.mass, "kg", above(0), "total mass, spread evenly over the particles"),
      real("scene.radius", c.radius, "m", above(0), "radius of each particle (contacts only)"),
      text("scene.pins", "top_corners", kPinChoices,
           "particles pinned: top_corners, top_edge (row j = 0), corners (all four), none"),
      ints("scene.pin_indices", {}, 0, at_least(0),
           "indices of extra particles to pin (each below nx ny)"),
  };
  // Defaults: a nearly inextensible cloth (under 1 % stretch under its own weight) with soft
  // bending; see scenarios/hanging_cloth.toml for the estimate.
  append(keys, group_keys("scene.stretch", "stretch constraints (grid edges)", "m/N",
                          ConstraintParams{1e-4, 1.0, 0.0}));
  keys.push_back(boolean("scene.shear", c.shear, "add shear constraints (both diagonals of each cell)"));
  append(keys, group_keys("scene.shear", "shear constraints (cell diagonals)", "m/N",
                          ConstraintParams{1e-3, 1.0, 0.0}));
  keys.push_back(boolean("scene.bending", c.bending, "add bending constraints"));
  keys.push_back(text("scene.bending_model", "dihedral", {"dihedral", "distance"},
                      "dihedral: angle across each interior edge; distance: particles two apart "
                      "along each grid line"));
  append(keys, group_keys("scene.bending", "bending constraints (rad^2/J when dihedral, m/N when distance)",
                          "rad^2/J or m/N", ConstraintParams{1.0, 1.0, 0.0}));
  keys.push_back(vec3("scene.velocity", Vec3::Zero(), "m/s", kSpeed,
                      "initial velocity of the free particles"));
  append(keys, motion_keys("scene.pin_motion", "the pinned particles"));
  return {"cloth", "a rectangular cloth of nx x ny particles with stretch, shear and bending",
          std::move(keys)};
}

SceneKindInfo tet_block_kind() {
  const TetBlockSpec t;
  std::vector<KeySpec> keys = {
      ints("scene.cells", {t.cells[0], t.cells[1], t.cells[2]}, 3, within(1, 1000),
           "hexahedral cells along x, y and z, each split into tetrahedra"),
      vec3("scene.size", t.size, "m", above(0), "extent of the block along x, y and z"),
      vec3("scene.origin", t.origin, "m", kCoordinate, "the block's minimum corner"),
      real("scene.density", t.density, "kg/m^3", above(0), "density; each tet's mass is lumped to its vertices"),
      real("scene.radius", t.radius, "m", above(0), "radius of each particle (contacts only)"),
      integer("scene.tets_per_cell", t.tets_per_cell, within(5, 6),
              "tetrahedra per cell: 5 (alternating) or 6 (sharing the main diagonal)"),
      text("scene.fixed", "none", kFaceChoices,
           "the face whose particles are pinned, or none; the opposite face is the observed tip"),
      boolean("scene.edges", t.edges, "add distance constraints on every tet edge"),
      boolean("scene.volumes", t.volumes, "add a volume constraint per tet"),
  };
  append(keys, fem_keys("the block's material"));
  // Defaults: rubber-like for 0.1 m cells (Young's modulus of the order of 1e7 Pa).
  append(keys, group_keys("scene.edge", "edge constraints", "m/N", ConstraintParams{1e-6, 1.0, 0.0}));
  append(keys, group_keys("scene.volume", "volume constraints", "m^5/N",
                          ConstraintParams{1e-10, 1.0, 0.0}));
  keys.push_back(vec3("scene.velocity", Vec3::Zero(), "m/s", kSpeed,
                      "initial velocity of the free particles"));
  append(keys, motion_keys("scene.pin_motion", "the pinned face"));
  return {"tet_block",
          "a box of tetrahedra with edge and volume constraints and/or FEM elements (a soft solid)",
          std::move(keys)};
}

SceneKindInfo tri_block_kind() {
  const TriBlockSpec t;
  std::vector<KeySpec> keys = {
      ints("scene.cells", {t.cells[0], t.cells[1]}, 2, within(1, 10000),
           "rectangular cells along x and y [cx, cy], each split into two triangles along a "
           "diagonal that alternates from cell to cell"),
      floats("scene.size", {t.size[0], t.size[1]}, 2, "m", above(0),
             "extent of the rectangle along x and y [w, h]; it lies in the xy plane"),
      vec3("scene.origin", t.origin, "m", kCoordinate, "the rectangle's minimum corner"),
      real("scene.density", t.density, "kg/m^3", above(0),
           "density; each triangle's mass (density x thickness x area) is lumped to its vertices"),
      real("scene.thickness", t.thickness, "m", above(0),
           "extent out of the plane that the mass and the elements' energy stand for (a 2D body "
           "per this much depth; the motion does not depend on it)"),
      real("scene.radius", t.radius, "m", above(0), "radius of each particle (contacts only)"),
      text("scene.fixed", "none", {"none", "x_min", "x_max", "y_min", "y_max"},
           "the edge whose particles are pinned, or none; the opposite edge is the observed tip"),
      boolean("scene.edges", t.edges, "add distance constraints on every triangle edge"),
      text("scene.material", "stvk", {"none", "stvk"},
           "a St Venant-Kirchhoff FEM element per triangle (core/fem.hpp: the 2 x 2 Green strain, "
           "plane strain in the plane), which xpbd simulates as one strain-vector constraint per "
           "triangle with the compliance matrix of Macklin et al. 2016, eqs. 27 and 28; or none"),
  };
  append(keys, modulus_keys(1e5));
  append(keys, group_keys("scene.edge", "edge constraints", "m/N", ConstraintParams{1e-6, 1.0, 0.0}));
  keys.push_back(vec3("scene.velocity", Vec3::Zero(), "m/s", kSpeed,
                      "initial velocity of the free particles"));
  append(keys, motion_keys("scene.pin_motion", "the pinned edge"));
  return {"tri_block",
          "a 2D rectangle of triangles in the xy plane with StVK FEM elements (plane strain) and/or "
          "edge constraints",
          std::move(keys)};
}

SceneKindInfo spheres_kind() {
  const PackedSpheresSpec p;
  return {"spheres",
          "packed spheres on a jittered cubic lattice (or a ring), with particle-particle contact",
          {
              text("scene.layout", "grid", {"grid", "ring"},
                   "grid: the cubic lattice of count spheres; ring: count[0] spheres (count[1] = "
                   "count[2] = 1) on a horizontal circle (normal to gravity) of radius "
                   "scene.ring_radius centred at scene.origin, the first on the side of +x; "
                   "neighbours may start overlapping"),
              ints("scene.count", {p.count[0], p.count[1], p.count[2]}, 3, within(1, 1000),
                   "spheres along x, y and z (ring: [count, 1, 1])"),
              real("scene.radius", p.radius, "m", above(0), "radius of each sphere"),
              real("scene.gap", p.gap, "1", at_least(0),
                   "space left between neighbours, as a fraction of the diameter"),
              vec3("scene.origin", p.origin, "m", kCoordinate,
                   "centre of the first sphere (minimum corner; grid) or of the circle (ring)"),
              real("scene.ring_radius", p.ring_radius, "m", above(0),
                   "ring: radius of the circle of centres (centre distance of neighbours "
                   "2 ring_radius sin(pi / count))"),
              real("scene.mass", p.mass, "kg", above(0), "mass of each sphere"),
              real("scene.jitter", p.jitter, "m", at_least(0),
                   "each centre displaced by a uniform random offset in [-jitter, jitter] per axis "
                   "(grid: below radius * gap)"),
              integer("scene.seed", static_cast<std::int64_t>(p.seed), at_least(0),
                      "seed of the jitter (deterministic)"),
              boolean("scene.particle_contact", true, "contacts between the spheres"),
              real("scene.restitution", 0.0, "1", within(0, 1),
                   "restitution e of sphere-sphere contacts"),
              real("scene.friction", 0.0, "1", at_least(0),
                   "Coulomb friction mu of sphere-sphere contacts"),
              vec3("scene.velocity", Vec3::Zero(), "m/s", kSpeed, "initial velocity of every sphere"),
          }};
}

SceneKindInfo mesh_kind() {
  const SurfaceBodySpec s;
  const TetBodySpec t;
  std::vector<KeySpec> keys = {
      text("scene.file", "", {},
           "mesh file, relative to the scenario file's directory: .obj (surface), .node with "
           ".ele (tetrahedra) or .msh (tetrahedra)"),
      text("scene.format", "auto", {"auto", "obj", "tetgen", "gmsh"},
           "file format; auto: from the extension (.obj, .node/.ele, .msh)"),
      real("scene.scale", 1.0, "1", kScale, "uniform scale applied to the vertices, before translate"),
      vec3("scene.translate", Vec3::Zero(), "m", kCoordinate, "offset added to the scaled vertices"),
      real("scene.mass", s.mass, "kg", above(0), "total mass of a surface mesh, spread evenly"),
      real("scene.density", t.density, "kg/m^3", above(0), "density of a tet mesh, lumped to the vertices"),
      real("scene.radius", s.radius, "m", above(0), "radius of each particle (contacts only)"),
      boolean("scene.bending", s.bending, "surface meshes: add dihedral bending constraints"),
      boolean("scene.reorient", t.reorient,
              "tet meshes: flip negatively oriented tets instead of refusing them"),
      boolean("scene.edges", t.edges, "tet meshes: add distance constraints on every tet edge"),
      boolean("scene.volumes", t.volumes, "tet meshes: add a volume constraint per tet"),
  };
  append(keys, fem_keys("tet meshes"));
  append(keys, group_keys("scene.stretch", "stretch constraints of a surface mesh", "m/N",
                          ConstraintParams{1e-4, 1.0, 0.0}));
  append(keys, group_keys("scene.bending", "bending constraints of a surface mesh", "rad^2/J",
                          ConstraintParams{1.0, 1.0, 0.0}));
  append(keys, group_keys("scene.edge", "edge constraints of a tet mesh", "m/N",
                          ConstraintParams{1e-6, 1.0, 0.0}));
  append(keys, group_keys("scene.volume", "volume constraints of a tet mesh", "m^5/N",
                          ConstraintParams{1e-10, 1.0, 0.0}));
  keys.push_back(ints("scene.pin_indices", {}, 0, at_least(0),
                      "indices of the vertices to pin (each below the vertex count)"));
  keys.push_back(vec3("scene.velocity", Vec3::Zero(), "m/s", kSpeed,
                      "initial velocity of the free particles"));
  append(keys, motion_keys("scene.pin_motion", "the pinned particles"));
  return {"mesh", "a surface (.obj) or tetrahedral (.node/.ele, .msh) mesh read from a file",
          std::move(keys)};
}

}  // namespace

const std::vector<SceneKindInfo>& scene_kinds() {
  static const std::vector<SceneKindInfo> kinds = {particle_kind(), spring_kind(),   pendulum_kind(),
                                                   chain_kind(),    cloth_kind(),    tet_block_kind(),
                                                   tri_block_kind(), spheres_kind(), mesh_kind()};
  return kinds;
}

const std::vector<KeySpec>& common_keys() {
  static const std::vector<KeySpec> keys = [] {
    const ExplosionLimits lim;
    const RunOptions run;
    const Model model;
    std::vector<KeySpec> keys{
        text("name", "", {}, "scenario name, used in run files and plots; default: the file's stem"),
        text("description", "", {}, "what the scenario shows, in one line"),
        vec3("gravity", model.gravity, "m/s^2", kAny, "gravitational acceleration"),
        text("scene.kind", "particle", kind_names(),
             "the kind of scene; it decides which other scene.* keys exist"),
        boolean("scene.surface_contact", false,
                "contact between the surfaces of bodies: every particle against the surface "
                "triangles (a cloth's, a tet body's boundary) of the other bodies ([[body]] "
                "entries and the scene's own), gap |x - q| - (r_p + the triangle's largest r); "
                "and their edges against each other, gap |P - Q| - (the larger r of each edge); "
                "pbd, xpbd and their variants (docs/scenarios.md)"),
        boolean("scene.self_contact", false,
                "contact within a body without tets (a cloth against itself): its particles "
                "against its own triangles, those touching the particle or its neighbours "
                "excepted, and its edges against its own edges, those sharing a vertex or a "
                "neighbour excepted; pbd, xpbd and their variants (docs/scenarios.md)"),
        real("scene.surface_friction", 0.0, "1", at_least(0),
             "Coulomb friction coefficient of the vertex-triangle and edge-edge contacts"),
        real("time.dt", run.dt, "s", above_upto(0, 1), "time step of one solver step"),
        real("time.duration", run.duration, "s", above_upto(0, 1e6),
             "simulated time; steps = round(duration / dt)"),
    };
    // The solver keys: one per option row (solver_api/options.hpp).
    append(keys, solver_keys());
    append(keys, {
        text("shadow.solver", "", {},
             "a global solver (global-cholmod, global-cg, global-ceres) run as a shadow: from the "
             "start of every k-th step it solves the converged step without touching the run, "
             "and the gap is logged (shadow_* series); empty: no shadow"),
        integer("shadow.every", 1, within(1, 1000000000), "the shadow solves every k-th step"),
        integer("output.frame_every", run.frame_every, within(0, 1000000000),
                "write positions and velocities every k steps (and the last step); 0: the steps "
                "nearest 1/60 s (a frame each 1/60 s of simulated time)"),
        real("limits.max_speed", lim.max_speed, "m/s", above(0),
             "a run has exploded when a particle is faster than this"),
        real("limits.max_extent_ratio", lim.max_extent_ratio, "1", above(0),
             "a run has exploded when its extent exceeds this times the initial extent (at least 1 mm)"),
        real("limits.max_distance", lim.max_distance, "m", above(0),
             "a run has exploded when a particle is farther than this from the origin"),
        // Scene defects for failure studies (config/scenes.cpp, apply_defects): applied to the
        // model and initial state of any scene kind after it is built. Defaults: no defect.
        ints("defects.zero_rest_length", {}, 0, at_least(0),
             "indices of distance constraints whose rest length becomes 0 (other kinds refused)"),
        real("defects.rest_scale", 1.0, "1", above(0),
             "rest lengths of the distance constraints of defects.rest_scale_constraints are "
             "multiplied by this (100: a cm/m unit mismatch)"),
        ints("defects.rest_scale_constraints", {}, 0, at_least(0),
             "indices of the distance constraints defects.rest_scale applies to; empty: every "
             "distance constraint"),
        ints("defects.inverse_mass_particles", {}, 0, at_least(0),
             "particles whose inverse mass is set to defects.inverse_mass_values (distinct); one "
             "given a non-zero value loses its pin, so that its inverse mass alone holds it"),
        floats("defects.inverse_mass_values", {}, 0, "1/kg", kAny,
               "inverse masses of defects.inverse_mass_particles, one each: any finite value, "
               "negative (-1 for a pinned particle) and huge (1e6) on purpose"),
        ints("defects.flip_tets", {}, 0, at_least(0),
             "tets whose volume constraints get their first two particles swapped, the rest "
             "volume kept positive (C = -V - V0 at rest: an inconsistently oriented listing)"),
        integer("defects.flip_every", 0, at_least(0),
                "also flip tets 0, k, 2k, ... with k = this; 0: none"),
        real("defects.initial_scale", 1.0, "1", above(0),
             "initial positions of the dynamic particles (inv_mass != 0) scaled by this about "
             "their centroid"),
        real("defects.initial_jitter", 0.0, "m", at_least(0),
             "each dynamic particle's initial position displaced by a seeded uniform random "
             "offset in [-jitter, jitter] per axis"),
        integer("defects.initial_seed", 0, at_least(0), "seed of defects.initial_jitter"),
        integer("relax.frames", 0, at_least(0),
                "relax the initial configuration over this many steps: the solver's rest values "
                "go linearly from the initial state's (C + rest) to the model's (fraction "
                "(k+1)/N at step k); pbd, xpbd and pbd-seed only; 0: none"),
    });
    return keys;
  }();
  return keys;
}

namespace {

// Collider keys and the collider types they apply to.
struct ColliderTable {
  std::vector<KeySpec> keys;
  std::map<std::string, std::vector<std::string>> types;
};

const ColliderTable& collider_table() {
  static const ColliderTable table = [] {
    const PlaneCollider plane;
    const SphereCollider sphere;
    const std::vector<std::string> all = {"plane", "sphere", "mesh"};
    const std::vector<std::string> planes = {"plane"};
    const std::vector<std::string> spheres = {"sphere"};
    const std::vector<std::string> meshes = {"mesh"};
    const std::vector<std::string> moving = {"sphere", "mesh"};
    ColliderTable t;
    auto add = [&t](KeySpec k, const std::vector<std::string>& types) {
      t.types[k.path] = types;
      t.keys.push_back(std::move(k));
    };
    add(text("collider.type", "plane", {"plane", "sphere", "mesh"},
             "plane (a half-space), sphere, or mesh (a triangle mesh from an OBJ file)"),
        all);
    add(vec3("collider.normal", plane.normal, "1", kAny,
             "plane normal, pointing into the allowed side (non-zero; stored as given, not "
             "normalised)"),
        planes);
    add(real("collider.offset", plane.offset, "m", kCoordinate,
             "the plane is normal . x + offset = 0 (metres for a unit normal)"),
        planes);
    add(vec3("collider.center", sphere.center, "m", kCoordinate, "centre of the sphere at t = 0"), spheres);
    add(real("collider.radius", sphere.radius, "m", above(0), "radius of the sphere"), spheres);
    add(text("collider.side", "outside", {"outside", "inside", "bowl"},
             "particles stay outside, inside, or inside the lower half (bowl: open above the centre)"),
        spheres);
    add(text("collider.file", "", {},
             "OBJ file of the mesh, relative to the scenario file's folder (polygons fan-"
             "triangulated; docs/scenarios.md, mesh colliders)"),
        meshes);
    add(vec3("collider.position", Vec3::Zero(), "m", kCoordinate,
             "translation of the mesh: x = position + R (scale x_file)"),
        meshes);
    add(vec3("collider.rotation", Vec3::Zero(), "deg", kAngle,
             "rotation R of the mesh: a rotation vector (axis times angle in degrees) about the "
             "file's origin"),
        meshes);
    add(real("collider.scale", 1.0, "1", kScale, "uniform scale of the mesh's vertices"), meshes);
    add(real("collider.restitution", plane.restitution, "1", within(0, 1),
             "restitution e of contacts with this collider"),
        all);
    add(real("collider.friction", plane.friction, "1", at_least(0),
             "Coulomb friction mu of contacts with this collider"),
        all);
    for (KeySpec& k : motion_keys("collider.motion", "the sphere or mesh (a translation)"))
      add(std::move(k), moving);
    return t;
  }();
  return table;
}

}  // namespace

const std::vector<KeySpec>& collider_keys() { return collider_table().keys; }

const std::vector<std::string>& body_kinds() {
  static const std::vector<std::string> kinds = {"chain", "cloth", "tet_block", "mesh"};
  return kinds;
}

const std::vector<KeySpec>& body_placement_keys() {
  static const std::vector<KeySpec> keys = {
      text("body.kind", "tet_block", body_kinds(),
           "the body's scene kind; its keys are that kind's scene keys, written without 'scene.'"),
      vec3("body.position", Vec3::Zero(), "m", kCoordinate,
           "translation added to every particle after the rotation"),
      vec3("body.rotation", Vec3::Zero(), "deg", kAngle,
           "rotation vector (axis times angle in degrees) about the body's centroid"),
      vec3("body.velocity", Vec3::Zero(), "m/s", kSpeed,
           "initial velocity of every dynamic particle (added to the kind's own)"),
      vec3("body.angular_velocity", Vec3::Zero(), "rad/s", kAngularSpeed,
           "initial angular velocity about the body's centroid (after the placement)"),
  };
  return keys;
}

namespace detail {

const KeySpec* find_key(const std::vector<KeySpec>& keys, const std::string& path) {
  for (const KeySpec& k : keys)
    if (k.path == path) return &k;
  return nullptr;
}

const SceneKindInfo* find_kind(const std::string& name) {
  for (const SceneKindInfo& k : scene_kinds())
    if (k.name == name) return &k;
  return nullptr;
}

const std::vector<std::string>& collider_key_types(const std::string& path) {
  static const std::vector<std::string> none;
  const auto& types = collider_table().types;
  auto it = types.find(path);
  return it == types.end() ? none : it->second;
}

bool collider_key_applies(const std::string& path, const std::string& type) {
  const auto& types = collider_key_types(path);
  return std::find(types.begin(), types.end(), type) != types.end();
}

std::vector<std::string> motion_key_paths(const std::string& prefix) {
  std::vector<std::string> paths;
  for (const std::string& s : kMotionSuffixes) paths.push_back(prefix + s);
  return paths;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[n][m];
}

namespace {
std::string last_component(const std::string& path) {
  const auto dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}
}  // namespace

std::string suggest(const std::string& word, const std::vector<std::string>& candidates) {
  // A typo: at most a third of the word's letters wrong (at least 1, at most 3).
  const std::size_t limit = std::clamp<std::size_t>(word.size() / 3, 1, 3);
  std::string best;
  std::size_t best_d = limit + 1;
  // The distance is at least the difference in length: only candidates within the limit are
  // compared, so that the search stays cheap whatever the word (a 1 MiB key is refused at once).
  auto far = [](std::size_t a, std::size_t b, std::size_t limit) { return (a > b ? a - b : b - a) > limit; };
  for (const std::string& c : candidates) {
    if (far(word.size(), c.size(), limit)) continue;
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  if (!best.empty()) return best;
  // The right key in the wrong table: compare the last components.
  const std::string tail = last_component(word);
  const std::size_t tail_limit = std::clamp<std::size_t>(tail.size() / 3, 0, 3);
  best_d = tail_limit + 1;
  for (const std::string& c : candidates) {
    const std::string c_tail = last_component(c);
    if (far(tail.size(), c_tail.size(), tail_limit)) continue;
    const std::size_t d = edit_distance(tail, c_tail);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  return best;
}

std::string format_double(double value) {
  char buf[64];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value);
  std::string s(buf, ec == std::errc() ? end : buf);
  if (s == "inf" || s == "-inf" || s == "nan" || s == "-nan") return s;
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}

namespace {
std::string quote(const std::string& s) {
  std::string out = "\"";
  for (char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (c < 0x20 || c == 0x7f)
          out += fmt::format("\\u{:04X}", static_cast<unsigned>(c));
        else
          out += ch;
    }
  }
  return out + "\"";
}

template <class T, class F>
std::string list(const std::vector<T>& v, F&& item) {
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i) out += ", ";
    out += item(v[i]);
  }
  return out + "]";
}
}  // namespace

std::string format_value(const Value& value) {
  struct Visitor {
    std::string operator()(bool b) const { return b ? "true" : "false"; }
    std::string operator()(std::int64_t i) const { return std::to_string(i); }
    std::string operator()(double d) const { return format_double(d); }
    std::string operator()(const std::string& s) const { return quote(s); }
    std::string operator()(const std::vector<double>& v) const { return list(v, format_double); }
    std::string operator()(const std::vector<std::int64_t>& v) const {
      return list(v, [](std::int64_t i) { return std::to_string(i); });
    }
    std::string operator()(const std::vector<std::string>& v) const { return list(v, quote); }
  };
  return std::visit(Visitor{}, value);
}

namespace {
std::string bound(double v, Type type) {
  if (type == Type::Int || type == Type::IntList) return fmt::format("{}", static_cast<long long>(v));
  return fmt::format("{}", v);
}
}  // namespace

std::string format_bounds(const KeySpec& k) {
  if (k.type == Type::Bool || k.type == Type::String || k.type == Type::StringList) return "";
  const bool has_min = k.min > -1e308, has_max = k.max < 1e308;
  if (has_min && has_max)
    return fmt::format("{}{}, {}{}", k.min_exclusive ? "(" : "[", bound(k.min, k.type),
                       bound(k.max, k.type), k.max_exclusive ? ")" : "]");
  if (has_min) return fmt::format("{} {}", k.min_exclusive ? ">" : ">=", bound(k.min, k.type));
  if (has_max) return fmt::format("{} {}", k.max_exclusive ? "<" : "<=", bound(k.max, k.type));
  return "";
}

std::string type_label(const KeySpec& k) {
  switch (k.type) {
    case Type::FloatList:
      return k.length ? fmt::format("list of {} floats", k.length) : "list of floats";
    case Type::IntList: return k.length ? fmt::format("list of {} ints", k.length) : "list of ints";
    case Type::StringList: return "list of strings";
    default: return to_string(k.type);
  }
}

}  // namespace detail

std::string suggest_name(const std::string& word, const std::vector<std::string>& candidates) {
  return detail::suggest(word, candidates);
}

}  // namespace pbdbench::config
