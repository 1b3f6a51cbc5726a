// One HDF5 file per run. The layout is documented in results/README.md:
//
//   /                  attributes: declared once, run_file.cpp kRoot (run_root_attributes():
//                      name, type, units, doc; results/README.md carries its table verbatim),
//                      written by the writer and read into RunFileData::root: format_version,
//                      status, status_reason, scenario, scenario_file, solver, config (resolved
//                      TOML), dt, steps_planned, material, steps_completed, wall_time,
//                      exploded_step, exploded_time, warnings (one per line, "" when none:
//                      metrics/health.hpp), warning_count, then the provenance (created,
//                      pbdbench_version, git_commit, compiler, build_type, cxx_flags)
//   /series/<name>     one dataset per series_table() entry (+ per-group series), extendible,
//                      chunked; attributes units, doc, deterministic
//   /frames/time       (F,) s
//   /frames/positions  (F, n, 3) m, chunked (1, n, 3), gzip (level 1, deflated off the stepping thread)
//   /frames/velocities (F, n, 3) m/s, the same (NaN rows where a frame came without them)
//   /model/...         (declared once in run_file.cpp, kModelArrays, for the writer and the reader)
//                      rest_positions (n,3), inv_mass (n), radius (n), gravity (3), edges (E,2),
//                      triangles (T,3), tets (K,4), constraint_kind (m), constraint_particles
//                      (m,4), constraint_rest (m), constraint_compliance (m),
//                      constraint_stiffness (m), constraint_damping (m), constraint_group (m);
//                      attribute group_names
//
// The writer flushes as it goes: when a row or a frame arrives at least `flush_every_seconds` of
// wall time after the last flush (an interval stretched so that flushing takes at most about 5 %
// of the wall time), at flush() and at finish(). A run killed at any moment leaves a file that
// h5py opens, with status "incomplete" and every series and frame up to the last flush; memory
// does not grow with the run, and a flush writes what changed since the last one, not the whole
// file (run_file.cpp and runfile/shadow_file.hpp say how; results/README.md has the
// measurements). One writer per path: the writer holds "<path>.lock" for its life
// (runfile/output_guard.hpp).
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "runfile/file_read.hpp"
#include "runfile/series.hpp"

namespace pbdbench {

enum class RunStatus { Incomplete, Complete, Exploded, Failed };
const char* to_string(RunStatus status);  // "incomplete", "complete", "exploded", "failed"

struct RunHeader {
  std::string scenario;       // scenario name
  std::string scenario_file;  // path of the scenario file
  std::string solver;         // solver name
  std::string config;         // the whole resolved configuration as TOML text
  double dt = 0.0;            // s
  long steps_planned = 0;
  // What the solver takes each constraint's material from (root attribute "material", one line
  // per constraint group; solvers/pbd_material.hpp pbd_material_text for pbd), "" when not told.
  std::string material;
  // pbd: the k it projects each model constraint with (model order; derived from the compliance
  // for the run's substep, or the explicit override), written as /model/pbd_stiffness with the
  // rule as its doc. Empty for the other solvers (no dataset).
  std::vector<double> pbd_stiffness;
  std::string pbd_stiffness_rule;
};

class RunFileWriter {
 public:
  // Locks the path, creates the file (replacing a run file left there, and only a run file),
  // writes the header, the build's provenance and the model, sets status "incomplete" and
  // flushes. Throws OutputRefused (runfile/output_guard.hpp) when the path holds anything but a
  // run file, is the scenario file (header.scenario_file), or another writer holds it, and
  // std::runtime_error naming the path on any other failure.
  RunFileWriter(const std::filesystem::path& path, const RunHeader& header, const Model& model,
                double flush_every_seconds = 0.5);
  ~RunFileWriter();  // closes; the status stays "incomplete" unless finish() was called
  RunFileWriter(const RunFileWriter&) = delete;
  RunFileWriter& operator=(const RunFileWriter&) = delete;

  void append(const SeriesRow& row);                // one row of every series
  // One frame of positions and, when given, velocities (else NaN).
  void append_frame(double time, const Points& x, const Points* v = nullptr);
  void flush();

  // Records the run's warnings (metrics/health.hpp): the root attributes "warnings" (one per
  // line) and "warning_count". Every file starts with none.
  void set_warnings(const std::vector<std::string>& lines);

  // Records how the run ended and closes the file. For Exploded, exploded_step/time say when.
  void finish(RunStatus status, const std::string& reason, long steps_completed,
              double wall_time, long exploded_step = -1, double exploded_time = -1.0);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The run file's root attributes, one member each (run_file.cpp kRoot declares their names,
// units and docs; run_root_attributes() lists them).
struct RunRoot {
  long long format_version = 0;  // 0: not in the file
  std::string status;            // to_string(RunStatus)
  std::string status_reason;
  std::string scenario;
  std::string scenario_file;
  std::string solver;
  std::string config;
  double dt = 0.0;  // s
  long long steps_planned = 0;
  std::string material;
  long long steps_completed = 0;
  double wall_time = 0.0;  // s
  long long exploded_step = -1;
  double exploded_time = -1.0;  // s
  std::string warnings;         // one per line
  long long warning_count = 0;
  Provenance provenance;
};

// The root attributes in the order the writer writes them: kRoot's, then provenance_attributes().
std::vector<AttributeInfo> run_root_attributes();

// A run file read back (compare, sweep, summary, claims, regress): what RunFileParts asked for.
struct RunFileData {
  RunRoot root;  // the declared root attributes (always read)
  std::map<std::string, std::string> attributes;  // every string attribute of the root
  std::map<std::string, double> numbers;          // every numeric scalar attribute of the root
  // Series (parts.series): every dataset under /series, by its width.
  std::map<std::string, std::vector<double>> series;  // width-1 series, (rows) each
  std::map<std::string, Points> series3;              // width-3 series, (rows x 3) each
  std::map<std::string, std::string> units;           // series name -> its `units` attribute
  std::map<std::string, std::string> docs;            // series name -> its `doc` attribute
  std::set<std::string> nondeterministic;  // series whose `deterministic` attribute is 0
  std::vector<std::string> group_names;    // /model's group_names (always read)
  // Frames (parts.frames): /frames/time, and the positions and velocities of all frames or of
  // the last one only (frame_time still has every frame's time).
  std::vector<double> frame_time;  // (F) s
  std::vector<Points> frames;      // (F or 1) frames of (n x 3) m
  std::vector<Points> velocities;  // the same in m/s (NaN rows where a frame came without them)
  bool has_velocities = false;     // the file has /frames/velocities (read or not)
  // /model/pbd_stiffness (parts.model): the k a pbd run projected each constraint with; empty
  // for the other solvers.
  std::vector<double> pbd_stiffness;
  // The model (parts.model): what /model stores (particles, gravity, topology, constraints and
  // group names); the rest of a Model (colliders, FEM elements, attachments, motions,
  // observables) is not in the file and stays empty.
  Model model;

  std::string status() const;  // attributes["status"]
  // attributes["warnings"] split into lines (none for files written before warnings existed).
  std::vector<std::string> warnings() const;
};

struct RunFileParts {
  bool series = true;
  enum class Frames { None, Last, All } frames = Frames::None;
  bool velocities = true;  // with the frames' positions, their velocities
  bool model = false;
};

// Throws std::runtime_error naming the path when the file cannot be read, or when its model or
// frames (when asked for) do not have the shapes above.
RunFileData read_run_file(const std::filesystem::path& path, const RunFileParts& parts);
RunFileData read_run_file(const std::filesystem::path& path, bool with_series = true);

// The bitwise tier of regression (regress/regress.hpp): the 64-bit FNV-1a hash of every
// deterministic series (in series_table() order) and of the last frame of positions, as 16 hex
// digits. Needs data read with series and at least the last frame.
std::string state_hash(const RunFileData& data);
// The same of a file (reads what it needs).
std::string state_hash(const std::filesystem::path& path);

}  // namespace pbdbench
