// The run file writer and reader.
//
// Crash safety. The HDF5 library updates a file's metadata (object headers, chunk B-trees, the
// superblock's end-of-file address) in place, several separate writes per flush, so a process
// killed during a flush, or after the metadata cache evicted an entry between flushes, can leave a
// file that no reader opens or whose series disagree. The latest file format (superblock version
// 3, which SWMR writing needs) is worse after a crash: the superblock keeps "open for writing"
// flags that make every plain (non-SWMR) open fail until an external tool clears them.
// tests/runfile/kill_test.py measures all of this; results/README.md has the numbers.
//
// So this writer never lets the library write to the published file. The library writes in
// place into a working copy, "<path>.shadow", through a file driver of our own
// (runfile/shadow_file.hpp); publishing flushes the library's caches and renames the working
// copy over <path>, then brings the previous image up to date with the bytes written since and
// makes it the next working copy. rename() is atomic: at any moment <path> is either the
// previous complete image or the new one, both valid files with status "incomplete" until
// finish() publishes the last one. Memory does not grow with the run (rows are buffered up to
// kMaxPendingRows), and a publish writes what changed, never the whole file. The writer holds
// an exclusive lock on "<path>.lock" for the run's life (runfile/output_guard.hpp) and no HDF5
// lock on <path>, so readers may open it while the run is still going.
#include "runfile/run_file.hpp"
#include "runfile/frame_reader.hpp"

#include "runfile/frame_compressor.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <H5Cpp.h>

#include <algorithm>
#include <bit>
#include <deque>
#include <memory>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <type_traits>

#include "runfile/h5_io.hpp"
#include "runfile/layout.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/shadow_file.hpp"

namespace pbdbench {

const char* to_string(RunStatus status) {
  switch (status) {
    case RunStatus::Incomplete: return "incomplete";
    case RunStatus::Complete: return "complete";
    case RunStatus::Exploded: return "exploded";
    case RunStatus::Failed: return "failed";
  }
  return "unknown";
}

std::string RunFileData::status() const { return root.status; }

std::vector<std::string> RunFileData::warnings() const { return layout::split_lines(root.warnings); }

namespace {

using Clock = std::chrono::steady_clock;

constexpr long long kFormatVersion = 1;
constexpr hsize_t kChunkRows = 256;  // rows per chunk of a series dataset
// Frames are deflated at level 1 without the shuffle filter, off the stepping thread
// (runfile/frame_compressor.hpp). On a 256 x 256 cloth's frames, level 1 without shuffle gave
// smaller files than level 4 with shuffle (24.4 against 26.2 MB) in half the time (1.37 against
// 2.63 s; scripts/frame_compression.py RUN.h5 times each setting on a run file's frames).
constexpr int kGzipLevel = 1;
// Publishing copies what changed since the last publish; it is spaced so that it takes at most
// about 1/kPublishShare of the wall time.
constexpr double kPublishShare = 20.0;
// Rows buffered in memory before they are written into the working copy (not yet published).
constexpr size_t kMaxPendingRows = 4096;

[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what) {
  throw std::runtime_error("run file " + path.string() + ": " + what);
}

std::string h5_message(const H5::Exception& e) { return h5::message(e); }

// ---------------------------------------------------------------------------------------------
// Attributes. Strings are variable-length UTF-8 (h5py reads them as str, not bytes).

// A fresh attribute `name` of this type and space (an existing one is removed first).
H5::Attribute fresh_attribute(H5::H5Object& obj, const std::string& name, const H5::DataType& type,
                              const H5::DataSpace& space) {
  if (obj.attrExists(name)) obj.removeAttr(name);
  return obj.createAttribute(name, type, space);
}

// A scalar attribute `name` of this type: the existing one when it has that type (rewritten in
// place, so that the object header does not grow with each rewrite), else a fresh one.
H5::Attribute scalar_attribute(H5::H5Object& obj, const std::string& name,
                               const H5::DataType& type) {
  if (obj.attrExists(name)) {
    H5::Attribute attr = obj.openAttribute(name);
    if (attr.getSpace().getSimpleExtentType() == H5S_SCALAR && attr.getDataType() == type)
      return attr;
  }
  return fresh_attribute(obj, name, type, H5::DataSpace(H5S_SCALAR));
}

void set_attr(H5::H5Object& obj, const std::string& name, const std::string& value) {
  const H5::StrType type = h5::utf8();
  scalar_attribute(obj, name, type).write(type, value);
}

void set_attr(H5::H5Object& obj, const std::string& name, const char* value) {
  set_attr(obj, name, std::string(value ? value : ""));
}

void set_attr(H5::H5Object& obj, const std::string& name, long long value) {
  scalar_attribute(obj, name, H5::PredType::STD_I64LE).write(H5::PredType::NATIVE_LLONG, &value);
}

void set_attr(H5::H5Object& obj, const std::string& name, int value) {
  scalar_attribute(obj, name, H5::PredType::STD_I32LE).write(H5::PredType::NATIVE_INT, &value);
}

void set_attr(H5::H5Object& obj, const std::string& name, double value) {
  scalar_attribute(obj, name, H5::PredType::IEEE_F64LE).write(H5::PredType::NATIVE_DOUBLE, &value);
}

void set_attr(H5::H5Object& obj, const std::string& name, const std::vector<std::string>& values) {
  const H5::StrType type = h5::utf8();
  const hsize_t n = values.size();
  H5::Attribute attr = fresh_attribute(obj, name, type, H5::DataSpace(1, &n));
  if (values.empty()) return;
  std::vector<const char*> ptrs;
  for (const std::string& v : values) ptrs.push_back(v.c_str());
  attr.write(type, ptrs.data());
}

// ---------------------------------------------------------------------------------------------
// The root attributes, declared once (results/README.md carries run_root_attributes() as a
// table): the writer writes each (put_root, by name: a name not in the table is a logic error)
// and the reader reads each into RunFileData::root. The provenance follows (layout.cpp).

using Root = RunRoot;

const std::array kRoot = {
    PBDBENCH_ATTRIBUTE(Root, "format_version", "", "layout version of this file: 1", format_version),
    PBDBENCH_ATTRIBUTE(Root, "status", "",
                       "`incomplete`, `complete`, `exploded` or `failed` (see above)", status),
    PBDBENCH_ATTRIBUTE(Root, "status_reason", "", "why the run ended (empty or a sentence)", status_reason),
    PBDBENCH_ATTRIBUTE(Root, "scenario", "", "the scenario's name", scenario),
    PBDBENCH_ATTRIBUTE(Root, "scenario_file", "", "the path of the scenario file the run was configured from",
                       scenario_file),
    PBDBENCH_ATTRIBUTE(Root, "solver", "", "the solver's registered name (`pbd-seed`, `pbd`, `xpbd`, ...)",
                       solver),
    PBDBENCH_ATTRIBUTE(Root, "config", "",
                       "the whole resolved configuration as TOML text (defaults and `--set` overrides "
                       "applied): enough to repeat the run",
                       config),
    PBDBENCH_ATTRIBUTE(Root, "dt", "s", "the time step", dt),
    PBDBENCH_ATTRIBUTE(Root, "steps_planned", "", "steps the run was configured to take", steps_planned),
    PBDBENCH_ATTRIBUTE(Root, "material", "",
                       "what the solver took each constraint group's material from, one line per group "
                       "and kind: for `pbd` the k of each group, \"derived from alpha = ... (Mueller 2007 "
                       "effective stiffness ...)\" or \"explicit override\" (docs/solvers.md, \"One "
                       "material\"); for `pbd-seed` its k; for the others the compliance alpha",
                       material),
    PBDBENCH_ATTRIBUTE(Root, "steps_completed", "", "steps taken; while the run is going, as of the last flush",
                       steps_completed),
    PBDBENCH_ATTRIBUTE(Root, "wall_time", "s",
                       "wall-clock time of the run; while the run is going, since the file was created, "
                       "as of the last flush",
                       wall_time),
    PBDBENCH_ATTRIBUTE(Root, "exploded_step", "", "the step at which the run exploded; -1 otherwise",
                       exploded_step),
    PBDBENCH_ATTRIBUTE(Root, "exploded_time", "s", "the simulated time at which it exploded; -1 otherwise",
                       exploded_time),
    PBDBENCH_ATTRIBUTE(Root, "warnings", "",
                       "the run's warnings, one a line; empty when none (see [Status](#status))", warnings),
    PBDBENCH_ATTRIBUTE(Root, "warning_count", "", "the number of lines of `warnings`", warning_count),
};

// Writes kRoot's attribute `name` from `root` (rewritten in place when it exists).
void put_root(H5::H5Object& file, const RunRoot& root, std::string_view name) {
  for (const layout::AttributeSpec<Root>& a : kRoot)
    if (a.name == name) {
      std::visit([&](const auto& v) { set_attr(file, std::string(name), v); }, a.get(root));
      return;
    }
  throw std::logic_error("run file: the root attribute " + std::string(name) +
                         " is not declared in run_file.cpp kRoot");
}

// ---------------------------------------------------------------------------------------------
// The arrays under /model, declared once (kModelArrays): the writer and the reader follow the
// same table.

// The file's and the memory's type of an element.
template <class T>
struct Element;
template <>
struct Element<double> {
  static const H5::PredType& file() { return H5::PredType::IEEE_F64LE; }
  static const H5::PredType& memory() { return H5::PredType::NATIVE_DOUBLE; }
};
template <>
struct Element<int> {
  static const H5::PredType& file() { return H5::PredType::STD_I32LE; }
  static const H5::PredType& memory() { return H5::PredType::NATIVE_INT; }
};
template <>
struct Element<signed char> {
  static const H5::PredType& file() { return H5::PredType::STD_I8LE; }
  static const H5::PredType& memory() { return H5::PredType::NATIVE_SCHAR; }
};
template <>
struct Element<std::uint16_t> {
  static const H5::PredType& file() { return H5::PredType::STD_U16LE; }
  static const H5::PredType& memory() { return H5::PredType::NATIVE_USHORT; }
};

struct ModelArray {
  const char* name;   // dataset under /model
  const char* units;  // its `units` attribute; nullptr: none (it depends on the constraint kind)
  void (*write)(H5::Group& g, const ModelArray& a, const Model& m);
  void (*read)(const H5::Group& g, const ModelArray& a, Model& m);
};

// Writes `values` as (rows,) when width is 0, else (rows, width).
template <class T>
void put_array(H5::Group& g, const ModelArray& a, const std::vector<T>& values, size_t width) {
  std::vector<hsize_t> dims{width == 0 ? values.size() : values.size() / width};
  if (width > 0) dims.push_back(width);
  const H5::DataSpace space(static_cast<int>(dims.size()), dims.data());
  H5::DataSet ds = g.createDataSet(a.name, Element<T>::file(), space);
  if (!values.empty()) ds.write(values.data(), Element<T>::memory());
  if (a.units != nullptr) set_attr(ds, "units", a.units);
}

// Reads what put_array wrote (none when the dataset is absent); throws std::runtime_error when
// it has another shape.
template <class T>
std::vector<T> take_array(const H5::Group& g, const ModelArray& a, size_t width) {
  if (!g.nameExists(a.name)) return {};
  const H5::DataSet ds = g.openDataSet(a.name);
  const H5::DataSpace space = ds.getSpace();
  const int rank = space.getSimpleExtentNdims();
  hsize_t dims[2] = {0, 0};
  if (rank == 1 || rank == 2) space.getSimpleExtentDims(dims);
  if (rank != (width == 0 ? 1 : 2) || (width > 0 && dims[1] != width))
    throw std::runtime_error(std::string("/model/") + a.name + " is not " +
                             (width == 0 ? "1-D" : "(rows, " + std::to_string(width) + ")"));
  std::vector<T> values(static_cast<size_t>(space.getSimpleExtentNpoints()));
  if (!values.empty()) ds.read(values.data(), Element<T>::memory());
  return values;
}

// A per-particle array (n).
template <std::vector<double> Model::*Member>
ModelArray per_particle(const char* name, const char* units) {
  return {name, units,
          [](H5::Group& g, const ModelArray& a, const Model& m) { put_array(g, a, m.*Member, 0); },
          [](const H5::Group& g, const ModelArray& a, Model& m) { m.*Member = take_array<double>(g, a, 0); }};
}

// Cells of K particle indices (rows x K).
template <size_t K, std::vector<std::array<int, K>> Model::*Member>
ModelArray cells(const char* name) {
  return {name, nullptr,
          [](H5::Group& g, const ModelArray& a, const Model& m) {
            std::vector<int> flat;
            for (const auto& cell : m.*Member) flat.insert(flat.end(), cell.begin(), cell.end());
            put_array(g, a, flat, K);
          },
          [](const H5::Group& g, const ModelArray& a, Model& m) {
            const std::vector<int> flat = take_array<int>(g, a, K);
            (m.*Member).resize(flat.size() / K);
            for (size_t r = 0; r < (m.*Member).size(); ++r)
              std::copy_n(flat.begin() + static_cast<long>(r * K), K, (m.*Member)[r].begin());
          }};
}

// One field of every constraint, stored as T: a scalar (W = 0) or W values (an array field).
template <class T, size_t W, auto Field>
ModelArray per_constraint(const char* name, const char* units) {
  return {name, units,
          [](H5::Group& g, const ModelArray& a, const Model& m) {
            std::vector<T> values;
            for (const Constraint& c : m.constraints) {
              if constexpr (W == 0)
                values.push_back(static_cast<T>(c.*Field));
              else
                values.insert(values.end(), (c.*Field).begin(), (c.*Field).end());
            }
            put_array(g, a, values, W);
          },
          [](const H5::Group& g, const ModelArray& a, Model& m) {
            const std::vector<T> values = take_array<T>(g, a, W);
            const size_t rows = W == 0 ? values.size() : values.size() / W;
            if (m.constraints.empty()) m.constraints.resize(rows);
            if (rows != m.constraints.size())
              throw std::runtime_error(std::string("/model/") + a.name + " has " + std::to_string(rows) +
                                       " rows for " + std::to_string(m.constraints.size()) + " constraints");
            for (size_t k = 0; k < rows; ++k) {
              auto& field = m.constraints[k].*Field;
              using F = std::remove_reference_t<decltype(field)>;
              if constexpr (W > 0) {
                std::copy_n(values.begin() + static_cast<long>(k * W), W, field.begin());
              } else if constexpr (std::is_same_v<F, ConstraintKind>) {
                if (values[k] < 0 || values[k] >= kConstraintKindCount)
                  throw std::runtime_error(std::string("/model/") + a.name + " has an unknown kind " +
                                           std::to_string(values[k]));
                field = static_cast<ConstraintKind>(values[k]);
              } else {
                field = static_cast<F>(values[k]);
              }
            }
          }};
}

const std::array kModelArrays = {
    ModelArray{"rest_positions", "m",
               [](H5::Group& g, const ModelArray& a, const Model& m) {
                 const Points& x = m.rest_positions;
                 put_array(g, a, std::vector<double>(x.data(), x.data() + x.size()), 3);
               },
               [](const H5::Group& g, const ModelArray& a, Model& m) {
                 const std::vector<double> x = take_array<double>(g, a, 3);
                 m.rest_positions.resize(static_cast<Eigen::Index>(x.size() / 3), 3);
                 std::copy(x.begin(), x.end(), m.rest_positions.data());
               }},
    per_particle<&Model::inv_mass>("inv_mass", "1/kg"),
    per_particle<&Model::radius>("radius", "m"),
    ModelArray{"gravity", "m/s^2",
               [](H5::Group& g, const ModelArray& a, const Model& m) {
                 put_array(g, a, std::vector<double>{m.gravity[0], m.gravity[1], m.gravity[2]}, 0);
               },
               [](const H5::Group& g, const ModelArray& a, Model& m) {
                 const std::vector<double> v = take_array<double>(g, a, 0);
                 if (v.size() == 3) m.gravity = Vec3(v[0], v[1], v[2]);
               }},
    cells<2, &Model::edges>("edges"),
    cells<3, &Model::triangles>("triangles"),
    cells<4, &Model::tets>("tets"),
    per_constraint<signed char, 0, &Constraint::kind>("constraint_kind", nullptr),
    per_constraint<int, 4, &Constraint::particles>("constraint_particles", nullptr),
    per_constraint<double, 0, &Constraint::rest>("constraint_rest", nullptr),
    per_constraint<double, 0, &Constraint::compliance>("constraint_compliance", nullptr),
    per_constraint<double, 0, &Constraint::stiffness>("constraint_stiffness", "1"),
    // Damping is in s / (units of alpha): it depends on the kind, so no units attribute.
    per_constraint<double, 0, &Constraint::damping>("constraint_damping", nullptr),
    per_constraint<std::uint16_t, 0, &Constraint::group>("constraint_group", nullptr),
};

void write_model(H5::H5File& file, const Model& model) {
  H5::Group g = file.createGroup("/model");
  for (const ModelArray& a : kModelArrays) {
    a.write(g, a, model);
    if (std::string_view(a.name) == "constraint_kind") {
      H5::DataSet ds = g.openDataSet(a.name);
      std::vector<std::string> names;
      for (int k = 0; k < kConstraintKindCount; ++k)
        names.emplace_back(to_string(static_cast<ConstraintKind>(k)));
      set_attr(ds, "kind_names", names);
    }
  }
  set_attr(g, "group_names", model.group_names);
}

void read_model(const H5::Group& g, Model& m) {
  for (const ModelArray& a : kModelArrays) a.read(g, a, m);
}

// Rows are appended, never read back: a dataset's chunk cache needs to hold the chunk being
// filled, not the default 1 MiB (which, per dataset, made memory grow over the first 10^5 rows).
H5::DSetAccPropList small_chunk_cache(size_t chunk_bytes) {
  H5::DSetAccPropList dapl;
  dapl.setChunkCache(101, 2 * chunk_bytes, 1.0);
  return dapl;
}

// An extendible dataset of doubles, (rows,) or (rows, width), with the rows not yet written.
struct Series {
  H5::DataSet dataset;
  int width = 1;
  hsize_t rows = 0;              // rows in the dataset
  std::vector<double> pending;   // rows not yet written, row-major
};

Series create_series(H5::Group& group, const std::string& name, int width, std::string_view units,
                     std::string_view doc, bool deterministic) {
  const int rank = width == 1 ? 1 : 2;
  const hsize_t dims[2] = {0, static_cast<hsize_t>(width)};
  const hsize_t maxdims[2] = {H5S_UNLIMITED, static_cast<hsize_t>(width)};
  const hsize_t chunk[2] = {kChunkRows, static_cast<hsize_t>(width)};
  H5::DSetCreatPropList props;
  props.setChunk(rank, chunk);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  props.setFillValue(H5::PredType::NATIVE_DOUBLE, &nan);
  Series s{group.createDataSet(name, H5::PredType::IEEE_F64LE, H5::DataSpace(rank, dims, maxdims), props,
                               small_chunk_cache(kChunkRows * static_cast<size_t>(width) * sizeof(double))),
           width, 0, {}};
  set_attr(s.dataset, "units", std::string(units));
  set_attr(s.dataset, "doc", std::string(doc));
  set_attr(s.dataset, "deterministic", deterministic ? 1 : 0);
  return s;
}

// Appends `count` rows (row-major, `width` values each) to an extendible dataset whose first
// dimension is the row count.
void append_rows(H5::DataSet& ds, hsize_t& rows, hsize_t count,
                 const std::vector<hsize_t>& row_dims, const void* data,
                 const H5::PredType& mem_type) {
  if (count == 0) return;
  const int rank = static_cast<int>(row_dims.size()) + 1;
  std::vector<hsize_t> size{rows + count}, start{rows}, block{count};
  for (hsize_t d : row_dims) {
    size.push_back(d);
    start.push_back(0);
    block.push_back(d);
  }
  ds.extend(size.data());
  H5::DataSpace file_space = ds.getSpace();  // the space changed with extend()
  file_space.selectHyperslab(H5S_SELECT_SET, block.data(), start.data());
  const H5::DataSpace mem_space(rank, block.data());
  ds.write(data, mem_type, mem_space, file_space);
  rows += count;
}

// Writes all of `data` to a new file `tmp`, then renames it over `path`.
}  // namespace

// ---------------------------------------------------------------------------------------------

struct RunFileWriter::Impl {
  std::filesystem::path path;
  double flush_every = 0.5;
  int particles = 0;
  size_t groups = 0;

  // Declared first, destroyed last: HDF5 keeps the file open while objects in it are open.
  std::optional<H5::H5File> file;
  std::vector<Series> series;        // series_table() order, then group series
  std::vector<std::string> series_names;
  std::optional<H5::DataSet> frame_time, frame_positions, frame_velocities;
  hsize_t frames = 0;
  // Frames' positions and velocities are deflated by a worker (chunk 2k: positions of frame k,
  // 2k + 1: its velocities) and stored here in order; a frame's time is stored with its
  // velocities, so every image has as many frame times as positions and velocities. A publish
  // stores the frames finished by then (the series may be a few frames ahead); finish() stores
  // them all. At most kMaxFramesQueued frames wait for the worker.
  static constexpr long long kMaxFramesQueued = 4;
  std::unique_ptr<FrameCompressor> compressor;
  std::deque<double> frame_times_queued;
  std::optional<CompressedChunk> held_positions;  // a frame's positions, its velocities not done

  size_t pending_rows = 0;
  long last_step = 0;
  bool dirty = false;     // the image changed since it was last published
  bool closed = false;    // finish() ran (or the file was closed)
  Clock::time_point started = Clock::now();
  Clock::time_point last_publish = Clock::now();
  double last_publish_cost = 0.0;  // s
  std::optional<OutputLock> lock;  // one writer per path, for the writer's life
  DiskWorker disk;                 // writebacks started, replaced files closed (disk_worker.hpp)
  RunRoot root;                    // the root attributes as last written (kRoot)
  bool broken = false;             // a publish failed half-way: the working copy is gone

  void write_pending() {
    if (pending_rows == 0) return;
    for (Series& s : series) {
      std::vector<hsize_t> row_dims;
      if (s.width != 1) row_dims.push_back(static_cast<hsize_t>(s.width));
      append_rows(s.dataset, s.rows, pending_rows, row_dims, s.pending.data(),
                  H5::PredType::NATIVE_DOUBLE);
      s.pending.clear();
    }
    pending_rows = 0;
    dirty = true;
  }

  // Stores the chunks the compressor has finished (with `wait`, every one submitted). The whole
  // frames among them (positions, velocities and time reach the image together) go in at once:
  // each dataset is extended once and the times appended in one write.
  void store_frames(bool wait) {
    if (!compressor) return;
    const hsize_t n = static_cast<hsize_t>(particles);
    std::vector<CompressedChunk> chunks = compressor->take(wait);
    std::vector<std::pair<CompressedChunk, CompressedChunk>> whole;  // (positions, velocities)
    for (CompressedChunk& c : chunks) {
      if (c.index % 2 == 0) {  // positions: held until the frame's velocities are done too
        held_positions = std::move(c);
        continue;
      }
      whole.emplace_back(std::move(*held_positions), std::move(c));
      held_positions.reset();
    }
    if (whole.empty()) return;
    const hsize_t size[3] = {frames + whole.size(), n, 3};
    frame_positions->extend(size);
    frame_velocities->extend(size);
    auto store = [&](H5::DataSet& ds, const CompressedChunk& c) {
      const hsize_t offset[3] = {static_cast<hsize_t>(c.index / 2), 0, 0};
      // Filter mask: 0 = the dataset's deflate filter was applied; bit 0 set = it was skipped.
      if (H5Dwrite_chunk(ds.getId(), H5P_DEFAULT, c.deflated ? 0u : 1u, offset, c.bytes.size(), c.bytes.data()) < 0)
        fail(path, "cannot write a frame's chunk");
    };
    std::vector<double> times;
    for (const auto& [positions, velocities] : whole) {
      store(*frame_positions, positions);
      store(*frame_velocities, velocities);
      times.push_back(frame_times_queued.front());
      frame_times_queued.pop_front();
    }
    append_rows(*frame_time, frames, times.size(), {}, times.data(), H5::PredType::NATIVE_DOUBLE);
    dirty = true;
  }

  double elapsed() const { return std::chrono::duration<double>(Clock::now() - started).count(); }

  // Writes the buffered rows, flushes the library and publishes the working copy at `path`;
  // PublishNext::Last when only closing the file follows (shadow_file.hpp).
  void publish(bool durable, PublishNext next = PublishNext::Working) {
    if (broken) fail(path, "an earlier publish failed: the file stays as it was then");
    const Clock::time_point t0 = Clock::now();
    write_pending();
    store_frames(durable);
    root.steps_completed = last_step;
    put_root(*file, root, "steps_completed");
    if (!durable) {
      root.wall_time = elapsed();
      put_root(*file, root, "wall_time");
    }
    file->flush(H5F_SCOPE_GLOBAL);
    try {
      shadow_publish(file->getId(), path, durable, next, &disk);
    } catch (...) {
      broken = true;
      throw;
    }
    dirty = false;
    last_publish = Clock::now();
    last_publish_cost = std::chrono::duration<double>(last_publish - t0).count();
  }

  void maybe_publish() {
    const double since = std::chrono::duration<double>(Clock::now() - last_publish).count();
    if (since >= std::max(flush_every, kPublishShare * last_publish_cost)) publish(false);
  }

  // Closes the library's file and removes the working copy (left only where the last publish
  // did not happen or failed); the lock goes last.
  void close() {
    closed = true;
    compressor.reset();  // joins the worker
    series.clear();
    frame_time.reset();
    frame_positions.reset();
    frame_velocities.reset();
    try {
      file.reset();
    } catch (...) {
      // The published file is what counts; the working copy is removed below.
    }
    std::error_code ec;
    std::filesystem::remove(shadow_path(path), ec);
    lock.reset();
  }
};

RunFileWriter::RunFileWriter(const std::filesystem::path& path, const RunHeader& header,
                             const Model& model, double flush_every_seconds)
    : impl_(std::make_unique<Impl>()) {
  Impl& w = *impl_;
  w.path = path;
  w.flush_every = flush_every_seconds;
  w.particles = model.particle_count();
  w.groups = model.group_names.size();
  H5::Exception::dontPrint();

  // One writer per path; only a run file may be replaced (checked under the lock).
  w.lock.emplace(path);
  check_output_path(path, header.scenario_file);
  const std::filesystem::path shadow = shadow_path(path);
  for (const std::filesystem::path& leftover : {shadow, std::filesystem::path(path.string() + ".previous")}) {
    // A killed writer's working copy: ours to remove, but only if it is a plain file.
    struct stat st {};
    if (::lstat(leftover.c_str(), &st) != 0) continue;
    if (!S_ISREG(st.st_mode))
      throw OutputRefused("--out " + path.string() + ": " + leftover.string() +
                          " is in the way and is not a regular file: nothing was written");
    ::unlink(leftover.c_str());
  }

  try {
    H5::FileAccPropList fapl;
    if (H5Pset_driver(fapl.getId(), shadow_driver(), nullptr) < 0)
      fail(path, "cannot select the run file's HDF5 driver");
    // The metadata cache: the chunk indexes grow with the run; 4 MiB holds what a flush touches
    // (the default lets the cache grow to 32 MiB).
    H5AC_cache_config_t mdc;
    mdc.version = H5AC__CURR_CACHE_CONFIG_VERSION;
    if (H5Pget_mdc_config(fapl.getId(), &mdc) >= 0) {
      mdc.set_initial_size = true;
      mdc.initial_size = 1 << 20;
      mdc.min_size = 1 << 20;
      mdc.max_size = 4 << 20;
      H5Pset_mdc_config(fapl.getId(), &mdc);
    }
    w.file.emplace(shadow.string(), H5F_ACC_TRUNC, H5::FileCreatPropList::DEFAULT, fapl);
    H5::H5File& file = *w.file;

    // Root attributes (kRoot), then the provenance.
    RunRoot& root = w.root;
    root.format_version = kFormatVersion;
    root.status = to_string(RunStatus::Incomplete);
    root.status_reason = "not finished: the run is still going, or its process ended before finishing";
    root.scenario = header.scenario;
    root.scenario_file = header.scenario_file;
    root.solver = header.solver;
    root.config = header.config;
    root.dt = header.dt;
    root.steps_planned = header.steps_planned;
    root.material = header.material;
    root.provenance = layout::current_provenance();
    for (const layout::AttributeSpec<Root>& a : kRoot) put_root(file, root, a.name);
    layout::write_provenance(file, root.provenance);

    write_model(file, model);
    if (!header.pbd_stiffness.empty()) {
      H5::Group g = file.openGroup("/model");
      h5::write(g, "pbd_stiffness", header.pbd_stiffness, "1",
                "k, PBD's stiffness per projection, that pbd used for each constraint (model "
                "order): " + header.pbd_stiffness_rule);
    }

    // Series.
    H5::Group series_group = file.createGroup("/series");
    for (const SeriesSpec& spec : series_table()) {
      w.series.push_back(create_series(series_group, std::string(spec.name), spec.width,
                                       spec.units, spec.doc, spec.deterministic));
      w.series_names.emplace_back(spec.name);
    }
    for (const GroupSeriesSpec& spec : group_series_table()) {
      for (const std::string& group : model.group_names) {
        std::string name = std::string(spec.prefix) + group;
        std::replace(name.begin(), name.end(), '/', '_');  // '/' would make a path
        if (std::find(w.series_names.begin(), w.series_names.end(), name) != w.series_names.end())
          fail(path, "series name " + name + " (from group \"" + group + "\") is used twice");
        const std::string doc = std::string(spec.doc) + " (group \"" + group + "\")";
        w.series.push_back(create_series(series_group, name, 1, spec.units, doc, true));
        w.series_names.push_back(name);
      }
    }

    // Frames.
    H5::Group frames = file.createGroup("/frames");
    {
      const hsize_t dims[1] = {0}, maxdims[1] = {H5S_UNLIMITED}, chunk[1] = {kChunkRows};
      H5::DSetCreatPropList props;
      props.setChunk(1, chunk);
      w.frame_time.emplace(frames.createDataSet("time", H5::PredType::IEEE_F64LE,
                                                H5::DataSpace(1, dims, maxdims), props,
                                                small_chunk_cache(kChunkRows * sizeof(double))));
      set_attr(*w.frame_time, "units", "s");
      set_attr(*w.frame_time, "doc", "simulated time of each frame");
    }
    {
      const hsize_t n = static_cast<hsize_t>(w.particles);
      const hsize_t dims[3] = {0, n, 3};
      const hsize_t maxdims[3] = {H5S_UNLIMITED, n > 0 ? n : H5S_UNLIMITED, 3};
      const hsize_t chunk[3] = {1, std::max<hsize_t>(n, 1), 3};
      H5::DSetCreatPropList props;
      props.setChunk(3, chunk);
      props.setDeflate(kGzipLevel);
      w.frame_positions.emplace(frames.createDataSet("positions", H5::PredType::IEEE_F64LE,
                                                     H5::DataSpace(3, dims, maxdims), props,
                                                     small_chunk_cache(static_cast<size_t>(chunk[1]) * 3 * sizeof(double))));
      set_attr(*w.frame_positions, "units", "m");
      set_attr(*w.frame_positions, "doc", "particle positions of each frame, (frames, n, 3)");
      w.frame_velocities.emplace(frames.createDataSet("velocities", H5::PredType::IEEE_F64LE,
                                                      H5::DataSpace(3, dims, maxdims), props,
                                                      small_chunk_cache(static_cast<size_t>(chunk[1]) * 3 * sizeof(double))));
      set_attr(*w.frame_velocities, "units", "m/s");
      set_attr(*w.frame_velocities, "doc", "particle velocities of each frame, (frames, n, 3) (NaN where not given)");
      if (n > 0) w.compressor = std::make_unique<FrameCompressor>(kGzipLevel);
    }
  } catch (const H5::Exception& e) {
    fail(path, "cannot create the HDF5 file: " + h5_message(e));
  }
  w.dirty = true;
  try {
    w.publish(false);
  } catch (const H5::Exception& e) {
    fail(path, "cannot write the HDF5 file: " + h5_message(e));
  }
}

RunFileWriter::~RunFileWriter() {
  if (!impl_ || impl_->closed) return;
  try {
    impl_->root.status_reason = "the writer was closed before the run finished";
    put_root(*impl_->file, impl_->root, "status_reason");
    impl_->dirty = true;
    impl_->publish(false, PublishNext::Last);
  } catch (...) {
    // Nothing to report from a destructor: the file on disk keeps its last published image,
    // which says "incomplete".
  }
  try {
    impl_->close();
  } catch (...) {
  }
}

void RunFileWriter::append(const SeriesRow& row) {
  Impl& w = *impl_;
  if (w.closed) throw std::logic_error("run file " + w.path.string() + ": append() after finish()");
  if (!row.sample || !row.report)
    throw std::invalid_argument("run file " + w.path.string() +
                                ": append() needs a row with a sample and a report");
  double values[3];
  size_t k = 0;
  for (const SeriesSpec& spec : series_table()) {
    spec.read(row, values);
    std::vector<double>& pending = w.series[k++].pending;
    pending.insert(pending.end(), values, values + spec.width);
  }
  for (const GroupSeriesSpec& spec : group_series_table()) {
    for (size_t g = 0; g < w.groups; ++g) {
      const double v = g < row.sample->groups.size() ? spec.read(row.sample->groups[g])
                                                     : std::numeric_limits<double>::quiet_NaN();
      w.series[k++].pending.push_back(v);
    }
  }
  ++w.pending_rows;
  w.last_step = row.step;
  w.dirty = true;
  try {
    if (w.pending_rows >= kMaxPendingRows) w.write_pending();  // into the working copy
    w.maybe_publish();
  } catch (const H5::Exception& e) {
    fail(w.path, "cannot write series: " + h5_message(e));
  }
}

void RunFileWriter::append_frame(double time, const Points& x, const Points* v) {
  Impl& w = *impl_;
  if (w.closed)
    throw std::logic_error("run file " + w.path.string() + ": append_frame() after finish()");
  if (x.rows() != w.particles)
    throw std::invalid_argument("run file " + w.path.string() + ": a frame of " +
                                std::to_string(x.rows()) + " particles, the model has " +
                                std::to_string(w.particles));
  try {
    // Rows and frames reach the published image together: publish() writes the pending rows
    // before it stores the finished frames, so a frame is never published ahead of its row.
    if (w.particles == 0) {
      w.write_pending();  // rows up to the frame reach the image no later than the frame
      append_rows(*w.frame_time, w.frames, 1, {}, &time, H5::PredType::NATIVE_DOUBLE);
    } else {
      // Points are row-major (n x 3), the chunk's layout; stored little-endian as on this machine.
      static_assert(Points::IsRowMajor, "a frame chunk is the points' memory as it is");
      static_assert(std::endian::native == std::endian::little, "the frames' file type is IEEE_F64LE");
      const size_t bytes = static_cast<size_t>(w.particles) * 3 * sizeof(double);
      if (v != nullptr && v->rows() == x.rows()) {
        w.compressor->submit({x.data(), v->data()}, bytes);
      } else {
        const Points nan = Points::Constant(x.rows(), 3, std::numeric_limits<double>::quiet_NaN());
        w.compressor->submit({x.data(), nan.data()}, bytes);
      }
      w.frame_times_queued.push_back(time);
      // Stored in batches of up to kMaxFramesQueued frames (HDF5's per-call costs once per
      // batch); past that the writer waits for the worker.
      if (w.compressor->outstanding() >= 2 * Impl::kMaxFramesQueued)
        w.store_frames(w.compressor->outstanding() > 2 * Impl::kMaxFramesQueued);
    }
    w.dirty = true;
    w.maybe_publish();
  } catch (const H5::Exception& e) {
    fail(w.path, "cannot write a frame: " + h5_message(e));
  }
}

void RunFileWriter::flush() {
  Impl& w = *impl_;
  if (w.closed || !w.dirty) return;
  try {
    w.publish(false);
  } catch (const H5::Exception& e) {
    fail(w.path, "cannot flush: " + h5_message(e));
  }
}

void RunFileWriter::set_warnings(const std::vector<std::string>& lines) {
  Impl& w = *impl_;
  if (w.closed) throw std::logic_error("run file " + w.path.string() + ": set_warnings() after finish()");
  try {
    w.root.warnings = layout::join_lines(lines);
    w.root.warning_count = static_cast<long long>(lines.size());
    put_root(*w.file, w.root, "warnings");
    put_root(*w.file, w.root, "warning_count");
    w.dirty = true;
  } catch (const H5::Exception& e) {
    fail(w.path, "cannot write the warnings: " + h5_message(e));
  }
}

void RunFileWriter::finish(RunStatus status, const std::string& reason, long steps_completed,
                           double wall_time, long exploded_step, double exploded_time) {
  Impl& w = *impl_;
  if (w.closed) throw std::logic_error("run file " + w.path.string() + ": finish() called twice");
  try {
    w.last_step = steps_completed;
    RunRoot& root = w.root;
    root.status = to_string(status);
    root.status_reason = reason;
    root.wall_time = wall_time;
    root.exploded_step = exploded_step;
    root.exploded_time = exploded_time;
    for (const char* name : {"status", "status_reason", "wall_time", "exploded_step", "exploded_time"})
      put_root(*w.file, root, name);
    w.publish(true, PublishNext::Last);
    w.close();
  } catch (const H5::Exception& e) {
    fail(w.path, "cannot finish: " + h5_message(e));
  }
}

// ---------------------------------------------------------------------------------------------
// Reader.

namespace {

// /frames: the times, and the positions and velocities of every frame or of the last.
void read_frames(const H5::Group& g, RunFileParts::Frames which, bool velocities, RunFileData& data) {
  if (g.nameExists("time")) data.frame_time = h5::read_doubles(g.openDataSet("time"));
  data.has_velocities = g.nameExists("velocities");
  for (auto [name, out] : {std::pair{"positions", &data.frames}, std::pair{"velocities", &data.velocities}}) {
    if (!g.nameExists(name) || (out == &data.velocities && !velocities)) continue;
    const H5::DataSet ds = g.openDataSet(name);
    H5::DataSpace space = ds.getSpace();
    hsize_t dims[3] = {0, 0, 0};
    if (space.getSimpleExtentNdims() != 3) throw std::runtime_error(std::string("/frames/") + name + " is not 3-D");
    space.getSimpleExtentDims(dims);
    if (dims[2] != 3) throw std::runtime_error(std::string("/frames/") + name + " is not (F, n, 3)");
    if (dims[0] != data.frame_time.size())
      throw std::runtime_error(std::to_string(data.frame_time.size()) + " frame times for " +
                               std::to_string(dims[0]) + " frames of " + name);
    const hsize_t first = which == RunFileParts::Frames::Last && dims[0] > 0 ? dims[0] - 1 : 0;
    const hsize_t count[3] = {dims[0] - first, dims[1], 3}, start[3] = {first, 0, 0};
    if (count[0] == 0) continue;
    std::vector<double> x(static_cast<size_t>(count[0] * count[1] * 3));
    space.selectHyperslab(H5S_SELECT_SET, count, start);
    const H5::DataSpace mem(3, count);
    ds.read(x.data(), H5::PredType::NATIVE_DOUBLE, mem, space);
    const hsize_t n = dims[1];
    for (hsize_t f = 0; f < count[0]; ++f) {
      Points p(static_cast<Eigen::Index>(n), 3);
      std::copy(x.begin() + static_cast<long>(f * n * 3), x.begin() + static_cast<long>((f + 1) * n * 3), p.data());
      out->push_back(std::move(p));
    }
  }
}

}  // namespace

RunFileData read_run_file(const std::filesystem::path& path, bool with_series) {
  RunFileParts parts;
  parts.series = with_series;
  return read_run_file(path, parts);
}

RunFileData read_run_file(const std::filesystem::path& path, const RunFileParts& parts) {
  H5::Exception::dontPrint();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(path, "no such file");
  RunFileData data;
  try {
    H5::H5File file(path.string(), H5F_ACC_RDONLY);
    h5::read_attributes(file, data.attributes, data.numbers);
    layout::read_attributes(file, kRoot, data.root);
    data.root.provenance = layout::read_provenance(file);

    if (file.nameExists("/model")) {
      H5::Group model = file.openGroup("/model");
      if (model.attrExists("group_names")) data.group_names = h5::read_strings(model.openAttribute("group_names"));
      if (parts.model) {
        read_model(model, data.model);
        data.model.group_names = data.group_names;
        if (model.nameExists("pbd_stiffness"))
          data.pbd_stiffness = h5::read_doubles(model.openDataSet("pbd_stiffness"));
      }
    }

    if (parts.series && file.nameExists("/series")) {
      H5::Group group = file.openGroup("/series");
      const hsize_t count = group.getNumObjs();
      for (hsize_t i = 0; i < count; ++i) {
        const std::string name = group.getObjnameByIdx(i);
        if (group.childObjType(name) != H5O_TYPE_DATASET) continue;
        H5::DataSet ds = group.openDataSet(name);
        H5::DataSpace space = ds.getSpace();
        const int rank = space.getSimpleExtentNdims();
        hsize_t dims[2] = {0, 0};
        if (rank < 1 || rank > 2) continue;
        space.getSimpleExtentDims(dims);
        if (rank == 1) {
          std::vector<double> values(dims[0]);
          if (dims[0] > 0) ds.read(values.data(), H5::PredType::NATIVE_DOUBLE);
          data.series[name] = std::move(values);
        } else if (dims[1] == 3) {
          Points values(static_cast<Eigen::Index>(dims[0]), 3);
          if (dims[0] > 0) ds.read(values.data(), H5::PredType::NATIVE_DOUBLE);
          data.series3[name] = std::move(values);
        } else {
          continue;
        }
        if (ds.attrExists("units")) data.units[name] = h5::get_string(ds, "units");
        if (ds.attrExists("doc")) data.docs[name] = h5::get_string(ds, "doc");
        if (ds.attrExists("deterministic")) {
          int deterministic = 1;
          ds.openAttribute("deterministic").read(H5::PredType::NATIVE_INT, &deterministic);
          if (deterministic == 0) data.nondeterministic.insert(name);
        }
      }
    }

    if (parts.frames != RunFileParts::Frames::None && file.nameExists("/frames"))
      read_frames(file.openGroup("/frames"), parts.frames, parts.velocities, data);
  } catch (const H5::Exception& e) {
    fail(path, "cannot read: " + h5_message(e));
  } catch (const std::runtime_error& e) {
    fail(path, e.what());
  }
  return data;
}

namespace {

// 64-bit FNV-1a.
struct Fnv {
  std::uint64_t h = 1469598103934665603ull;
  void add(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) {
      h ^= p[i];
      h *= 1099511628211ull;
    }
  }
};

}  // namespace

std::string state_hash(const RunFileData& data) {
  Fnv fnv;
  for (const SeriesSpec& s : series_table()) {
    if (!s.deterministic) continue;
    const std::string name(s.name);
    if (auto it = data.series.find(name); it != data.series.end())
      fnv.add(it->second.data(), it->second.size() * sizeof(double));
    if (auto it = data.series3.find(name); it != data.series3.end())
      fnv.add(it->second.data(), static_cast<size_t>(it->second.size()) * sizeof(double));
  }
  if (!data.frames.empty()) {
    const Points& last = data.frames.back();
    fnv.add(last.data(), static_cast<size_t>(last.size()) * sizeof(double));
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv.h));
  return hex;
}

std::string state_hash(const std::filesystem::path& path) {
  RunFileParts parts;
  parts.frames = RunFileParts::Frames::Last;
  return state_hash(read_run_file(path, parts));
}

std::vector<AttributeInfo> run_root_attributes() {
  std::vector<AttributeInfo> out;
  layout::describe(kRoot, out);
  for (AttributeInfo& a : provenance_attributes()) out.push_back(std::move(a));
  return out;
}

// ---------------------------------------------------------------------------------------------
// Frames one at a time (frame_reader.hpp).

std::vector<double> for_each_frame(const std::filesystem::path& path, bool velocities, const FrameVisitor& visit) {
  H5::Exception::dontPrint();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(path, "no such file");
  std::vector<double> times;
  std::optional<H5::H5File> file;
  std::optional<H5::DataSet> sets[2];  // positions, velocities
  H5::DataSpace spaces[2];
  hsize_t n = 0;
  try {
    file.emplace(path.string(), H5F_ACC_RDONLY);
    if (!file->nameExists("/frames")) return times;
    const H5::Group g = file->openGroup("/frames");
    if (g.nameExists("time")) times = h5::read_doubles(g.openDataSet("time"));
    const char* names[2] = {"positions", "velocities"};
    for (int k = 0; k < 2; ++k) {
      if (!g.nameExists(names[k]) || (k == 1 && !velocities)) continue;
      sets[k].emplace(g.openDataSet(names[k]));
      spaces[k] = sets[k]->getSpace();
      hsize_t dims[3] = {0, 0, 0};
      if (spaces[k].getSimpleExtentNdims() != 3) fail(path, std::string("/frames/") + names[k] + " is not 3-D");
      spaces[k].getSimpleExtentDims(dims);
      if (dims[2] != 3) fail(path, std::string("/frames/") + names[k] + " is not (F, n, 3)");
      if (dims[0] != times.size())
        fail(path, std::to_string(times.size()) + " frame times for " + std::to_string(dims[0]) + " frames of " + names[k]);
      if (k == 1 && dims[1] != n) fail(path, "/frames/velocities and /frames/positions differ in their particles");
      n = dims[1];
    }
  } catch (const H5::Exception& e) {
    fail(path, "cannot read: " + h5_message(e));
  }
  if (!sets[0]) return times;
  Points x(static_cast<Eigen::Index>(n), 3), v(static_cast<Eigen::Index>(n), 3);
  for (std::size_t f = 0; f < times.size(); ++f) {
    try {
      for (int k = 0; k < 2; ++k) {
        if (!sets[k] || n == 0) continue;
        const hsize_t count[3] = {1, n, 3}, start[3] = {f, 0, 0};
        spaces[k].selectHyperslab(H5S_SELECT_SET, count, start);
        const H5::DataSpace mem(3, count);
        sets[k]->read(k == 0 ? x.data() : v.data(), H5::PredType::NATIVE_DOUBLE, mem, spaces[k]);
      }
    } catch (const H5::Exception& e) {
      fail(path, "cannot read frame " + std::to_string(f) + ": " + h5_message(e));
    }
    visit(f, times[f], x, sets[1] ? &v : nullptr);
  }
  return times;
}

}  // namespace pbdbench
