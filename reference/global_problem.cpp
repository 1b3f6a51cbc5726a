#include "reference/global_problem.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"

namespace pbdbench {

namespace {

using Mat12 = Eigen::Matrix<double, 12, 12>;

std::string constraint_label(const Model& model, int j) {
  const Constraint& c = model.constraints[static_cast<size_t>(j)];
  std::string group = c.group < model.group_names.size() ? model.group_names[c.group] : "";
  return "constraint " + std::to_string(j) + " (" + to_string(c.kind) +
         (group.empty() ? "" : ", group " + group) + ")";
}

RowEval to_row(const ConstraintEval& e, int count, const int* particles) {
  RowEval r;
  r.C = e.C;
  r.count = count;
  r.valid = e.valid;
  for (int i = 0; i < count; ++i) {
    r.particles[static_cast<size_t>(i)] = particles[i];
    r.grad[static_cast<size_t>(i)] = e.grad[static_cast<size_t>(i)];
  }
  return r;
}

// [P -P; -P P] with P = (I - n n^T) / len: the Hessian of |x1 - x0|.
Mat12 length_hessian(const Vec3& d) {
  Mat12 H = Mat12::Zero();
  const double len = d.norm();
  if (!(len > 0.0)) return H;
  const Vec3 n = d / len;
  const Mat3 P = (Mat3::Identity() - n * n.transpose()) / len;
  H.block<3, 3>(0, 0) = P;
  H.block<3, 3>(3, 3) = P;
  H.block<3, 3>(0, 3) = -P;
  H.block<3, 3>(3, 0) = -P;
  return H;
}

// y += A x for a symmetric pattern's values (both triangles stored).
void pattern_product(const SparsityPattern& p, const std::vector<double>& values, double scale,
                     const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  for (int c = 0; c < p.n; ++c) {
    const double xc = scale * x(c);
    if (xc == 0.0) continue;
    for (std::int64_t k = p.column_start[static_cast<size_t>(c)];
         k < p.column_start[static_cast<size_t>(c) + 1]; ++k)
      y(p.row[static_cast<size_t>(k)]) += values[static_cast<size_t>(k)] * xc;
  }
}

}  // namespace

GlobalProblem::GlobalProblem(const Model& model) : model_(&model), energy_(model) {
  if (model.surface_contact || model.self_contact)
    throw std::invalid_argument(
        "no global solver simulates vertex-triangle contact (scene.surface_contact or "
        "scene.self_contact): pbd and xpbd do");
  for (size_t k = 0; k < model.elements.size(); ++k)
    if (!fem::has_constraint_form(model.elements[k].material))
      throw std::invalid_argument(
          "the global solvers cannot simulate element " + std::to_string(k) + ": its material " +
          to_string(model.elements[k].material) +
          " has no constraint form (stable_neo_hookean, stvk and linear have, as in xpbd); use a "
          "reference solver");
  particle_dof_.assign(static_cast<size_t>(model.particle_count()), -1);
  const std::vector<int>& dynamic = energy_.dynamic_particles();
  for (size_t b = 0; b < dynamic.size(); ++b)
    particle_dof_[static_cast<size_t>(dynamic[b])] = static_cast<int>(b);
  for (int j = 0; j < model.constraint_count(); ++j) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    if (c.compliance > 0.0) {
      compliant_.push_back(j);
      if (c.damping > 0.0) damped_.push_back(j);
    } else if (c.kind == ConstraintKind::Distance || c.kind == ConstraintKind::Volume) {
      rigid_.push_back(j);
    } else {
      throw std::invalid_argument(
          "the global solvers cannot hold " + constraint_label(model, j) +
          " rigid (compliance 0): only distance and volume constraints may be rigid; give it a "
          "compliance");
    }
  }
}

double GlobalProblem::alpha_tilde(int constraint) const {
  return model_->constraints[static_cast<size_t>(constraint)].compliance / (h_ * h_);
}

void GlobalProblem::begin_step(const Points& x_start, const Points& x_pred, double h, double t_end,
                               std::vector<Contact> contacts) {
  const int n = model_->particle_count();
  if (x_start.rows() != n || x_pred.rows() != n)
    throw std::invalid_argument("GlobalProblem::begin_step: positions for " +
                                std::to_string(x_start.rows()) + " and " +
                                std::to_string(x_pred.rows()) + " particles, the model has " +
                                std::to_string(n));
  if (!(h > 0.0) || !std::isfinite(h))
    throw std::invalid_argument("GlobalProblem::begin_step: h = " + std::to_string(h));
  h_ = h;
  t_end_ = t_end;
  x_start_ = x_start;
  x_pred_ = x_pred;
  q_start_ = energy_.gather(x_start);
  q_hat_ = energy_.gather(x_pred);
  for (Eigen::Index k = 0; k < q_hat_.size() / 3; ++k)
    q_hat_.segment<3>(3 * k) -= h * h * model_->gravity;
  if (!damped_.empty()) energy_.damping_matrix(x_start, damping_values_);
  else damping_values_.clear();
  contacts_ = std::move(contacts);
  rows_.clear();
  for (int j : rigid_) rows_.push_back(GlobalRow{false, j, -1});
  for (size_t k = 0; k < contacts_.size(); ++k)
    rows_.push_back(GlobalRow{true, -1, static_cast<int>(k)});
}

double GlobalProblem::objective(const Points& x) const {
  const Eigen::VectorXd q = energy_.gather(x);
  const Eigen::VectorXd d = q - q_hat_;
  double E = 0.5 * d.dot(mass().cwiseProduct(d)) + h_ * h_ * energy_.energy(x);
  if (!damping_values_.empty()) {
    const Eigen::VectorXd e = q - q_start_;
    Eigen::VectorXd De = Eigen::VectorXd::Zero(e.size());
    pattern_product(energy_.hessian_pattern(), damping_values_, 1.0, e, De);
    E += 0.5 * h_ * e.dot(De);
  }
  return E;
}

void GlobalProblem::gradient(const Points& x, Eigen::VectorXd& g) const {
  const Eigen::VectorXd q = energy_.gather(x);
  energy_.gradient(x, g);
  g *= h_ * h_;
  g += mass().cwiseProduct(q - q_hat_);
  if (!damping_values_.empty())
    pattern_product(energy_.hessian_pattern(), damping_values_, h_, q - q_start_, g);
}

void GlobalProblem::hessian_values(const Points& x, std::vector<double>& values) const {
  const SparsityPattern& p = energy_.hessian_pattern();
  energy_.hessian(x, values, /*project_psd=*/true);
  const double h2 = h_ * h_;
  for (double& v : values) v *= h2;
  if (!damping_values_.empty())
    for (size_t k = 0; k < values.size(); ++k) values[k] += h_ * damping_values_[k];
  for (int c = 0; c < p.n; ++c) values[static_cast<size_t>(p.find(c, c))] += mass()(c);
}

Eigen::SparseMatrix<double> GlobalProblem::hessian(const Points& x) const {
  const SparsityPattern& p = energy_.hessian_pattern();
  std::vector<double> values;
  hessian_values(x, values);
  Eigen::SparseMatrix<double> H(p.n, p.n);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(values.size());
  for (int c = 0; c < p.n; ++c)
    for (std::int64_t k = p.column_start[static_cast<size_t>(c)];
         k < p.column_start[static_cast<size_t>(c) + 1]; ++k)
      triplets.emplace_back(static_cast<int>(p.row[static_cast<size_t>(k)]), c, values[static_cast<size_t>(k)]);
  H.setFromTriplets(triplets.begin(), triplets.end());
  return H;
}

void GlobalProblem::hessian_product(const Points& x, const Eigen::VectorXd& v,
                                    Eigen::VectorXd& out) const {
  energy_.hessian_product(x, v, out, /*project_psd=*/true);
  out *= h_ * h_;
  out += mass().cwiseProduct(v);
  if (!damping_values_.empty())
    pattern_product(energy_.hessian_pattern(), damping_values_, h_, v, out);
}

Eigen::VectorXd GlobalProblem::hessian_diagonal(const Points& x) const {
  const SparsityPattern& p = energy_.hessian_pattern();
  std::vector<double> values;
  energy_.hessian(x, values, /*project_psd=*/true);
  Eigen::VectorXd d = mass();
  for (int c = 0; c < p.n; ++c) {
    const std::int64_t k = p.find(c, c);
    double v = h_ * h_ * values[static_cast<size_t>(k)];
    if (!damping_values_.empty()) v += h_ * damping_values_[static_cast<size_t>(k)];
    d(c) += v;
  }
  return d;
}

RowEval GlobalProblem::eval_row(int r, const Points& x) const {
  const GlobalRow& row = rows_[static_cast<size_t>(r)];
  if (!row.inequality) {
    const Constraint& c = model_->constraints[static_cast<size_t>(row.constraint)];
    return to_row(eval_constraint(*model_, c, x), arity(c.kind), c.particles.data());
  }
  const Contact& contact = contacts_[static_cast<size_t>(row.contact)];
  const ConstraintEval e = eval_contact(*model_, contact, x, t_end_);
  const int particles[2] = {contact.a, contact.b};
  return to_row(e, contact.kind == ContactKind::Particle ? 2 : 1, particles);
}

Mat12 GlobalProblem::row_hessian(int r, const Points& x) const {
  const GlobalRow& row = rows_[static_cast<size_t>(r)];
  if (!row.inequality) {
    const Constraint& c = model_->constraints[static_cast<size_t>(row.constraint)];
    const auto& p = c.particles;
    if (c.kind == ConstraintKind::Distance)
      return length_hessian(x.row(p[1]).transpose() - x.row(p[0]).transpose());
    return volume_constraint_hessian(x.row(p[0]), x.row(p[1]), x.row(p[2]), x.row(p[3]));
  }
  const Contact& contact = contacts_[static_cast<size_t>(row.contact)];
  switch (contact.kind) {
    case ContactKind::Plane: return Mat12::Zero();
    case ContactKind::Particle:
      // C = |x_a - x_b| - (r_a + r_b): the particles in the order (a, b).
      return length_hessian(x.row(contact.a).transpose() - x.row(contact.b).transpose());
    case ContactKind::Sphere: {
      const SphereCollider& s = model_->spheres[static_cast<size_t>(contact.b)];
      const Vec3 d = x.row(contact.a).transpose() - sphere_center(*model_, s, t_end_);
      // Outside: C = |d| - (R + r); Inside and Bowl: C = (R - r) - |d|.
      const Mat12 H = length_hessian(d);
      Mat12 out = Mat12::Zero();
      out.block<3, 3>(0, 0) = (s.side == SphereSide::Outside ? 1.0 : -1.0) * H.block<3, 3>(0, 0);
      return out;
    }
    case ContactKind::Mesh: {
      // C = s(x - offset) - r: the signed distance's Hessian, the sign times the unsigned one's.
      const MeshCollider& m = model_->meshes[static_cast<size_t>(contact.b)];
      const MeshDistance md =
          mesh_distance(m, x.row(contact.a).transpose() - mesh_offset(*model_, m, t_end_));
      Mat12 out = Mat12::Zero();
      out.block<3, 3>(0, 0) = (md.distance < 0.0 ? -1.0 : 1.0) * md.hessian;
      return out;
    }
    case ContactKind::Edge:  // (edge-edge: refused with it)
    case ContactKind::Triangle:  // refused by the constructor
      throw std::logic_error("global problem: a vertex-triangle contact reached the Hessian");
  }
  return Mat12::Zero();
}

RowEval GlobalProblem::eval_compliant(int constraint, const Points& x) const {
  const Constraint& c = model_->constraints[static_cast<size_t>(constraint)];
  if (c.kind != ConstraintKind::Bending)
    return to_row(eval_constraint(*model_, c, x), arity(c.kind), c.particles.data());
  Eigen::Matrix<double, 12, 1> g;
  bool valid = true;
  RowEval r;
  r.C = smooth_bending(c, x, &g, &valid);
  r.count = 4;
  r.valid = valid;
  for (int i = 0; i < 4; ++i) {
    r.particles[static_cast<size_t>(i)] = c.particles[static_cast<size_t>(i)];
    r.grad[static_cast<size_t>(i)] = valid ? Vec3(g.segment<3>(3 * i)) : Vec3::Zero();
  }
  return r;
}

double GlobalProblem::generalized_inverse_mass(const RowEval& e) const {
  double w = 0.0;
  for (int i = 0; i < e.count; ++i)
    w += model_->inv_mass[static_cast<size_t>(e.particles[static_cast<size_t>(i)])] *
         e.grad[static_cast<size_t>(i)].squaredNorm();
  return w;
}

void GlobalProblem::stationarity(const Points& x, const std::vector<double>& row_lambda,
                                 Eigen::VectorXd& g, std::vector<RowEval>* evals) const {
  gradient(x, g);
  if (evals) evals->resize(rows_.size());
  for (size_t r = 0; r < rows_.size(); ++r) {
    const RowEval e = eval_row(static_cast<int>(r), x);
    const double l = r < row_lambda.size() ? row_lambda[r] : 0.0;
    if (l != 0.0 && e.valid)
      for (int i = 0; i < e.count; ++i) {
        const int d = particle_dof(e.particles[static_cast<size_t>(i)]);
        if (d >= 0) g.segment<3>(3 * d) -= l * e.grad[static_cast<size_t>(i)];
      }
    if (evals) (*evals)[r] = e;
  }
}

double GlobalProblem::stationarity_residual(const Points& x,
                                            const std::vector<double>& row_lambda) const {
  Eigen::VectorXd g;
  stationarity(x, row_lambda, g, nullptr);
  double worst = 0.0;
  for (Eigen::Index k = 0; k < g.size(); ++k) worst = std::max(worst, std::abs(g(k)) / mass()(k));
  return std::isfinite(g.norm()) ? worst : std::numeric_limits<double>::infinity();
}

GlobalProblem::Residuals GlobalProblem::residuals(const Points& x,
                                                  const std::vector<double>& row_lambda) const {
  Residuals out;
  Eigen::VectorXd g;
  std::vector<RowEval> evals;
  stationarity(x, row_lambda, g, &evals);
  double h2 = 0.0, worst_row = 0.0;
  for (size_t r = 0; r < rows_.size(); ++r) {
    const RowEval& e = evals[r];
    const double l = r < row_lambda.size() ? row_lambda[r] : 0.0;
    double hr = 0.0, pos = 0.0;
    if (!rows_[r].inequality) {
      hr = e.C;
      double gn = 0.0;
      for (int i = 0; i < e.count; ++i) gn += e.grad[static_cast<size_t>(i)].squaredNorm();
      pos = gn > 0.0 ? std::abs(e.C) / std::sqrt(gn) : std::abs(e.C);
    } else {
      hr = l > 0.0 ? e.C : std::min(e.C, 0.0);
      pos = std::abs(hr);  // contacts are in metres with a unit normal
    }
    h2 += hr * hr;
    worst_row = std::max(worst_row, pos);
  }
  double worst_dof = 0.0;
  for (Eigen::Index k = 0; k < g.size(); ++k) worst_dof = std::max(worst_dof, std::abs(g(k)) / mass()(k));
  out.g_norm = g.norm();
  out.h_norm = std::sqrt(h2);
  out.position = std::max(worst_dof, worst_row);
  if (!std::isfinite(out.g_norm) || !std::isfinite(out.h_norm))
    out.position = std::numeric_limits<double>::infinity();
  return out;
}

void GlobalProblem::positions(const Eigen::VectorXd& q, Points& x) const {
  x = x_start_;
  const std::vector<int>& dynamic = energy_.dynamic_particles();
  for (size_t b = 0; b < dynamic.size(); ++b)
    x.row(dynamic[b]) = q.segment<3>(3 * static_cast<Eigen::Index>(b)).transpose();
}

Eigen::VectorXd GlobalProblem::gather(const Points& x) const { return energy_.gather(x); }

void GlobalProblem::constraint_forces(const Points& x, const std::vector<double>& row_lambda,
                                      std::vector<double>& lambda) const {
  lambda.assign(static_cast<size_t>(model_->constraint_count()), 0.0);
  for (int j : compliant_) {
    // A strain kind's multiplier is a vector (core/fem.hpp); its slot stays 0.
    if (is_strain_kind(model_->constraints[static_cast<size_t>(j)].kind)) continue;
    lambda[static_cast<size_t>(j)] =
        -eval_compliant(j, x).C / model_->constraints[static_cast<size_t>(j)].compliance;
  }
  for (size_t r = 0; r < rows_.size() && r < row_lambda.size(); ++r)
    if (!rows_[r].inequality)
      lambda[static_cast<size_t>(rows_[r].constraint)] = row_lambda[r] / (h_ * h_);
}

}  // namespace pbdbench
