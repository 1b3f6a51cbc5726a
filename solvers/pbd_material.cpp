#include "solvers/pbd_material.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

#include <fmt/format.h>

#include "core/constraint_functions.hpp"
#include "solvers/kernels.hpp"

namespace pbdbench {

namespace {

double abs_inv_mass(const Model& model, int p) {
  return std::abs(model.inv_mass[static_cast<std::size_t>(p)]);
}

// sum |w_i| |grad_i phi|^2 of the signed dihedral angle phi of the hinge (x0, x1; wings x2, x3):
// |grad_wing| = 1 / (the wing vertex's distance to the hinge line), along the wing's normal; the
// hinge vertices take minus the wings' gradients shared by the lever rule (t: where the wing
// vertex projects on the hinge, 0 at x0, 1 at x1). The gradients sum to zero (translation).
double bending_inverse_mass_sum(const Model& model, const Constraint& c) {
  const auto row = [&](int i) -> Vec3 {
    return model.rest_positions.row(c.particles[static_cast<std::size_t>(i)]).transpose();
  };
  const Vec3 x0 = row(0), x1 = row(1), x2 = row(2), x3 = row(3);
  const Vec3 e = x1 - x0;
  const double e2 = e.squaredNorm();
  const Vec3 n1 = e.cross(x2 - x0), n2 = e.cross(x3 - x0);
  const double a1 = n1.norm(), a2 = n2.norm();  // |e| times the wing's distance to the hinge
  if (!(e2 > 0.0) || !(a1 > 0.0) || !(a2 > 0.0)) return 0.0;
  const double len = std::sqrt(e2);
  // Wing gradients: n1 / d1 and -n2 / d2 (unit normals; the second wing's orientation flipped so
  // that lifting both wings to one side moves the signed angle one way).
  const Vec3 u2 = (len / a1) * (n1 / a1);
  const Vec3 u3 = -(len / a2) * (n2 / a2);
  const double t2 = (x2 - x0).dot(e) / e2, t3 = (x3 - x0).dot(e) / e2;
  const Vec3 u0 = -(1.0 - t2) * u2 - (1.0 - t3) * u3;
  const Vec3 u1 = -t2 * u2 - t3 * u3;
  const std::array<Vec3, 4> u{u0, u1, u2, u3};
  double s = 0.0;
  for (int i = 0; i < 4; ++i)
    s += abs_inv_mass(model, c.particles[static_cast<std::size_t>(i)]) * u[static_cast<std::size_t>(i)].squaredNorm();
  return s;
}

std::string number(double v) { return fmt::format("{:.4g}", v); }

// "lo .. hi", or one number where the two print the same (rounding differences of one value).
std::string range(double lo, double hi) {
  return number(lo) == number(hi) ? number(lo) : number(lo) + " .. " + number(hi);
}

}  // namespace

double pbd_inverse_mass_sum(const Model& model, const Constraint& c) {
  switch (c.kind) {
    case ConstraintKind::Distance:
      return abs_inv_mass(model, c.particles[0]) + abs_inv_mass(model, c.particles[1]);
    case ConstraintKind::Volume: {
      const ConstraintEval e = eval_constraint(c, model.rest_positions);
      if (!e.valid) return 0.0;
      double s = 0.0;
      for (int i = 0; i < 4; ++i)
        s += abs_inv_mass(model, c.particles[static_cast<std::size_t>(i)]) *
             e.grad[static_cast<std::size_t>(i)].squaredNorm();
      return std::isfinite(s) ? s : 0.0;
    }
    case ConstraintKind::Bending: {
      const double s = bending_inverse_mass_sum(model, c);
      return std::isfinite(s) ? s : 0.0;
    }
    default: return 0.0;  // the FEM kinds: no rule (pbd_material_problem)
  }
}

double pbd_stiffness_from_compliance(double alpha, double inverse_mass_sum, double h, int iterations) {
  if (!(alpha > 0.0) || !(inverse_mass_sum > 0.0)) return 1.0;
  // (1 - k)^n = 1 / (1 + x), x = h^2 S / alpha: k = 1 - exp(-log1p(x) / n), computed so that a
  // soft constraint (x small) keeps its digits.
  const double x = h * h * inverse_mass_sum / alpha;
  if (std::isinf(x)) return 1.0;
  return -std::expm1(-std::log1p(x) / static_cast<double>(iterations));
}

double pbd_compliance_of_stiffness(double k, double inverse_mass_sum, double h, int iterations) {
  if (k >= 1.0) return 0.0;
  if (!(k > 0.0)) return std::numeric_limits<double>::infinity();
  // (1 - k)^-n - 1 = expm1(-n log1p(-k)).
  const double x = std::expm1(-static_cast<double>(iterations) * std::log1p(-k));
  return h * h * inverse_mass_sum / x;
}

std::vector<double> pbd_inverse_mass_sums(const Model& model) {
  std::vector<double> s;
  s.reserve(model.constraints.size());
  for (const Constraint& c : model.constraints) s.push_back(pbd_inverse_mass_sum(model, c));
  return s;
}

std::vector<double> pbd_stiffness(const Model& model, const SolverOptions& options,
                                  const std::vector<double>& inverse_mass_sums, double h) {
  std::vector<double> k;
  k.reserve(model.constraints.size());
  for (std::size_t j = 0; j < model.constraints.size(); ++j) {
    const Constraint& c = model.constraints[j];
    if (options.pbd_material == PbdMaterial::Stiffness)
      k.push_back(options.pbd_stiffness_correction ? pbd_corrected_stiffness(c.stiffness, options.iterations)
                                                   : c.stiffness);
    else
      k.push_back(pbd_stiffness_from_compliance(c.compliance, inverse_mass_sums[j], h, options.iterations));
  }
  return k;
}

std::string pbd_material_problem(const Model& model) {
  const bool fem_constraints = std::any_of(model.constraints.begin(), model.constraints.end(),
                                           [](const Constraint& c) { return is_fem_kind(c.kind); });
  if (model.elements.empty() && !fem_constraints) return "";
  return fmt::format(
      "pbd has no rule for an FEM material ({} elements): a Young's modulus gives no "
      "per-constraint stiffness k; set scene.material = \"none\" (edge and volume constraints, "
      "whose compliances pbd derives k from) or solver.name = \"xpbd\" or a reference solver",
      model.elements.size());
}

std::vector<PbdGroupMaterial> pbd_material_summary(const Model& model, const SolverOptions& options,
                                                   double h) {
  const std::vector<double> k = pbd_stiffness(model, options, pbd_inverse_mass_sums(model), h);
  std::map<std::pair<int, int>, PbdGroupMaterial> by;
  for (std::size_t j = 0; j < model.constraints.size(); ++j) {
    const Constraint& c = model.constraints[j];
    const auto key = std::make_pair(static_cast<int>(c.group), static_cast<int>(c.kind));
    auto [it, fresh] = by.try_emplace(key);
    PbdGroupMaterial& g = it->second;
    if (fresh) {
      g.group = c.group < model.group_names.size() ? model.group_names[c.group] : "";
      g.kind = c.kind;
      g.compliance_min = g.compliance_max = c.compliance;
      g.k_min = g.k_max = k[j];
      g.derived = options.pbd_material == PbdMaterial::Compliance;
    }
    ++g.count;
    g.compliance_min = std::min(g.compliance_min, c.compliance);
    g.compliance_max = std::max(g.compliance_max, c.compliance);
    g.k_min = std::min(g.k_min, k[j]);
    g.k_max = std::max(g.k_max, k[j]);
  }
  std::vector<PbdGroupMaterial> out;
  for (auto& [key, g] : by) out.push_back(std::move(g));
  return out;
}

std::string pbd_material_text(const Model& model, const SolverOptions& options, double h) {
  std::string out;
  for (const PbdGroupMaterial& g : pbd_material_summary(model, options, h)) {
    if (!out.empty()) out += '\n';
    out += fmt::format("{} ({} x {}): ", g.group, g.count, to_string(g.kind));
    if (is_fem_kind(g.kind)) {
      // No k exists: pbd_stiffness's entry for an FEM constraint is never used, pbd refuses.
      out += "no k (pbd has no stiffness rule for an FEM element's Young's modulus and refuses the scene)";
      continue;
    }
    out += "k = " + range(g.k_min, g.k_max);
    if (g.derived)
      out += fmt::format(" derived from alpha = {} (Mueller 2007 effective stiffness: k = 1 - (1 + "
                         "h^2 S / alpha)^(-1/n), h = {} s, n = {})",
                         range(g.compliance_min, g.compliance_max), number(h), options.iterations);
    else
      out += fmt::format(" (explicit override, solver.pbd.material = \"stiffness\"{}; alpha = {} not read)",
                         options.pbd_stiffness_correction ? ", k' = 1 - (1 - k)^(1/n)" : "",
                         range(g.compliance_min, g.compliance_max));
  }
  return out;
}

namespace {

// What a solver other than pbd uses for one group of FEM constraints: the reference solvers
// (ref-*) the element's energy (reference/energy.cpp: an FEM constraint stands for its element);
// the others (xpbd, force-symplectic, global-*) the constraint's compliance, a matrix for the
// strain kinds (core/constraint_kind.hpp); pbd-seed none (it refuses FEM scenes).
std::string fem_material_text(const Model& model, const PbdGroupMaterial& g, const std::string& solver) {
  if (solver == "pbd-seed") return "none (pbd-seed has no FEM material and refuses the scene)";
  double mu_lo = std::numeric_limits<double>::infinity(), mu_hi = -mu_lo, la_lo = mu_lo, la_hi = -mu_lo;
  for (const Constraint& c : model.constraints)
    if (c.kind == g.kind && model.group_names.size() > c.group && model.group_names[c.group] == g.group &&
        c.element >= 0 && static_cast<std::size_t>(c.element) < model.elements.size()) {
      const FemElement& e = model.elements[static_cast<std::size_t>(c.element)];
      mu_lo = std::min(mu_lo, e.mu);
      mu_hi = std::max(mu_hi, e.mu);
      la_lo = std::min(la_lo, e.lambda);
      la_hi = std::max(la_hi, e.lambda);
    }
  const std::string moduli = mu_lo <= mu_hi ? fmt::format("mu = {} Pa, lambda = {} Pa", range(mu_lo, mu_hi),
                                                          range(la_lo, la_hi))
                                            : std::string("the element's mu and lambda");
  if (solver.rfind("ref-", 0) == 0)
    return "the element's energy V Psi(F), " + moduli + " (from E and nu; not the constraint's alpha = " +
           range(g.compliance_min, g.compliance_max) + ")";
  const std::string alpha = range(g.compliance_min, g.compliance_max);
  switch (g.kind) {
    case ConstraintKind::FemDeviatoric:
      return "alpha = " + alpha + " = 1 / (mu V), " + moduli + " from E and nu";
    case ConstraintKind::FemHydrostatic:
      return "alpha = " + alpha + " = 1 / (lambda_snh V), " + moduli + " from E and nu";
    default:
      return "the compliance matrix K^-1 / V of the element (" + moduli +
             " from E and nu); alpha = " + alpha + " is its deviatoric entry 1 / (2 mu V)";
  }
}

}  // namespace

std::string material_text(const Model& model, const SolverOptions& options, double dt) {
  if (options.name == "pbd") return pbd_material_text(model, options, dt / options.substeps);
  const bool seed = options.name == "pbd-seed";
  std::string out;
  for (const PbdGroupMaterial& g : pbd_material_summary(model, options, dt / options.substeps)) {
    if (!out.empty()) out += '\n';
    out += fmt::format("{} ({} x {}): ", g.group, g.count, to_string(g.kind));
    if (is_fem_kind(g.kind)) {
      out += fem_material_text(model, g, options.name);
      continue;
    }
    if (seed) {
      double lo = 1.0, hi = 0.0;
      for (const Constraint& c : model.constraints)
        if (model.group_names.size() > c.group && model.group_names[c.group] == g.group && c.kind == g.kind) {
          lo = std::min(lo, c.stiffness);
          hi = std::max(hi, c.stiffness);
        }
      out += "k = " + range(lo, hi) + " (the seed listing's stiffness per projection, the *_stiffness "
             "keys; alpha = " + range(g.compliance_min, g.compliance_max) + " not read)";
    } else {
      out += "alpha = " + range(g.compliance_min, g.compliance_max) + " (compliance, inverse stiffness)";
    }
  }
  return out;
}

bool elastic_energy_defined(const Model& model, const SolverOptions& options) {
  const bool reads_k = options.name == "pbd-seed" ||
                       (options.name == "pbd" && options.pbd_material == PbdMaterial::Stiffness);
  if (!reads_k) return true;
  return std::all_of(model.constraints.begin(), model.constraints.end(), [](const Constraint& c) {
    return is_fem_kind(c.kind) || (c.compliance == 0.0 && c.stiffness == 1.0);
  });
}

}  // namespace pbdbench
