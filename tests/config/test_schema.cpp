// The schema tables: well-formed, defaults from their one source, bounds that agree with
// SolverOptions::validate(), and the helpers that read them.
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "config/internal.hpp"
#include "tests/config/helpers.hpp"

namespace pbdbench::config {
namespace {

bool numeric(Type t) {
  return t == Type::Int || t == Type::Float || t == Type::Vec3 || t == Type::FloatList ||
         t == Type::IntList;
}

// Each element of a default, as doubles (empty for non-numeric values).
std::vector<double> numbers(const Value& v) {
  if (const auto* i = std::get_if<std::int64_t>(&v)) return {static_cast<double>(*i)};
  if (const auto* d = std::get_if<double>(&v)) return {*d};
  if (const auto* l = std::get_if<std::vector<double>>(&v)) return *l;
  if (const auto* l = std::get_if<std::vector<std::int64_t>>(&v)) return {l->begin(), l->end()};
  return {};
}

bool matches_type(const KeySpec& k) {
  const Value& v = k.default_value;
  switch (k.type) {
    case Type::Bool: return std::holds_alternative<bool>(v);
    case Type::Int: return std::holds_alternative<std::int64_t>(v);
    case Type::Float: return std::holds_alternative<double>(v);
    case Type::String: return std::holds_alternative<std::string>(v);
    case Type::Vec3: return std::holds_alternative<std::vector<double>>(v) && std::get<std::vector<double>>(v).size() == 3;
    case Type::FloatList: return std::holds_alternative<std::vector<double>>(v);
    case Type::IntList: return std::holds_alternative<std::vector<std::int64_t>>(v);
    case Type::StringList: return std::holds_alternative<std::vector<std::string>>(v);
  }
  return false;
}

void check_table(const std::vector<KeySpec>& keys, const std::string& table) {
  std::set<std::string> seen;
  for (const KeySpec& k : keys) {
    SCOPED_TRACE(table + ": " + k.path);
    EXPECT_TRUE(seen.insert(k.path).second) << "duplicate key";
    EXPECT_FALSE(k.doc.empty());
    EXPECT_TRUE(matches_type(k)) << "default of the wrong type";
    if (numeric(k.type) && k.type != Type::IntList && k.type != Type::FloatList && k.type != Type::Int) {
      EXPECT_FALSE(k.units.empty()) << "a float key without units (write \"1\" for dimensionless)";
    }
    if (!numeric(k.type)) {
      EXPECT_EQ(k.min, -1e308);
      EXPECT_EQ(k.max, 1e308);
    }
    for (double x : numbers(k.default_value)) {
      EXPECT_TRUE(std::isfinite(x));
      EXPECT_TRUE(k.min_exclusive ? x > k.min : x >= k.min) << "default below the minimum";
      EXPECT_TRUE(k.max_exclusive ? x < k.max : x <= k.max) << "default above the maximum";
    }
    if (k.length) {
      const auto n = numbers(k.default_value).size();
      EXPECT_EQ(n, k.length);
    }
    if (!k.choices.empty()) {
      if (const auto* s = std::get_if<std::string>(&k.default_value)) {
        EXPECT_NE(std::find(k.choices.begin(), k.choices.end(), *s), k.choices.end());
      }
      if (const auto* l = std::get_if<std::vector<std::string>>(&k.default_value)) {
        for (const auto& s : *l) EXPECT_NE(std::find(k.choices.begin(), k.choices.end(), s), k.choices.end());
      }
    }
  }
}

TEST(Schema, TablesAreWellFormed) {
  check_table(common_keys(), "common");
  check_table(collider_keys(), "collider");
  for (const SceneKindInfo& kind : scene_kinds()) {
    check_table(kind.keys, kind.name);
    EXPECT_FALSE(kind.doc.empty());
    for (const KeySpec& k : kind.keys) {
      EXPECT_EQ(k.path.rfind("scene.", 0), 0u) << k.path;
      EXPECT_NE(k.path, "scene.kind");
      EXPECT_EQ(detail::find_key(common_keys(), k.path), nullptr) << k.path;
    }
  }
  for (const KeySpec& k : collider_keys()) {
    EXPECT_EQ(k.path.rfind("collider.", 0), 0u) << k.path;
    EXPECT_FALSE(detail::collider_key_types(k.path).empty()) << k.path;
  }
}

TEST(Schema, KindsAndTheirKeyCounts) {
  std::vector<std::string> names;
  for (const SceneKindInfo& k : scene_kinds()) names.push_back(k.name);
  EXPECT_EQ(names, (std::vector<std::string>{"particle", "spring", "pendulum", "chain", "cloth",
                                             "tet_block", "tri_block", "spheres", "mesh"}));
  const KeySpec* kind = detail::find_key(common_keys(), "scene.kind");
  ASSERT_NE(kind, nullptr);
  EXPECT_EQ(kind->choices, names);
}

TEST(Schema, DefaultsComeFromTheStructs) {
  const SolverOptions so;
  const ExplosionLimits lim;
  const RunOptions run;
  auto def = [](const std::string& path) { return detail::find_key(common_keys(), path)->default_value; };
  EXPECT_EQ(std::get<std::string>(def("solver.name")), so.name);
  EXPECT_EQ(std::get<std::int64_t>(def("solver.iterations")), so.iterations);
  EXPECT_EQ(std::get<std::int64_t>(def("solver.substeps")), so.substeps);
  EXPECT_EQ(std::get<std::string>(def("solver.order")), to_string(so.order));
  EXPECT_EQ(std::get<std::string>(def("solver.precision")), to_string(so.precision));
  EXPECT_EQ(std::get<double>(def("solver.seed.damping")), so.seed_damping);
  EXPECT_EQ(std::get<double>(def("solver.seed.reference_dt")), so.seed_reference_dt);
  EXPECT_EQ(std::get<double>(def("time.dt")), run.dt);
  EXPECT_EQ(std::get<double>(def("time.duration")), run.duration);
  EXPECT_EQ(std::get<std::int64_t>(def("output.frame_every")), run.frame_every);
  EXPECT_EQ(std::get<double>(def("limits.max_speed")), lim.max_speed);
  EXPECT_EQ(std::get<double>(def("limits.max_extent_ratio")), lim.max_extent_ratio);
  EXPECT_EQ(std::get<double>(def("limits.max_distance")), lim.max_distance);
  EXPECT_EQ(detail::find_key(common_keys(), "solver.seed.fixes")->choices, seed_departure_ids());

  // A configuration of defaults gives back the default structs.
  const Config c = load_text("", "defaults.toml");
  const SolverOptions from = solver_options(c);
  EXPECT_EQ(from.name, so.name);
  EXPECT_EQ(from.iterations, so.iterations);
  EXPECT_EQ(from.shuffle_seed, so.shuffle_seed);
  EXPECT_EQ(from.jacobi_relaxation, so.jacobi_relaxation);
  EXPECT_EQ(from.jacobi_averaging, so.jacobi_averaging);
  EXPECT_EQ(from.xpbd_residuals, so.xpbd_residuals);
  EXPECT_EQ(from.precision, so.precision);
  EXPECT_EQ(from.seed_restitution, so.seed_restitution);
  const RunOptions r = run_options(c);
  EXPECT_EQ(r.dt, run.dt);
  EXPECT_EQ(r.limits.max_distance, lim.max_distance);
}

TEST(Schema, ClothDefaultsMakeTheStandardCloth) {
  const SceneKindInfo* cloth = detail::find_kind("cloth");
  ASSERT_NE(cloth, nullptr);
  auto def = [&](const std::string& p) { return detail::find_key(cloth->keys, p)->default_value; };
  EXPECT_EQ(std::get<std::vector<std::int64_t>>(def("scene.resolution")), (std::vector<std::int64_t>{64, 64}));
  EXPECT_EQ(std::get<std::vector<double>>(def("scene.size")), (std::vector<double>{1.0, 1.0}));
  EXPECT_EQ(std::get<double>(def("scene.mass")), 1.0);
}

// Every solver key of the schema maps onto a SolverOptions field, and where the schema has a
// finite bound, SolverOptions::validate() draws the same line: a value just outside fails it, one
// just inside passes (both come from the option's row, solver_api/options.cpp). The schema's own
// validation is checked on the same values.
TEST(Schema, SolverBoundsAgreeWithValidate) {
  int bounds_checked = 0;
  for (const KeySpec& k : common_keys()) {
    if (k.path.rfind("solver.", 0) != 0) continue;
    SCOPED_TRACE(k.path);
    {
      SolverOptions o;
      EXPECT_NO_THROW(detail::set_solver_option(o, k.path, k.default_value));
      EXPECT_EQ(o.validate(), "");
    }
    if (k.type != Type::Int && k.type != Type::Float) continue;
    const bool is_int = k.type == Type::Int;
    auto value = [&](double x) -> Value {
      if (is_int) return static_cast<std::int64_t>(x);
      return x;
    };
    auto text = [&](double x) {
      return is_int ? std::to_string(static_cast<std::int64_t>(x)) : detail::format_double(x);
    };
    auto check = [&](double inside, double outside) {
      SolverOptions in, out;
      detail::set_solver_option(in, k.path, value(inside));
      detail::set_solver_option(out, k.path, value(outside));
      EXPECT_EQ(in.validate(), "") << "inside value " << text(inside);
      EXPECT_NE(out.validate(), "") << "outside value " << text(outside);
      EXPECT_NO_THROW((void)load_text("", "b.toml", testing::sets({k.path + "=" + text(inside)})))
          << text(inside);
      EXPECT_THROW((void)load_text("", "b.toml", testing::sets({k.path + "=" + text(outside)})), ConfigError)
          << text(outside);
      ++bounds_checked;
    };
    const double inf = std::numeric_limits<double>::infinity();
    if (k.min > -1e308) {
      if (k.path == "solver.shuffle_seed") {
        // An unsigned field: -1 cannot be represented, so only the schema guards the bound.
        EXPECT_THROW((void)load_text("", "b.toml", testing::sets({k.path + "=-1"})), ConfigError);
      } else if (is_int) {
        check(k.min_exclusive ? k.min + 1 : k.min, k.min_exclusive ? k.min : k.min - 1);
      } else {
        check(k.min_exclusive ? std::nextafter(k.min, inf) : k.min,
              k.min_exclusive ? k.min : std::nextafter(k.min, -inf));
      }
    }
    if (k.max < 1e308) {
      if (is_int) {
        check(k.max_exclusive ? k.max - 1 : k.max, k.max_exclusive ? k.max : k.max + 1);
      } else {
        check(k.max_exclusive ? std::nextafter(k.max, -inf) : k.max,
              k.max_exclusive ? k.max : std::nextafter(k.max, inf));
      }
    }
  }
  // Both bounds of iterations, substeps, threads, jacobi_relaxation, pbd.velocity_damping, seed.damping,
  // seed.restitution, ref.rtol, ref.max_steps, ref.max_newton, global.max_iterations,
  // global.regularization, global.cg_tolerance, global.cg_max_iterations, global.reuse_tolerance
  // and global.reuse_iterations; the minimum of
  // contact_margin, seed.reference_dt, seed.fast_speed, ref.atol, ref.atol_velocity,
  // global.tolerance, force.contact_stiffness, force.contact_damping, ref.barrier_distance,
  // ref.barrier_stiffness and ref.friction_velocity.
  EXPECT_EQ(bounds_checked, 43);
}

TEST(Schema, SetSolverOptionRefusesOtherPaths) {
  SolverOptions o;
  EXPECT_THROW(detail::set_solver_option(o, "time.dt", 0.1), std::invalid_argument);
  EXPECT_THROW(detail::set_solver_option(o, "solver.order", std::string("sideways")), std::invalid_argument);
  EXPECT_THROW(detail::set_solver_option(o, "solver.precision", std::string("half")), std::invalid_argument);
}

TEST(Schema, EditDistance) {
  EXPECT_EQ(detail::edit_distance("", ""), 0u);
  EXPECT_EQ(detail::edit_distance("abc", ""), 3u);
  EXPECT_EQ(detail::edit_distance("iteratons", "iterations"), 1u);
  EXPECT_EQ(detail::edit_distance("ab", "ba"), 1u);  // a transposition
  EXPECT_EQ(detail::edit_distance("kitten", "sitting"), 3u);
}

TEST(Schema, Suggestions) {
  const std::vector<std::string> keys = {"solver.iterations", "solver.substeps", "time.dt"};
  EXPECT_EQ(detail::suggest("solver.iteratons", keys), "solver.iterations");
  EXPECT_EQ(detail::suggest("solver.subtseps", keys), "solver.substeps");
  EXPECT_EQ(detail::suggest("iterations", keys), "solver.iterations");  // right key, wrong table
  EXPECT_EQ(detail::suggest("completely.different", keys), "");
  EXPECT_EQ(detail::suggest("x", keys), "");
}

TEST(Schema, FormatDoubleRoundTripsAndReadsAsAFloat) {
  for (double x : {0.0, 1.0, -2.0, 0.1, 1.0 / 60.0, 1e-8, 1e300, -9.81, 6.02214076e23, 5e-324}) {
    const std::string s = detail::format_double(x);
    EXPECT_EQ(std::strtod(s.c_str(), nullptr), x) << s;
    EXPECT_NE(s.find_first_of(".e"), std::string::npos) << s;
  }
  EXPECT_EQ(detail::format_double(1.0 / 60.0), "0.016666666666666666");
  EXPECT_EQ(detail::format_double(1.0), "1.0");
}

TEST(Schema, FormatValueIsToml) {
  EXPECT_EQ(detail::format_value(Value{std::string("a \"b\"\\\n")}), "\"a \\\"b\\\"\\\\\\n\"");
  EXPECT_EQ(detail::format_value(Value{std::vector<double>{0.0, -9.81, 0.0}}), "[0.0, -9.81, 0.0]");
  EXPECT_EQ(detail::format_value(Value{std::vector<std::int64_t>{}}), "[]");
  EXPECT_EQ(detail::format_value(Value{true}), "true");
}

TEST(Schema, BoundsText) {
  EXPECT_EQ(detail::format_bounds(*detail::find_key(common_keys(), "time.dt")), "(0, 1]");
  EXPECT_EQ(detail::format_bounds(*detail::find_key(common_keys(), "solver.iterations")), "[1, 100000]");
  EXPECT_EQ(detail::format_bounds(*detail::find_key(common_keys(), "solver.contact_margin")), ">= 0");
  EXPECT_EQ(detail::format_bounds(*detail::find_key(common_keys(), "limits.max_speed")), "> 0");
  EXPECT_EQ(detail::format_bounds(*detail::find_key(common_keys(), "gravity")), "");
}

}  // namespace
}  // namespace pbdbench::config
