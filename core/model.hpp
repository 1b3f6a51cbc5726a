// The immutable description of a scene: particles, topology, constraints, colliders and scripted
// motions. Nothing in here changes while a simulation runs; the mutable part is `State`
// (core/state.hpp). Every solver, every metric and the run-file writer read the same Model.
//
// Conventions
// - SI units throughout: metres, kilograms, seconds, radians.
// - Particle arrays are indexed by particle id 0..n-1; `Points` rows are particles.
// - A particle with inv_mass == 0 never moves under the solver: it is pinned, or kinematic when an
//   `Attachment` with a motion drives it.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/constraint_kind.hpp"
#include "core/mesh_collider.hpp"
#include "core/types.hpp"

namespace pbdbench {

// ---------------------------------------------------------------------------------------------
// Constraints that live for the whole run (bilateral, equality C(x) = 0): their kinds are in
// core/constraint_kind.hpp, their functions in core/constraint_functions.hpp.
struct Constraint {
  ConstraintKind kind = ConstraintKind::Distance;
  std::array<int, 4> particles{-1, -1, -1, -1};  // the first arity(kind) entries are used
  double rest = 0.0;        // rest value of the measured quantity: m, m^3 or rad (see kind)
  double compliance = 0.0;  // alpha, XPBD compliance: inverse stiffness in units of C^2/J
                            // (m/N for distance); 0 = rigid
  double stiffness = 1.0;   // k in [0, 1], PBD's dimensionless stiffness (Mueller 2007, sec. 3.3)
  double damping = 0.0;     // beta >= 0, XPBD damping coefficient (Macklin 2016, eq. 26), in
                            // s / (units of alpha), N s/m for distance: gamma = alpha beta / h
  std::uint16_t group = 0;  // index into Model::group_names: "stretch", "shear", "bending", ...
  int element = -1;         // FEM kinds: index into Model::elements; -1 otherwise
};

// ---------------------------------------------------------------------------------------------
// Hyperelastic FEM elements (linear tetrahedra, and linear triangles of the StVK material). Their
// energy densities are in core/fem.hpp.
enum class Material : std::uint8_t {
  StableNeoHookean,  // Psi = mu/2 (I_C - 3) + lambda_snh/2 (J - 1 - mu/lambda_snh)^2,
                     // lambda_snh = lambda + mu so that small strains obey linear elasticity
                     // (Smith et al. 2018 without the log term, as Macklin and Mueller 2021)
  Corotated,         // fixed corotated: Psi = mu |F - R|^2 + lambda/2 (J - 1)^2, F = R S
                     // (Stomakhin et al. 2012); its small-strain limit is linear elasticity
  StVK,              // St Venant-Kirchhoff: Psi = mu E : E + lambda/2 tr(E)^2, E = (F^T F - I)/2
                     // the Green strain (the linear isotropic law on the Green strain; Macklin et
                     // al. 2016, sec. 6.3). Tets, and triangles (2 x 2 E: plane strain)
  Linear,            // linear elasticity: Psi = mu e : e + lambda/2 tr(e)^2, e = (F + F^T)/2 - I
                     // the small strain; not invariant under rotation (tets only)
};

const char* to_string(Material material);  // "stable_neo_hookean", "corotated", "stvk", "linear"

struct FemElement {
  std::array<int, 4> particles{-1, -1, -1, -1};  // a triangle's fourth entry is -1
  int vertices = 4;                      // 4: a tet; 3: a triangle, a 2D element of the xy plane
  Mat3 rest_inverse = Mat3::Identity();  // Dm^-1, Dm = [X1-X0, X2-X0, X3-X0] at rest (1/m); a
                                         // triangle's is the 2 x 2 top-left block, Dm = the x and
                                         // y of the rest edges X1-X0, X2-X0
  double rest_volume = 0.0;              // m^3, |det Dm| / 6 > 0; a triangle's is its rest area
                                         // times its thickness
  Material material = Material::StableNeoHookean;
  double mu = 0.0;      // Pa, shear modulus E / (2 (1 + nu))
  double lambda = 0.0;  // Pa, Lame's first parameter of linear elasticity E nu / ((1+nu)(1-2nu))
};

// What the scene measures besides the generic metrics (metrics/metrics.hpp); empty when the
// scene kind has no such observable.
struct Observables {
  std::vector<int> tip;     // particles whose mean displacement is the tip displacement
                            // (a beam's free end)
  int bob = -1;             // the pendulum's bob, whose angle about `pivot` is logged
  Vec3 pivot = Vec3::Zero();  // m
};

// ---------------------------------------------------------------------------------------------
// Scripted motion: an offset added to a rest point, as a function of time.
enum class MotionKind : std::uint8_t {
  Static,     // offset = 0
  Linear,     // offset = velocity * (t - start), clamped to [start, stop]
  Oscillate,  // offset = amplitude * sin(2 pi frequency (t - start)), zero before start
  Circle,     // offset = radius * (cos(w s) - 1) * u + radius * sin(w s) * v, s = t - start,
              // w = 2 pi frequency; (u, v) an orthonormal pair perpendicular to `axis`
};

struct Motion {
  MotionKind kind = MotionKind::Static;
  Vec3 velocity = Vec3::Zero();   // m/s (Linear)
  Vec3 amplitude = Vec3::Zero();  // m (Oscillate)
  Vec3 axis = Vec3::UnitY();      // unit axis of rotation (Circle)
  double radius = 0.0;            // m (Circle)
  double frequency = 0.0;         // Hz (Oscillate, Circle)
  double start = 0.0;             // s, the motion begins here
  double stop = 1e300;            // s, the motion holds its offset from here (Linear)
};

// A particle whose position is prescribed: target(t) = anchor + offset(motion, t).
// The attached particle has inv_mass == 0. motion == -1 means a static pin.
struct Attachment {
  int particle = -1;
  Vec3 anchor = Vec3::Zero();  // m
  int motion = -1;             // index into Model::motions, or -1
};

// ---------------------------------------------------------------------------------------------
// Colliders. Contacts against them are inequality constraints C(x) >= 0 built each step
// (core/contacts.hpp).

// The half-space n . x + offset >= radius of the particle. The normal is stored as given by the
// scenario (it may be non-unit on purpose, to study what a listing does with it); every corrected
// solver and every metric uses the unit normal n / |n| and offset / |n|.
struct PlaneCollider {
  Vec3 normal = Vec3::UnitY();
  double offset = 0.0;       // m (for a unit normal); the plane is n . x + offset = 0
  double restitution = 0.0;  // e in [0, 1]
  double friction = 0.0;     // Coulomb coefficient mu >= 0
};

enum class SphereSide : std::uint8_t {
  Outside,  // particles stay outside:   |x - c| - (R + r) >= 0
  Inside,   // particles stay inside:    (R - r) - |x - c| >= 0
  Bowl,     // as Inside, but only for particles below the centre: (x - c) . up < 0, so the
            // top half is open. `up` is the unit vector opposite to gravity (or +y without
            // gravity).
};

struct SphereCollider {
  Vec3 center = Vec3::Zero();  // m, at t = 0
  double radius = 1.0;         // m
  SphereSide side = SphereSide::Outside;
  double restitution = 0.0;
  double friction = 0.0;
  int motion = -1;  // index into Model::motions, or -1 for a fixed sphere
};

// ---------------------------------------------------------------------------------------------
struct Model {
  std::string name;  // the scenario's name

  // Particles (n of them).
  Points rest_positions;          // (n x 3) m, the reference configuration (rest lengths etc.)
  std::vector<double> inv_mass;   // (n) 1/kg; 0 = pinned or kinematic
  std::vector<double> radius;     // (n) m, used by contacts only

  Vec3 gravity = Vec3(0.0, -9.81, 0.0);  // m/s^2

  // Topology (for output, plotting and volume metrics; constraints carry their own indices).
  std::vector<std::array<int, 2>> edges;      // (E x 2)
  std::vector<std::array<int, 3>> triangles;  // (T x 3) surface triangles, outward-facing when closed
  std::vector<std::array<int, 4>> tets;       // (K x 4) positively oriented (det[x1-x0,x2-x0,x3-x0] > 0)
                                              // unless a mesh was imported with reorient = false
  bool surface_closed = false;                // triangles form a closed, consistently oriented surface

  // Constraints (m of them), and the names of the groups they belong to.
  std::vector<Constraint> constraints;
  std::vector<std::string> group_names;  // e.g. {"stretch", "shear", "bending"}

  // Prescribed particles and the motions that drive them.
  std::vector<Attachment> attachments;
  std::vector<Motion> motions;

  // Colliders and particle-particle contact.
  std::vector<PlaneCollider> planes;
  std::vector<SphereCollider> spheres;
  std::vector<MeshCollider> meshes;     // triangle meshes (core/mesh_collider.hpp)
  bool particle_contact = false;        // contacts between particles not joined by a constraint
  double particle_restitution = 0.0;    // e for particle-particle contacts
  double particle_friction = 0.0;       // mu for particle-particle contacts
  // Contact between surfaces (core/surface_contact.hpp): particles against the triangles above,
  // and their edges against each other; e: particle_restitution.
  bool surface_contact = false;         // between bodies (particle_body), both moving
  bool self_contact = false;            // within a body without tets (a cloth against itself)
  bool edge_contact = true;             // with either: edge-edge as well as vertex-triangle
                                        // (false: vertex-triangle alone, for controls)
  double surface_friction = 0.0;        // mu for vertex-triangle and edge-edge contacts
  std::vector<int> particle_body;       // (n) 0: the scene's own body, i + 1: [[body]] entry i;
                                        // empty: one body

  // FEM elements (their XPBD form, for the stable neo-Hookean material, is a pair of FEM-kind
  // constraints per element in `constraints`).
  std::vector<FemElement> elements;

  Observables observables;

  int particle_count() const { return static_cast<int>(rest_positions.rows()); }
  int constraint_count() const { return static_cast<int>(constraints.size()); }

  // Index of a group name, adding it when absent.
  std::uint16_t group_index(const std::string& group_name);
};

// Offset of a motion at time t (m), and its time derivative (m/s).
Vec3 motion_offset(const Motion& motion, double t);
Vec3 motion_velocity(const Motion& motion, double t);

// Position of an attached particle at time t (m).
Vec3 attachment_target(const Model& model, const Attachment& attachment, double t);

// Centre of a sphere collider at time t (m).
Vec3 sphere_center(const Model& model, const SphereCollider& sphere, double t);

// Translation of a mesh collider at time t (m): its motion's offset, 0 for a static mesh.
Vec3 mesh_offset(const Model& model, const MeshCollider& mesh, double t);

// Unit "up" vector: -gravity / |gravity|, or +y when there is no gravity.
Vec3 up_direction(const Model& model);

}  // namespace pbdbench
