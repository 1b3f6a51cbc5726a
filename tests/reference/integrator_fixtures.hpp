// Small hand-written MechanicalSystems with known solutions, for the integrator tests
// (test_first_order_system, test_ref_bdf, test_ref_fixed_step, test_ref_static), and helpers to
// build and run the catalog scenes.
#pragma once

#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "config/config.hpp"
#include "core/state.hpp"
#include "reference/mechanical_system.hpp"

namespace pbdbench::test {

// The dense n x n pattern (every entry), or only the diagonal.
inline SparsityPattern full_pattern(int n, bool dense = true) {
  SparsityPattern p;
  p.n = n;
  p.column_start.push_back(0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i)
      if (dense || i == j) p.row.push_back(i);
    p.column_start.push_back(p.nnz());
  }
  return p;
}

// M q'' = -K q - D u + g(t): constant K (N/m), D (N s/m), and g(t) = g0 + g1 sin(w t) (N),
// dense pattern.
class LinearSystem final : public MechanicalSystem {
 public:
  LinearSystem(Eigen::VectorXd mass, Eigen::MatrixXd K, Eigen::MatrixXd D, Eigen::VectorXd g0,
               Eigen::VectorXd g1 = {}, double w = 0.0)
      : mass_(std::move(mass)), K_(std::move(K)), D_(std::move(D)), g0_(std::move(g0)),
        g1_(g1.size() ? std::move(g1) : Eigen::VectorXd::Zero(mass_.size())), w_(w),
        pattern_(full_pattern(static_cast<int>(mass_.size()))) {}

  int dofs() const override { return static_cast<int>(mass_.size()); }
  const Eigen::VectorXd& mass() const override { return mass_; }
  void force(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
             Eigen::VectorXd& f) const override {
    f = -K_ * q - D_ * u + g0_ + g1_ * std::sin(w_ * t);
  }
  const SparsityPattern& pattern() const override { return pattern_; }
  void stiffness(double, const Eigen::VectorXd&, const Eigen::VectorXd&,
                 std::vector<double>& values) const override {
    dense_values(K_, values);
  }
  void damping(double, const Eigen::VectorXd&, const Eigen::VectorXd&,
               std::vector<double>& values) const override {
    dense_values(D_, values);
  }
  bool has_damping() const override { return D_.cwiseAbs().maxCoeff() > 0.0; }
  double potential(double t, const Eigen::VectorXd& q) const override {
    return 0.5 * q.dot(K_ * q) - q.dot(g0_ + g1_ * std::sin(w_ * t));
  }

 private:
  void dense_values(const Eigen::MatrixXd& A, std::vector<double>& values) const {
    values.resize(static_cast<size_t>(pattern_.nnz()));
    for (int j = 0; j < dofs(); ++j)
      for (auto p = pattern_.column_start[static_cast<size_t>(j)];
           p < pattern_.column_start[static_cast<size_t>(j) + 1]; ++p)
        values[static_cast<size_t>(p)] = A(pattern_.row[static_cast<size_t>(p)], j);
  }

  Eigen::VectorXd mass_;
  Eigen::MatrixXd K_, D_;
  Eigen::VectorXd g0_, g1_;
  double w_;
  SparsityPattern pattern_;
};

// One dof: m q'' = -k q (k = 1 / alpha).
inline LinearSystem oscillator(double m, double k) {
  return LinearSystem(Eigen::VectorXd::Constant(1, m), Eigen::MatrixXd::Constant(1, 1, k),
                      Eigen::MatrixXd::Zero(1, 1), Eigen::VectorXd::Zero(1));
}

// A nonlinear system on scalar dofs with a sparse pattern, exact Jacobians:
//   U = sum_e k_e/4 (d_e^2 - r_e)^2 (d_e = q_a - q_b) + sum_i (c_i/2 q_i^2 - a_i cos q_i)
//   f = -dU/dq + g_i sin(w t) - sum_e beta_e (u_a - u_b) (e_a - e_b) - gamma_i u_i - delta_i u_i^3
class RandomSystem final : public MechanicalSystem {
 public:
  struct Edge {
    int a, b;
    double k, r, beta;
  };

  RandomSystem(int n, unsigned seed, bool damped) : n_(n), damped_(damped) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    mass_.resize(n);
    c_.resize(n);
    a_.resize(n);
    g_.resize(n);
    gamma_.resize(n);
    delta_.resize(n);
    for (int i = 0; i < n; ++i) {
      mass_[i] = 0.5 + U(rng);
      c_[i] = 1.0 + 2.0 * U(rng);
      a_[i] = U(rng);
      g_[i] = U(rng) - 0.5;
      gamma_[i] = damped ? 0.3 * U(rng) : 0.0;
      delta_[i] = damped ? 0.2 * U(rng) : 0.0;
    }
    std::vector<std::vector<bool>> linked(static_cast<size_t>(n), std::vector<bool>(static_cast<size_t>(n), false));
    for (int i = 0; i + 1 < n; ++i) add_edge(i, i + 1, rng, linked);
    for (int extra = 0; extra < n; ++extra) {
      const int a = static_cast<int>(U(rng) * n) % n, b = static_cast<int>(U(rng) * n) % n;
      if (a != b && !linked[static_cast<size_t>(a)][static_cast<size_t>(b)]) add_edge(a, b, rng, linked);
    }
    pattern_.n = n;
    pattern_.column_start.push_back(0);
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i)
        if (i == j || linked[static_cast<size_t>(i)][static_cast<size_t>(j)]) pattern_.row.push_back(i);
      pattern_.column_start.push_back(pattern_.nnz());
    }
  }

  int dofs() const override { return n_; }
  const Eigen::VectorXd& mass() const override { return mass_; }
  const SparsityPattern& pattern() const override { return pattern_; }
  bool has_damping() const override { return damped_; }
  const std::vector<Edge>& edges() const { return edges_; }

  void force(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
             Eigen::VectorXd& f) const override {
    f.resize(n_);
    for (int i = 0; i < n_; ++i)
      f[i] = -c_[i] * q[i] - a_[i] * std::sin(q[i]) + g_[i] * std::sin(w_ * t) - gamma_[i] * u[i] -
             delta_[i] * u[i] * u[i] * u[i];
    for (const Edge& e : edges_) {
      const double d = q[e.a] - q[e.b];
      const double s = e.k * (d * d - e.r) * d;
      const double damp = damped_ ? e.beta * (u[e.a] - u[e.b]) : 0.0;
      f[e.a] -= s + damp;
      f[e.b] += s + damp;
    }
  }
  void stiffness(double, const Eigen::VectorXd& q, const Eigen::VectorXd&,
                 std::vector<double>& values) const override {
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n_, n_);
    for (int i = 0; i < n_; ++i) K(i, i) = c_[i] + a_[i] * std::cos(q[i]);
    for (const Edge& e : edges_) {
      const double d = q[e.a] - q[e.b];
      const double h = e.k * (3.0 * d * d - e.r);
      K(e.a, e.a) += h;
      K(e.b, e.b) += h;
      K(e.a, e.b) -= h;
      K(e.b, e.a) -= h;
    }
    to_values(K, values);
  }
  void damping(double, const Eigen::VectorXd&, const Eigen::VectorXd& u,
               std::vector<double>& values) const override {
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(n_, n_);
    for (int i = 0; i < n_; ++i) D(i, i) = gamma_[i] + 3.0 * delta_[i] * u[i] * u[i];
    if (damped_)
      for (const Edge& e : edges_) {
        D(e.a, e.a) += e.beta;
        D(e.b, e.b) += e.beta;
        D(e.a, e.b) -= e.beta;
        D(e.b, e.a) -= e.beta;
      }
    to_values(D, values);
  }
  double potential(double t, const Eigen::VectorXd& q) const override {
    double U = 0.0;
    for (int i = 0; i < n_; ++i)
      U += 0.5 * c_[i] * q[i] * q[i] - a_[i] * std::cos(q[i]) - g_[i] * std::sin(w_ * t) * q[i];
    for (const Edge& e : edges_) {
      const double d = q[e.a] - q[e.b];
      U += 0.25 * e.k * (d * d - e.r) * (d * d - e.r);
    }
    return U;
  }

 private:
  void add_edge(int a, int b, std::mt19937& rng, std::vector<std::vector<bool>>& linked) {
    std::uniform_real_distribution<double> U(0.0, 1.0);
    edges_.push_back({a, b, 0.5 + U(rng), 0.2 + U(rng), 0.1 + 0.4 * U(rng)});
    linked[static_cast<size_t>(a)][static_cast<size_t>(b)] = true;
    linked[static_cast<size_t>(b)][static_cast<size_t>(a)] = true;
  }
  void to_values(const Eigen::MatrixXd& A, std::vector<double>& values) const {
    values.resize(static_cast<size_t>(pattern_.nnz()));
    for (int j = 0; j < n_; ++j)
      for (auto p = pattern_.column_start[static_cast<size_t>(j)];
           p < pattern_.column_start[static_cast<size_t>(j) + 1]; ++p)
        values[static_cast<size_t>(p)] = A(pattern_.row[static_cast<size_t>(p)], j);
  }

  int n_;
  bool damped_;
  double w_ = 3.0;
  Eigen::VectorXd mass_, c_, a_, g_, gamma_, delta_;
  std::vector<Edge> edges_;
  SparsityPattern pattern_;
};

// A catalog scenario with overrides, as the runner would build it.
struct CatalogScene {
  Scene scene;
  SolverOptions options;
  config::Config config;
};

inline CatalogScene catalog(const std::string& name,
                            const std::vector<std::pair<std::string, std::string>>& overrides) {
  std::vector<config::Override> o;
  for (const auto& [k, v] : overrides) o.push_back({k, v});
  CatalogScene c{{}, {}, config::load(name, o)};
  c.scene = config::build_scene(c.config);
  c.options = config::solver_options(c.config);
  return c;
}

}  // namespace pbdbench::test
