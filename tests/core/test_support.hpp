// Helpers shared by the core tests: named tolerances, seeded random numbers with a portable
// mapping, finite differences, and temporary files.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>

#include "core/constraint_functions.hpp"
#include "core/types.hpp"

namespace pbdbench::test {

// ---------------------------------------------------------------------------------------------
// Tolerances. A comparison passes when |a - b| <= abs + rel * |b| (b: the reference value).

struct Tolerance {
  double abs;
  double rel;
};

// Central differences with step h on positions of order 1 m: truncation error ~ h^2 |C'''|
// (1e-12 for smooth configurations) plus round-off ~ eps |C| / h (1e-10). 1e-6 + 1e-5 |b| leaves
// room for the curvature of the bending angle near (but not at) its singular configurations.
inline constexpr double kFdStep = 1e-6;
inline constexpr Tolerance kFdTol{1e-6, 1e-5};

// Quantities computed two ways in double precision from data of order 1 (sums of a few dozen
// terms): a few hundred ulps.
inline constexpr Tolerance kRoundoff{1e-12, 1e-12};

inline bool near(double a, double b, Tolerance tol) {
  return std::abs(a - b) <= tol.abs + tol.rel * std::abs(b);
}

inline bool near(const Vec3& a, const Vec3& b, Tolerance tol) {
  return (a - b).norm() <= tol.abs + tol.rel * b.norm();
}

// ---------------------------------------------------------------------------------------------
// Seeded random numbers: the uniform mapping is ours (std::uniform_real_distribution is
// implementation-defined), so a configuration number means the same thing on every platform.

class Random {
 public:
  explicit Random(std::uint64_t seed) : rng_(seed) {}
  double uniform() { return static_cast<double>(rng_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  int integer(int lo, int hi) { return lo + static_cast<int>(uniform() * (hi - lo + 1)); }  // [lo, hi]
  Vec3 vec(double lo, double hi) { return Vec3(uniform(lo, hi), uniform(lo, hi), uniform(lo, hi)); }

 private:
  std::mt19937_64 rng_;
};

inline std::string str(const Vec3& v) {
  std::ostringstream s;
  s.precision(17);
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

// ---------------------------------------------------------------------------------------------
// Finite differences of a function of up to four points.

using Config4 = std::array<Vec3, 4>;

// Central-difference gradient of f with respect to point i.
inline Vec3 fd_gradient(const std::function<double(const Config4&)>& f, Config4 x, int i,
                        double h = kFdStep) {
  Vec3 g;
  for (int a = 0; a < 3; ++a) {
    const double x0 = x[static_cast<size_t>(i)][a];
    x[static_cast<size_t>(i)][a] = x0 + h;
    const double fp = f(x);
    x[static_cast<size_t>(i)][a] = x0 - h;
    const double fm = f(x);
    x[static_cast<size_t>(i)][a] = x0;
    g[a] = (fp - fm) / (2.0 * h);
  }
  return g;
}

// Compares every analytic gradient component with central differences; returns an empty string
// when they agree, else a description of the configuration and the mismatch.
inline std::string check_gradient(const std::function<ConstraintEval(const Config4&)>& eval,
                                  const Config4& x, int arity) {
  const ConstraintEval e = eval(x);
  const auto value = [&](const Config4& y) { return eval(y).C; };
  std::ostringstream out;
  out.precision(17);
  for (int i = 0; i < arity; ++i) {
    const Vec3 fd = fd_gradient(value, x, i);
    for (int a = 0; a < 3; ++a) {
      if (!near(e.grad[static_cast<size_t>(i)][a], fd[a], kFdTol)) {
        out << "grad[" << i << "][" << a << "] = " << e.grad[static_cast<size_t>(i)][a]
            << ", central difference " << fd[a] << "; configuration:";
        for (int k = 0; k < arity; ++k) out << " x" << k << " = " << str(x[static_cast<size_t>(k)]);
        return out.str();
      }
    }
  }
  return "";
}

// The two momentum properties of an internal constraint's gradients: sum_i grad_i = 0
// (translation invariance) and sum_i x_i x grad_i = 0 (rotation invariance). Returns an empty
// string when both hold to round-off relative to the size of the terms.
inline std::string check_momentum(const ConstraintEval& e, const Config4& x, int arity) {
  Vec3 force = Vec3::Zero(), torque = Vec3::Zero();
  double force_scale = 0.0, torque_scale = 0.0;
  for (int i = 0; i < arity; ++i) {
    const Vec3& g = e.grad[static_cast<size_t>(i)];
    const Vec3& p = x[static_cast<size_t>(i)];
    force += g;
    torque += p.cross(g);
    force_scale += g.norm();
    torque_scale += p.norm() * g.norm();
  }
  // Sums of a few terms: 1e-12 of the largest term's scale is a few hundred ulps.
  std::ostringstream out;
  out.precision(17);
  if (force.norm() > 1e-12 * force_scale) out << "sum of gradients " << str(force) << " is not zero";
  else if (torque.norm() > 1e-12 * torque_scale) out << "sum of x_i x grad_i " << str(torque) << " is not zero";
  else return "";
  out << "; configuration:";
  for (int k = 0; k < arity; ++k) out << " x" << k << " = " << str(x[static_cast<size_t>(k)]);
  return out.str();
}

// ---------------------------------------------------------------------------------------------
// Files.

inline std::filesystem::path mesh_dir() {
  return std::filesystem::path(PBDBENCH_SOURCE_DIR) / "scenarios" / "meshes";
}

// A fresh directory for the current test's temporary files, under the build tree.
inline std::filesystem::path temp_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::path(PBDBENCH_BINARY_DIR) / "tests" / "core" /
                                    "tmp" / (std::string(info->test_suite_name()) + "." + info->name());
  std::filesystem::create_directories(dir);
  return dir;
}

// Writes `text` to temp_dir()/name and returns the path.
inline std::string write_temp(const std::string& name, const std::string& text) {
  const std::filesystem::path p = temp_dir() / name;
  std::ofstream(p) << text;
  return p.string();
}

}  // namespace pbdbench::test
