#include "runfile/converge_file.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

#include "runfile/layout.hpp"
#include "runfile/output_guard.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

namespace {

constexpr const char* kContent = "pbdbench converge";

using R = ConvergeResult;
using M = ConvergeMethod;

// ---------------------------------------------------------------------------------------------
// The layout. The root (then created and the build's provenance):

const std::array kRoot = {
    PBDBENCH_DERIVED(R, "content", "", "the kind of file: `pbdbench converge`", std::string(kContent)),
    PBDBENCH_DERIVED(R, "converge_format_version", "", "the layout's version: 1", 1LL),
    PBDBENCH_ATTRIBUTE(R, "scene", "", "the scenario's name", scene),
    PBDBENCH_ATTRIBUTE(R, "scenario_file", "", "the scenario file", scenario_file),
    PBDBENCH_ATTRIBUTE(R, "config", "", "the resolved configuration (TOML)", config),
    PBDBENCH_ATTRIBUTE(R, "dt", "s", "time.dt", dt),
    PBDBENCH_DERIVED(R, "h", "s", "the measured step: one substep of dt", r.dt),
    PBDBENCH_DERIVED(R, "substeps", "", "substeps of the measured step", 1LL),
    PBDBENCH_ATTRIBUTE(R, "time", "s", "the simulated time at the start of the measured step", time),
    PBDBENCH_ATTRIBUTE(R, "warmup_steps", "", "steps of the scene's own solver before it",
                       warmup_steps),
    PBDBENCH_ATTRIBUTE(R, "warmup_solver", "", "the scene's own solver.name", warmup_solver),
    PBDBENCH_ATTRIBUTE(R, "particles", "", "particles of the scene", particles),
    PBDBENCH_ATTRIBUTE(R, "dynamic_particles", "", "particles with inv_mass != 0", dynamic_particles),
    PBDBENCH_ATTRIBUTE(R, "constraints", "", "constraints of the model", constraints),
    PBDBENCH_ATTRIBUTE(R, "rows", "", "rigid rows and contacts of the step", rows),
    PBDBENCH_ATTRIBUTE(R, "contacts", "", "contacts of the step", contacts),
    PBDBENCH_ATTRIBUTE(R, "tolerance", "m", "solver.global.tolerance", tolerance),
    PBDBENCH_ATTRIBUTE(R, "start_residual", "m", "the residual at x~", start_residual),
    PBDBENCH_ATTRIBUTE(R, "residual_note", "", "how the residual is scored", residual_note),
    PBDBENCH_DERIVED(R, "error_note", "", "how the error is measured",
                     std::string("error: sqrt(sum m_i |x_i - x*_i|^2 / sum m_i) over the dynamic "
                                 "particles, x* the global-cholmod solution")),
    PBDBENCH_DERIVED(R, "methods", "", "the methods' keys (their groups), comma-separated",
                     [&] {
                       std::string keys;
                       for (const ConvergeMethod& m : r.methods)
                         keys += (keys.empty() ? "" : ",") + m.key;
                       return keys;
                     }()),
    PBDBENCH_ATTRIBUTE(R, "machine", "", "the CPU model (/proc/cpuinfo)", machine),
};

// /<method>: attributes.
const std::array kMethod = {
    PBDBENCH_ATTRIBUTE(M, "method", "", "the method, in one line", description),
    PBDBENCH_ATTRIBUTE(M, "iteration_kind", "", "what an iteration is", iteration_kind),
    PBDBENCH_ATTRIBUTE(M, "xpbd", "", "1: an xpbd order (one step per sweep count); 0: a global solver",
                       xpbd),
    PBDBENCH_ATTRIBUTE(M, "converged", "", "global: reached solver.global.tolerance", converged),
    PBDBENCH_ATTRIBUTE(M, "final_error", "m", "distance of the last result or iterate from x*",
                       final_error),
};

// /<method>: datasets, of an xpbd order ...
const std::array kXpbd = {
    PBDBENCH_DATASET(M, "iteration", "1", "projection sweeps of the step", iteration),
    PBDBENCH_DATASET(M, "residual", "m", "Residuals::position of the step's result", residual),
    PBDBENCH_DATASET(M, "time", "s", "wall time of the whole step (fastest of up to 5 when under 20 ms)",
                     time),
    PBDBENCH_DATASET(M, "error", "m", "mass-weighted RMS distance of the result from x*", error),
};

// ... and of a global solver.
const std::array kGlobal = {
    PBDBENCH_DATASET(M, "iteration", "1", "<iteration_kind> (0: the start, x~)", iteration,
                     nullptr, [](const M& m) { return m.iteration_kind + " (0: the start, x~)"; }),
    PBDBENCH_DATASET(M, "residual", "m", "Residuals::position of the iterate", residual),
    PBDBENCH_DATASET(M, "time", "s", "wall time since the solve began", time),
    PBDBENCH_DATASET(M, "inner_iterations", "1",
                     "cumulative conjugate-gradient or Levenberg-Marquardt iterations",
                     inner_iterations),
};

}  // namespace

std::vector<AttributeInfo> converge_root_attributes() {
  std::vector<AttributeInfo> out;
  layout::describe(kRoot, out);
  for (AttributeInfo& a : provenance_attributes()) out.push_back(std::move(a));
  return out;
}

std::vector<AttributeInfo> converge_method_attributes() {
  std::vector<AttributeInfo> out;
  layout::describe(kMethod, out);
  return out;
}

bool is_converge_file(const fs::path& path) { return is_pbdbench_file(path, kContent); }

void write_converge_file(const fs::path& path, const ConvergeResult& r) {
  layout::write_file(path, "converge", [&](H5::H5File& file) {
    layout::write_attributes(file, kRoot, r);
    layout::write_provenance(file);
    for (const ConvergeMethod& m : r.methods) {
      H5::Group g = file.createGroup("/" + m.key);
      layout::write_attributes(g, kMethod, m);
      if (m.xpbd)
        layout::write_datasets(g, kXpbd, m);
      else
        layout::write_datasets(g, kGlobal, m);
    }
  });
}

ConvergeFile read_converge_file(const fs::path& path) {
  ConvergeFile out;
  ConvergeResult& r = out.result;
  layout::read_file(path, "converge", kContent, [&](const H5::H5File& file) {
    h5::read_attributes(file, out.attributes, out.numbers);
    layout::read_attributes(file, kRoot, r);
    out.provenance = layout::read_provenance(file);
    std::string keys = out.attributes["methods"];
    std::replace(keys.begin(), keys.end(), ',', '\n');
    for (const std::string& key : layout::split_lines(keys)) {
      if (!file.nameExists("/" + key))
        throw std::runtime_error("converge file " + path.string() + ": no group /" + key +
                                 " for the method " + key);
      const H5::Group g = file.openGroup("/" + key);
      ConvergeMethod m;
      m.key = key;
      layout::read_attributes(g, kMethod, m);
      if (m.xpbd)
        layout::read_datasets(g, kXpbd, m);
      else
        layout::read_datasets(g, kGlobal, m);
      r.methods.push_back(std::move(m));
    }
  });
  return out;
}

}  // namespace pbdbench
