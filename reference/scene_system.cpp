#include "reference/scene_system.hpp"

namespace pbdbench {

SceneSystem::SceneSystem(const Model& model) : energy_(model) {}

void SceneSystem::force(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
                        Eigen::VectorXd& f) const {
  energy_.positions(q, t, x_);
  energy_.gradient(x_, f);
  f = -f;
  if (energy_.has_damping()) {
    energy_.velocities(u, t, v_);
    energy_.damping_force(x_, v_, fd_);
    f += fd_;
  }
}

void SceneSystem::stiffness(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& /*u*/,
                            std::vector<double>& values) const {
  energy_.positions(q, t, x_);
  energy_.hessian(x_, values);
}

void SceneSystem::damping(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& /*u*/,
                          std::vector<double>& values) const {
  energy_.positions(q, t, x_);
  energy_.damping_matrix(x_, values);
}

double SceneSystem::potential(double t, const Eigen::VectorXd& q) const {
  energy_.positions(q, t, x_);
  return energy_.energy(x_);
}

void SceneSystem::gather(const State& s, Eigen::VectorXd& q, Eigen::VectorXd& u) const {
  q = energy_.gather(s.x);
  u = energy_.gather(s.v);
}

void SceneSystem::scatter(const Eigen::VectorXd& q, const Eigen::VectorXd& u, double t,
                          State& s) const {
  energy_.positions(q, t, s.x);
  energy_.velocities(u, t, s.v);
  energy_.constraint_forces(s.x, s.lambda);
}

}  // namespace pbdbench
