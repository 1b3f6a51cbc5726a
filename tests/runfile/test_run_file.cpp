// Tests of runfile/run_file: a file written from a hand-made model and rows reads back with every
// attribute, series, frame and model array; the status goes incomplete -> complete / exploded,
// and stays incomplete when the writer is destroyed without finish(); errors name the path.
#include "runfile/run_file.hpp"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/resource.h>

#include <csignal>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <map>
#include <string>
#include <vector>

#include "runfile/build_info.hpp"
#include "tests/runfile/fixture_model.hpp"
#include "tests/runfile/test_support.hpp"

namespace pbdbench {
namespace {

namespace fs = std::filesystem;

using test::temp_dir;

using test::fixture_header;

// Appends rows 0..rows-1 made by the fixture functions.
void append_rows(RunFileWriter& w, const Model& m, long first, long rows) {
  for (long r = first; r < first + rows; ++r) {
    const Sample s = test::fixture_sample(r, m.group_names.size());
    const StepReport rep = test::fixture_report(r);
    w.append(SeriesRow{0.01 * static_cast<double>(r), r, 1e-5 * static_cast<double>(r), &s, &rep});
  }
}

// ---------------------------------------------------------------------------------------------
// Reading what read_run_file does not return (frames, model arrays, dataset attributes) with the
// HDF5 C API directly.

struct H5Handle {
  hid_t id;
  herr_t (*close)(hid_t);
  ~H5Handle() {
    if (id >= 0) close(id);
  }
};

std::vector<hsize_t> dims_of(hid_t file, const char* name) {
  H5Handle ds{H5Dopen2(file, name, H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) return {};
  H5Handle space{H5Dget_space(ds.id), H5Sclose};
  std::vector<hsize_t> dims(static_cast<size_t>(H5Sget_simple_extent_ndims(space.id)));
  H5Sget_simple_extent_dims(space.id, dims.data(), nullptr);
  return dims;
}

template <class T>
std::vector<T> read_all(hid_t file, const char* name, hid_t mem_type) {
  H5Handle ds{H5Dopen2(file, name, H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) return {};
  H5Handle space{H5Dget_space(ds.id), H5Sclose};
  std::vector<T> out(static_cast<size_t>(H5Sget_simple_extent_npoints(space.id)));
  if (!out.empty()) H5Dread(ds.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data());
  return out;
}

// A scalar string attribute, with whether it is a variable-length UTF-8 string.
std::string string_attr(hid_t obj, const char* name, bool* vlen_utf8 = nullptr) {
  H5Handle attr{H5Aopen(obj, name, H5P_DEFAULT), H5Aclose};
  if (attr.id < 0) return "<missing>";
  H5Handle type{H5Aget_type(attr.id), H5Tclose};
  if (vlen_utf8)
    *vlen_utf8 = H5Tis_variable_str(type.id) > 0 && H5Tget_cset(type.id) == H5T_CSET_UTF8;
  H5Handle mem{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(mem.id, H5T_VARIABLE);
  H5Tset_cset(mem.id, H5T_CSET_UTF8);
  char* value = nullptr;
  if (H5Aread(attr.id, mem.id, &value) < 0) return "<unreadable>";
  std::string out = value ? value : "";
  H5free_memory(value);
  return out;
}

std::vector<std::string> string_list_attr(hid_t obj, const char* name) {
  H5Handle attr{H5Aopen(obj, name, H5P_DEFAULT), H5Aclose};
  if (attr.id < 0) return {"<missing>"};
  H5Handle space{H5Aget_space(attr.id), H5Sclose};
  H5Handle mem{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(mem.id, H5T_VARIABLE);
  H5Tset_cset(mem.id, H5T_CSET_UTF8);
  std::vector<char*> buf(static_cast<size_t>(H5Sget_simple_extent_npoints(space.id)));
  std::vector<std::string> out;
  if (!buf.empty() && H5Aread(attr.id, mem.id, buf.data()) >= 0) {
    for (char* s : buf) out.emplace_back(s);
    H5Dvlen_reclaim(mem.id, space.id, H5P_DEFAULT, buf.data());
  }
  return out;
}

long long int_attr(hid_t obj, const char* name) {
  H5Handle attr{H5Aopen(obj, name, H5P_DEFAULT), H5Aclose};
  long long v = -12345;
  if (attr.id >= 0) H5Aread(attr.id, H5T_NATIVE_LLONG, &v);
  return v;
}

// ---------------------------------------------------------------------------------------------

TEST(runfile_file, RoundTrip) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  const RunHeader h = fixture_header();
  constexpr long kRows = 300;  // more than one chunk of 256 rows
  {
    RunFileWriter w(path, h, m, 0.0);
    append_rows(w, m, 0, kRows);
    w.append_frame(0.0, test::fixture_frame(m, 0));
    w.append_frame(0.5, test::fixture_frame(m, 1));
    w.append_frame(1.0, test::fixture_frame(m, 2));
    w.finish(RunStatus::Complete, "reached steps_planned", kRows - 1, 1.25);
  }

  const RunFileData d = read_run_file(path);
  // String attributes.
  EXPECT_EQ(d.status(), "complete");
  EXPECT_EQ(d.attributes.at("status_reason"), "reached steps_planned");
  EXPECT_EQ(d.attributes.at("scenario"), "fixture");
  EXPECT_EQ(d.attributes.at("scenario_file"), "scenarios/fixture.toml");
  EXPECT_EQ(d.attributes.at("solver"), "xpbd");
  EXPECT_EQ(d.attributes.at("config"), h.config);
  EXPECT_TRUE(std::regex_match(d.attributes.at("created"),
                               std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)")))
      << d.attributes.at("created");
  const BuildInfo& b = build_info();
  EXPECT_EQ(d.attributes.at("pbdbench_version"), b.version);
  EXPECT_EQ(d.attributes.at("git_commit"), b.git_commit);
  EXPECT_EQ(d.attributes.at("compiler"), b.compiler);
  EXPECT_EQ(d.attributes.at("build_type"), b.build_type);
  EXPECT_EQ(d.attributes.at("cxx_flags"), b.cxx_flags);
  const std::set<std::string> strings = {"status", "status_reason", "scenario", "scenario_file",
                                         "solver", "config", "created", "pbdbench_version",
                                         "git_commit", "compiler", "build_type", "cxx_flags",
                                         "warnings", "material"};
  for (const auto& [name, value] : d.attributes)
    EXPECT_TRUE(strings.count(name)) << "unexpected string attribute " << name;
  EXPECT_EQ(d.attributes.size(), strings.size());
  // Numeric attributes.
  const std::map<std::string, double> numbers = {
      {"format_version", 1}, {"dt", 0.01}, {"steps_planned", 100},
      {"steps_completed", kRows - 1}, {"wall_time", 1.25}, {"exploded_step", -1},
      {"exploded_time", -1.0}, {"warning_count", 0}};
  EXPECT_EQ(d.numbers, numbers);
  EXPECT_EQ(d.attributes.at("warnings"), "");
  EXPECT_TRUE(d.warnings().empty());
  EXPECT_EQ(d.group_names, m.group_names);

  // Series: every table entry, plus one per group and group series.
  size_t expected_count = 0;
  for (const SeriesSpec& spec : series_table()) {
    const std::string name(spec.name);
    ++expected_count;
    if (spec.width == 1) {
      ASSERT_TRUE(d.series.count(name)) << name;
      ASSERT_EQ(d.series.at(name).size(), static_cast<size_t>(kRows)) << name;
    } else {
      ASSERT_TRUE(d.series3.count(name)) << name;
      ASSERT_EQ(d.series3.at(name).rows(), kRows) << name;
    }
  }
  for (const GroupSeriesSpec& g : group_series_table())
    for (const std::string& group : m.group_names) {
      ASSERT_TRUE(d.series.count(std::string(g.prefix) + group)) << g.prefix << group;
      ++expected_count;
    }
  EXPECT_EQ(d.series.size() + d.series3.size(), expected_count);

  for (long r = 0; r < kRows; ++r) {
    const size_t i = static_cast<size_t>(r);
    const double x = static_cast<double>(r);
    ASSERT_EQ(d.series.at("time")[i], 0.01 * x);
    ASSERT_EQ(d.series.at("step")[i], x);
    ASSERT_EQ(d.series.at("kinetic_energy")[i], 0.5 * x);
    ASSERT_EQ(d.series.at("penetration_count")[i], static_cast<double>(r % 5));
    ASSERT_EQ(d.series.at("wall_step")[i], 1e-5 * x);
    ASSERT_EQ(d.series3.at("linear_momentum").row(r), Vec3(x, 2 * x, 3 * x).transpose());
    ASSERT_EQ(d.series3.at("angular_momentum")(r, 2), -3 * x);
    ASSERT_EQ(d.series3.at("tip_displacement").row(r), Vec3(0.0, -1e-3 * x, 0.0).transpose());
    ASSERT_EQ(d.series3.at("support_force")(r, 1), 9.81 + 1e-2 * x);
    ASSERT_EQ(d.series.at("pendulum_angle")[i], std::sin(0.1 * x));
    // Group series: group g has max 1e-3 (r+1) (g+1), rms 1e-4 (r+1) (g+1).
    ASSERT_EQ(d.series.at("constraint_error_max_volume")[i], 1e-3 * (x + 1) * 2);
    ASSERT_EQ(d.series.at("constraint_error_rms_bending")[i], 1e-4 * (x + 1) * 3);
  }
  // The initial row's report is a default StepReport: NaN residuals, zero counts.
  EXPECT_TRUE(std::isnan(d.series.at("residual_g")[0]));
  EXPECT_EQ(d.series.at("iterations")[0], 0.0);
  EXPECT_EQ(d.series.at("iterations")[1], 10.0);

  // What read_run_file does not return: layout, dataset attributes, frames, model.
  H5Handle f{H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(f.id, 0);
  bool vlen = false;
  EXPECT_EQ(string_attr(f.id, "status", &vlen), "complete");
  EXPECT_TRUE(vlen) << "string attributes must be variable-length UTF-8 (h5py reads them as str)";
  for (const SeriesSpec& spec : series_table()) {
    const std::string name = "/series/" + std::string(spec.name);
    H5Handle ds{H5Dopen2(f.id, name.c_str(), H5P_DEFAULT), H5Dclose};
    ASSERT_GE(ds.id, 0) << name;
    EXPECT_EQ(string_attr(ds.id, "units", &vlen), spec.units) << name;
    EXPECT_TRUE(vlen) << name;
    EXPECT_EQ(string_attr(ds.id, "doc"), spec.doc) << name;
    EXPECT_EQ(int_attr(ds.id, "deterministic"), spec.deterministic ? 1 : 0) << name;
    H5Handle space{H5Dget_space(ds.id), H5Sclose};
    hsize_t dims[2], maxdims[2];
    const int rank = H5Sget_simple_extent_dims(space.id, dims, maxdims);
    ASSERT_EQ(rank, spec.width == 1 ? 1 : 2) << name;
    EXPECT_EQ(maxdims[0], H5S_UNLIMITED) << name;
    if (rank == 2) {
      EXPECT_EQ(dims[1], 3u) << name;
    }
    H5Handle dcpl{H5Dget_create_plist(ds.id), H5Pclose};
    EXPECT_EQ(H5Pget_layout(dcpl.id), H5D_CHUNKED) << name;
  }
  {
    H5Handle ds{H5Dopen2(f.id, "/series/constraint_error_max_stretch", H5P_DEFAULT), H5Dclose};
    EXPECT_EQ(string_attr(ds.id, "units"), "1");
    EXPECT_EQ(int_attr(ds.id, "deterministic"), 1);
  }

  // Frames.
  EXPECT_EQ(dims_of(f.id, "/frames/time"), (std::vector<hsize_t>{3}));
  EXPECT_EQ(read_all<double>(f.id, "/frames/time", H5T_NATIVE_DOUBLE),
            (std::vector<double>{0.0, 0.5, 1.0}));
  EXPECT_EQ(dims_of(f.id, "/frames/positions"), (std::vector<hsize_t>{3, 4, 3}));
  const auto pos = read_all<double>(f.id, "/frames/positions", H5T_NATIVE_DOUBLE);
  ASSERT_EQ(pos.size(), 36u);
  for (long fr = 0; fr < 3; ++fr) {
    const Points expect = test::fixture_frame(m, fr);
    for (int p = 0; p < 4; ++p)
      for (int k = 0; k < 3; ++k)
        EXPECT_EQ(pos[static_cast<size_t>(fr * 12 + p * 3 + k)], expect(p, k));
  }
  {
    H5Handle ds{H5Dopen2(f.id, "/frames/positions", H5P_DEFAULT), H5Dclose};
    H5Handle dcpl{H5Dget_create_plist(ds.id), H5Pclose};
    hsize_t chunk[3] = {0, 0, 0};
    ASSERT_EQ(H5Pget_chunk(dcpl.id, 3, chunk), 3);
    EXPECT_EQ(chunk[0], 1u);
    EXPECT_EQ(chunk[1], 4u);
    EXPECT_EQ(chunk[2], 3u);
    std::vector<H5Z_filter_t> filters;
    for (int i = 0; i < H5Pget_nfilters(dcpl.id); ++i) {
      unsigned flags = 0, values[4];
      size_t nvalues = 4;
      filters.push_back(H5Pget_filter2(dcpl.id, static_cast<unsigned>(i), &flags, &nvalues,
                                       values, 0, nullptr, nullptr));
      if (filters.back() == H5Z_FILTER_DEFLATE) {
        ASSERT_GE(nvalues, 1u);
        EXPECT_EQ(values[0], 1u) << "gzip level";
      }
    }
    // Deflate alone: the chunks are deflated by runfile/frame_compressor.hpp's worker and stored
    // with H5Dwrite_chunk, so the pipeline declared here is what a reader undoes.
    EXPECT_EQ(filters, (std::vector<H5Z_filter_t>{H5Z_FILTER_DEFLATE}));
    EXPECT_EQ(string_attr(ds.id, "units"), "m");
  }

  // Model.
  EXPECT_EQ(dims_of(f.id, "/model/rest_positions"), (std::vector<hsize_t>{4, 3}));
  EXPECT_EQ(read_all<double>(f.id, "/model/rest_positions", H5T_NATIVE_DOUBLE),
            (std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(read_all<double>(f.id, "/model/inv_mass", H5T_NATIVE_DOUBLE), m.inv_mass);
  EXPECT_EQ(read_all<double>(f.id, "/model/radius", H5T_NATIVE_DOUBLE), m.radius);
  EXPECT_EQ(read_all<double>(f.id, "/model/gravity", H5T_NATIVE_DOUBLE),
            (std::vector<double>{0.0, -9.81, 0.0}));
  EXPECT_EQ(dims_of(f.id, "/model/edges"), (std::vector<hsize_t>{6, 2}));
  EXPECT_EQ(read_all<int>(f.id, "/model/edges", H5T_NATIVE_INT),
            (std::vector<int>{0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3}));
  EXPECT_EQ(dims_of(f.id, "/model/triangles"), (std::vector<hsize_t>{4, 3}));
  EXPECT_EQ(read_all<int>(f.id, "/model/triangles", H5T_NATIVE_INT),
            (std::vector<int>{0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}));
  EXPECT_EQ(dims_of(f.id, "/model/tets"), (std::vector<hsize_t>{1, 4}));
  EXPECT_EQ(read_all<int>(f.id, "/model/tets", H5T_NATIVE_INT), (std::vector<int>{0, 1, 2, 3}));
  {
    H5Handle ds{H5Dopen2(f.id, "/model/constraint_kind", H5P_DEFAULT), H5Dclose};
    H5Handle type{H5Dget_type(ds.id), H5Tclose};
    EXPECT_EQ(H5Tget_class(type.id), H5T_INTEGER);
    EXPECT_EQ(H5Tget_size(type.id), 1u) << "constraint_kind is int8";
    EXPECT_EQ(string_list_attr(ds.id, "kind_names"),
              (std::vector<std::string>{"distance", "volume", "bending", "fem_deviatoric", "fem_hydrostatic",
                                        "fem_strain_triangle", "fem_strain_tet"}));
  }
  EXPECT_EQ(read_all<int>(f.id, "/model/constraint_kind", H5T_NATIVE_INT),
            (std::vector<int>{0, 0, 0, 0, 0, 0, 1, 2}));
  EXPECT_EQ(dims_of(f.id, "/model/constraint_particles"), (std::vector<hsize_t>{8, 4}));
  const auto cp = read_all<int>(f.id, "/model/constraint_particles", H5T_NATIVE_INT);
  ASSERT_EQ(cp.size(), 32u);
  EXPECT_EQ(std::vector<int>(cp.begin(), cp.begin() + 4), (std::vector<int>{0, 1, -1, -1}));
  EXPECT_EQ(std::vector<int>(cp.begin() + 28, cp.end()), (std::vector<int>{1, 2, 0, 3}));
  std::vector<double> rest, compliance, stiffness, damping;
  std::vector<int> group;
  for (const Constraint& c : m.constraints) {
    rest.push_back(c.rest);
    compliance.push_back(c.compliance);
    stiffness.push_back(c.stiffness);
    damping.push_back(c.damping);
    group.push_back(c.group);
  }
  EXPECT_EQ(read_all<double>(f.id, "/model/constraint_rest", H5T_NATIVE_DOUBLE), rest);
  EXPECT_EQ(read_all<double>(f.id, "/model/constraint_compliance", H5T_NATIVE_DOUBLE), compliance);
  EXPECT_EQ(read_all<double>(f.id, "/model/constraint_stiffness", H5T_NATIVE_DOUBLE), stiffness);
  EXPECT_EQ(read_all<double>(f.id, "/model/constraint_damping", H5T_NATIVE_DOUBLE), damping);
  EXPECT_EQ(read_all<int>(f.id, "/model/constraint_group", H5T_NATIVE_INT), group);
  {
    H5Handle model{H5Gopen2(f.id, "/model", H5P_DEFAULT), H5Gclose};
    EXPECT_EQ(string_list_attr(model.id, "group_names"), m.group_names);
  }

  // No temporary file is left behind.
  EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
}

// The root attributes are declared once (run_file.cpp kRoot, then the provenance):
// every attribute the writer writes, in a run that goes through warnings and an explosion, is in
// run_root_attributes() with the HDF5 type the table gives, every row of the table is written,
// the reader returns each in RunFileData::root, and results/README.md carries the table.
TEST(runfile_file, RootAttributesAreTheDeclaredTable) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  RunHeader h = fixture_header();
  h.material = "bars (3 x distance): alpha = 0.001";
  {
    RunFileWriter w(path, h, m, 0.0);
    append_rows(w, m, 0, 5);
    w.set_warnings({"energy_gain @4 (t = 0.04 s): 3 J", "volume @2 (t = 0.02 s): lost 30 %"});
    w.finish(RunStatus::Exploded, "max speed 2000 m/s", 4, 0.25, 4, 0.04);
  }
  const std::vector<AttributeInfo> table = run_root_attributes();
  std::map<std::string, AttributeType> declared;
  for (const AttributeInfo& a : table) {
    EXPECT_TRUE(declared.emplace(a.name, a.type).second) << a.name << " is declared twice";
    EXPECT_FALSE(a.doc.empty()) << a.name;
  }
  // Every root attribute of the file, with its HDF5 type class.
  std::map<std::string, AttributeType> written;
  {
    H5Handle f{H5Fopen(path.string().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    ASSERT_GE(f.id, 0);
    auto collect = [](hid_t obj, const char* name, const H5A_info_t*, void* out) -> herr_t {
      H5Handle attr{H5Aopen(obj, name, H5P_DEFAULT), H5Aclose};
      H5Handle type{H5Aget_type(attr.id), H5Tclose};
      const H5T_class_t c = H5Tget_class(type.id);
      (*static_cast<std::map<std::string, AttributeType>*>(out))[name] =
          c == H5T_STRING ? AttributeType::Text : c == H5T_INTEGER ? AttributeType::Integer : AttributeType::Real;
      return 0;
    };
    hsize_t index = 0;
    ASSERT_GE(H5Aiterate2(f.id, H5_INDEX_NAME, H5_ITER_INC, &index, collect, &written), 0);
  }
  for (const auto& [name, type] : written) {
    ASSERT_TRUE(declared.count(name)) << "the writer writes the root attribute " << name
                                      << ", which run_root_attributes() does not declare";
    EXPECT_EQ(to_string(type), std::string(to_string(declared.at(name)))) << name;
  }
  for (const AttributeInfo& a : table) EXPECT_TRUE(written.count(a.name)) << a.name << " is not written";

  // The reader returns each.
  const RunFileData d = read_run_file(path, false);
  const RunRoot& r = d.root;
  EXPECT_EQ(r.format_version, 1);
  EXPECT_EQ(r.status, "exploded");
  EXPECT_EQ(r.status_reason, "max speed 2000 m/s");
  EXPECT_EQ(r.scenario, h.scenario);
  EXPECT_EQ(r.scenario_file, h.scenario_file);
  EXPECT_EQ(r.solver, h.solver);
  EXPECT_EQ(r.config, h.config);
  EXPECT_EQ(r.dt, h.dt);
  EXPECT_EQ(r.steps_planned, h.steps_planned);
  EXPECT_EQ(r.material, h.material);
  EXPECT_EQ(r.steps_completed, 4);
  EXPECT_EQ(r.wall_time, 0.25);
  EXPECT_EQ(r.exploded_step, 4);
  EXPECT_EQ(r.exploded_time, 0.04);
  EXPECT_EQ(r.warnings, "energy_gain @4 (t = 0.04 s): 3 J\nvolume @2 (t = 0.02 s): lost 30 %");
  EXPECT_EQ(r.warning_count, 2);
  EXPECT_TRUE(std::regex_match(r.provenance.created, std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)")));
  const BuildInfo& b = build_info();
  EXPECT_EQ(r.provenance.pbdbench_version, b.version);
  EXPECT_EQ(r.provenance.git_commit, b.git_commit);
  EXPECT_EQ(r.provenance.compiler, b.compiler);
  EXPECT_EQ(r.provenance.build_type, b.build_type);
  EXPECT_EQ(r.provenance.cxx_flags, b.cxx_flags);
  // ... and each agrees with the raw maps (the same attributes, read without the table).
  for (const AttributeInfo& a : table) {
    if (a.type == AttributeType::Text)
      EXPECT_TRUE(d.attributes.count(a.name)) << a.name;
    else
      EXPECT_TRUE(d.numbers.count(a.name)) << a.name;
  }
  EXPECT_EQ(d.attributes.at("material"), r.material);
  EXPECT_EQ(d.numbers.at("exploded_step"), static_cast<double>(r.exploded_step));

  // The documentation carries the table verbatim.
  test::expect_readme_carries(attributes_markdown(table), "run_root_attributes()");
}

TEST(runfile_file, WithoutSeries) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter w(path, fixture_header(), m);
    append_rows(w, m, 0, 3);
    w.finish(RunStatus::Complete, "done", 2, 0.1);
  }
  const RunFileData d = read_run_file(path, false);
  EXPECT_TRUE(d.series.empty());
  EXPECT_TRUE(d.series3.empty());
  EXPECT_EQ(d.status(), "complete");
  EXPECT_EQ(d.group_names, m.group_names);
}

TEST(runfile_file, IncompleteOnOpenCompleteAfterFinish) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  RunFileWriter w(path, fixture_header(), m, 1e9);
  // The constructor published the file: it is readable while the writer is alive.
  RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_EQ(d.series.at("time").size(), 0u);
  EXPECT_EQ(d.numbers.at("steps_completed"), 0);
  EXPECT_EQ(d.numbers.at("steps_planned"), 100);

  // Rows are buffered (flush interval 1e9 s) until flush().
  append_rows(w, m, 0, 5);
  EXPECT_EQ(read_run_file(path).series.at("time").size(), 0u);
  w.flush();
  d = read_run_file(path);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_EQ(d.series.at("time").size(), 5u);
  EXPECT_EQ(d.numbers.at("steps_completed"), 4);

  // A frame writes the buffered rows into the file image together with the frame; flush()
  // publishes them.
  append_rows(w, m, 5, 2);
  w.append_frame(0.06, test::fixture_frame(m, 0));
  w.flush();
  d = read_run_file(path);
  EXPECT_EQ(d.series.at("time").size(), 7u);

  w.finish(RunStatus::Complete, "reached steps_planned", 6, 0.5);
  d = read_run_file(path);
  EXPECT_EQ(d.status(), "complete");
  EXPECT_EQ(d.numbers.at("steps_completed"), 6);
  EXPECT_EQ(d.numbers.at("wall_time"), 0.5);
  EXPECT_EQ(d.series.at("time").size(), 7u);
  EXPECT_THROW(w.append(SeriesRow{}), std::logic_error);
  EXPECT_THROW(w.finish(RunStatus::Complete, "again", 6, 0.5), std::logic_error);
}

TEST(runfile_file, ExplodedRecordsWhen) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter w(path, fixture_header(), m);
    append_rows(w, m, 0, 4);
    w.finish(RunStatus::Exploded, "max speed 2000 m/s exceeds limits.max_speed = 1000", 3, 0.2,
             3, 0.03);
  }
  const RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "exploded");
  EXPECT_EQ(d.attributes.at("status_reason"),
            "max speed 2000 m/s exceeds limits.max_speed = 1000");
  EXPECT_EQ(d.numbers.at("exploded_step"), 3);
  EXPECT_EQ(d.numbers.at("exploded_time"), 0.03);
  EXPECT_EQ(d.series.at("step").size(), 4u);
}

TEST(runfile_file, FailedStatus) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter w(path, fixture_header(), m);
    w.finish(RunStatus::Failed, "solver threw: singular matrix", 0, 0.0);
  }
  EXPECT_EQ(read_run_file(path).status(), "failed");
  EXPECT_STREQ(to_string(RunStatus::Incomplete), "incomplete");
  EXPECT_STREQ(to_string(RunStatus::Complete), "complete");
  EXPECT_STREQ(to_string(RunStatus::Exploded), "exploded");
  EXPECT_STREQ(to_string(RunStatus::Failed), "failed");
}

TEST(runfile_file, WarningsAndVelocitiesRoundTrip) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  Points x = m.rest_positions, v = Points::Constant(m.particle_count(), 3, 0.5);
  {
    RunFileWriter w(path, fixture_header(), m);
    w.append_frame(0.0, x, &v);
    w.append_frame(0.1, x);  // without velocities: NaN
    w.set_warnings({"volume @3 (t = 0.03 s): tet volume lost 30 %", "energy_gain @4 (t = 0.04 s): x"});
    w.finish(RunStatus::Complete, "", 0, 0.0);
  }
  const RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "complete");
  EXPECT_EQ(d.warnings(), (std::vector<std::string>{"volume @3 (t = 0.03 s): tet volume lost 30 %",
                                                    "energy_gain @4 (t = 0.04 s): x"}));
  EXPECT_EQ(d.numbers.at("warning_count"), 2.0);
  const hid_t f = H5Fopen(path.string().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t ds = H5Dopen2(f, "/frames/velocities", H5P_DEFAULT);
  ASSERT_GE(ds, 0);
  const hid_t space = H5Dget_space(ds);
  hsize_t dims[3] = {0, 0, 0};
  H5Sget_simple_extent_dims(space, dims, nullptr);
  std::vector<double> all(static_cast<size_t>(dims[0] * dims[1] * dims[2]));
  H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, all.data());
  H5Sclose(space);
  H5Dclose(ds);
  H5Fclose(f);
  ASSERT_EQ(dims[0], 2u);
  EXPECT_EQ(all.front(), 0.5);
  EXPECT_TRUE(std::isnan(all.back()));
}

// Frames are deflated by a worker thread and stored chunk by chunk: frames that deflate and
// frames that do not (random bits, stored with the filter skipped) read back bit for bit, in
// order, through the library's own filter pipeline; an image published in between has as many
// frame times as positions and velocities (the frames the worker had finished), at most the
// frames appended so far.
TEST(runfile_file, FramesReadBackBitForBitWhetherOrNotTheyDeflate) {
  const fs::path path = temp_dir() / "frames.h5";
  const Model m = test::fixture_model();
  const int n = m.particle_count();
  std::vector<Points> xs, vs;
  std::uint64_t bits = 0x9E3779B97F4A7C15ull;
  for (int f = 0; f < 7; ++f) {
    Points x = m.rest_positions * (1.0 + 0.25 * f), v = Points::Constant(n, 3, 0.5 * f);
    if (f % 3 == 2)  // random bit patterns (finite): deflate cannot shrink them
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
          bits ^= bits << 13, bits ^= bits >> 7, bits ^= bits << 17;
          x(i, k) = std::ldexp(static_cast<double>(bits >> 11), -40);
          v(i, k) = -x(i, k);
        }
    xs.push_back(x);
    vs.push_back(v);
  }
  {
    RunFileWriter w(path, fixture_header(), m);
    for (int f = 0; f < 7; ++f) {
      w.append_frame(0.1 * f, xs[static_cast<size_t>(f)], &vs[static_cast<size_t>(f)]);
      if (f == 3) {
        w.flush();
        const hid_t file = H5Fopen(path.string().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
        ASSERT_GE(file, 0);
        std::vector<hsize_t> rows;
        for (const char* name : {"/frames/positions", "/frames/velocities", "/frames/time"}) {
          const hid_t ds = H5Dopen2(file, name, H5P_DEFAULT);
          const hid_t space = H5Dget_space(ds);
          hsize_t dims[3] = {0, 0, 0};
          H5Sget_simple_extent_dims(space, dims, nullptr);
          rows.push_back(dims[0]);
          H5Sclose(space);
          H5Dclose(ds);
        }
        H5Fclose(file);
        EXPECT_EQ(rows[0], rows[2]);
        EXPECT_EQ(rows[1], rows[2]);
        EXPECT_LE(rows[2], 4u);
      }
    }
    w.finish(RunStatus::Complete, "", 0, 0.0);
  }
  RunFileParts parts;
  parts.frames = RunFileParts::Frames::All;
  const RunFileData d = read_run_file(path, parts);
  ASSERT_EQ(d.frames.size(), 7u);
  ASSERT_EQ(d.velocities.size(), 7u);
  for (size_t f = 0; f < 7; ++f) {
    EXPECT_EQ(d.frame_time[f], 0.1 * static_cast<double>(f));
    EXPECT_EQ(std::memcmp(d.frames[f].data(), xs[f].data(), sizeof(double) * 3 * static_cast<size_t>(n)), 0) << f;
    EXPECT_EQ(std::memcmp(d.velocities[f].data(), vs[f].data(), sizeof(double) * 3 * static_cast<size_t>(n)), 0) << f;
  }
}

TEST(runfile_file, DestroyedWithoutFinishStaysIncomplete) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter w(path, fixture_header(), m, 1e9);
    append_rows(w, m, 0, 6);  // buffered: the destructor writes them
  }
  const RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_NE(d.attributes.at("status_reason").find("before the run finished"), std::string::npos)
      << d.attributes.at("status_reason");
  EXPECT_EQ(d.series.at("time").size(), 6u);
  EXPECT_EQ(d.numbers.at("steps_completed"), 5);
}

// A file left by an earlier run must not keep claiming "complete" under a new run's name.
TEST(runfile_file, ReplacesAnEarlierRunAtOnce) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter w(path, fixture_header(), m);
    append_rows(w, m, 0, 10);
    w.finish(RunStatus::Complete, "done", 9, 0.1);
  }
  ASSERT_EQ(read_run_file(path).status(), "complete");
  RunFileWriter w(path, fixture_header(), m);
  const RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_EQ(d.series.at("time").size(), 0u);
}

TEST(runfile_file, UnwritablePathThrowsNamingThePath) {
  const fs::path dir = temp_dir();
  const Model m = test::fixture_model();
  const fs::path missing = dir / "no_such_dir" / "run.h5";
  try {
    RunFileWriter w(missing, fixture_header(), m);
    ADD_FAILURE() << "no exception for " << missing;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(missing));

  // A directory where the file should be.
  const fs::path is_dir = dir / "a_directory.h5";
  fs::create_directories(is_dir);
  try {
    RunFileWriter w(is_dir, fixture_header(), m);
    ADD_FAILURE() << "no exception for " << is_dir;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(is_dir.string()), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_directory(is_dir));
}

// A write that fails (here: a file-size limit, as a full disk would) throws naming the path, and
// the file on disk stays the last published one.
TEST(runfile_file, WriteFailureThrowsAndKeepsTheLastFile) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  RunFileWriter w(path, fixture_header(), m, 1e9);
  append_rows(w, m, 0, 3);
  w.flush();
  const auto size = fs::file_size(path);
  append_rows(w, m, 3, 2);

  rlimit old{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
  rlimit small = old;
  small.rlim_cur = size / 2;  // the next image cannot be written
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);  // write() fails with EFBIG instead
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string what;
  try {
    w.flush();
  } catch (const std::runtime_error& e) {
    what = e.what();
  }
  setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);

  EXPECT_NE(what.find(path.string()), std::string::npos) << "message: " << what;
  EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
  const RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "incomplete");
  EXPECT_EQ(d.series.at("time").size(), 3u);
}

TEST(runfile_file, ReadErrorsNameThePath) {
  const fs::path dir = temp_dir();
  const fs::path missing = dir / "missing.h5";
  try {
    read_run_file(missing);
    ADD_FAILURE() << "no exception for " << missing;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos) << e.what();
  }
  const fs::path text = dir / "not_hdf5.h5";
  std::ofstream(text) << "this is not an HDF5 file\n";
  try {
    read_run_file(text);
    ADD_FAILURE() << "no exception for " << text;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(text.string()), std::string::npos) << e.what();
  }
}

TEST(runfile_file, BadArgumentsThrow) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  RunFileWriter w(path, fixture_header(), m);
  Points wrong = Points::Zero(3, 3);
  EXPECT_THROW(w.append_frame(0.0, wrong), std::invalid_argument);
  EXPECT_THROW(w.append(SeriesRow{}), std::invalid_argument);  // no sample, no report
}

TEST(runfile_file, DuplicateGroupNamesAreRejected) {
  const fs::path path = temp_dir() / "run.h5";
  Model m = test::fixture_model();
  m.group_names.push_back("stretch");  // two groups named "stretch": two series of one name
  try {
    RunFileWriter w(path, fixture_header(), m);
    ADD_FAILURE() << "no exception for duplicate group names";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("constraint_error_max_stretch"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(runfile_file, ModelWithoutConstraintsOrParticles) {
  const fs::path path = temp_dir() / "run.h5";
  Model m;  // nothing at all
  {
    RunFileWriter w(path, fixture_header(), m);
    const Sample s;
    const StepReport rep;
    w.append(SeriesRow{0.0, 0, 0.0, &s, &rep});
    w.append_frame(0.0, Points(0, 3));
    w.finish(RunStatus::Complete, "done", 0, 0.0);
  }
  const RunFileData d = read_run_file(path);
  EXPECT_EQ(d.status(), "complete");
  EXPECT_TRUE(d.group_names.empty());
  EXPECT_EQ(d.series.at("time").size(), 1u);
  H5Handle f{H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(f.id, 0);
  EXPECT_EQ(dims_of(f.id, "/model/constraint_kind"), (std::vector<hsize_t>{0}));
  EXPECT_EQ(dims_of(f.id, "/model/edges"), (std::vector<hsize_t>{0, 2}));
  EXPECT_EQ(dims_of(f.id, "/frames/time"), (std::vector<hsize_t>{1}));
}


// The complete reader: series with units, docs and the deterministic flag, frames with
// velocities (all of them, or the last), the model, read back as written.
TEST(runfile_file, CompleteReaderRoundTrip) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter w(path, fixture_header(), m, 0.0);
    append_rows(w, m, 0, 5);
    for (long fr = 0; fr < 3; ++fr) {
      const Points v = test::fixture_frame(m, 10 + fr);  // any distinct values
      w.append_frame(0.5 * static_cast<double>(fr), test::fixture_frame(m, fr), fr == 1 ? nullptr : &v);
    }
    w.finish(RunStatus::Complete, "done", 4, 1.0);
  }
  RunFileParts parts;
  parts.frames = RunFileParts::Frames::All;
  parts.model = true;
  const RunFileData d = read_run_file(path, parts);

  for (const SeriesSpec& spec : series_table()) {
    const std::string name(spec.name);
    EXPECT_EQ(d.units.at(name), spec.units) << name;
    EXPECT_EQ(d.docs.at(name), spec.doc) << name;
    EXPECT_EQ(d.nondeterministic.count(name), spec.deterministic ? 0u : 1u) << name;
  }
  EXPECT_EQ(d.units.at("constraint_error_max_stretch"), "1");

  EXPECT_EQ(d.frame_time, (std::vector<double>{0.0, 0.5, 1.0}));
  ASSERT_EQ(d.frames.size(), 3u);
  ASSERT_EQ(d.velocities.size(), 3u);
  for (long fr = 0; fr < 3; ++fr) {
    const size_t i = static_cast<size_t>(fr);
    EXPECT_EQ(d.frames[i], test::fixture_frame(m, fr)) << fr;
    if (fr == 1)
      EXPECT_TRUE(d.velocities[i].array().isNaN().all()) << "a frame without velocities";
    else
      EXPECT_EQ(d.velocities[i], test::fixture_frame(m, 10 + fr)) << fr;
  }

  const Model& r = d.model;
  EXPECT_EQ(r.rest_positions, m.rest_positions);
  EXPECT_EQ(r.inv_mass, m.inv_mass);
  EXPECT_EQ(r.radius, m.radius);
  EXPECT_EQ(r.gravity, m.gravity);
  EXPECT_EQ(r.edges, m.edges);
  EXPECT_EQ(r.triangles, m.triangles);
  EXPECT_EQ(r.tets, m.tets);
  EXPECT_EQ(r.group_names, m.group_names);
  ASSERT_EQ(r.constraints.size(), m.constraints.size());
  for (size_t k = 0; k < m.constraints.size(); ++k) {
    const Constraint &a = r.constraints[k], &b = m.constraints[k];
    EXPECT_EQ(a.kind, b.kind) << k;
    EXPECT_EQ(a.particles, b.particles) << k;
    EXPECT_EQ(a.rest, b.rest) << k;
    EXPECT_EQ(a.compliance, b.compliance) << k;
    EXPECT_EQ(a.stiffness, b.stiffness) << k;
    EXPECT_EQ(a.damping, b.damping) << k;
    EXPECT_EQ(a.group, b.group) << k;
  }

  // The last frame only; nothing of the model or frames unless asked for.
  RunFileParts last;
  last.frames = RunFileParts::Frames::Last;
  last.velocities = false;
  const RunFileData l = read_run_file(path, last);
  EXPECT_EQ(l.frame_time.size(), 3u);
  ASSERT_EQ(l.frames.size(), 1u);
  EXPECT_EQ(l.frames[0], test::fixture_frame(m, 2));
  EXPECT_TRUE(l.velocities.empty());
  EXPECT_EQ(l.model.rest_positions.rows(), 0);
  const RunFileData plain = read_run_file(path);
  EXPECT_TRUE(plain.frames.empty());
  EXPECT_TRUE(plain.frame_time.empty());
  EXPECT_TRUE(plain.model.constraints.empty());
  EXPECT_EQ(plain.group_names, m.group_names);
}

// The state hash: 16 hex digits that change with a deterministic series or the last frame,
// and not with the wall-clock timings or an earlier frame.
TEST(runfile_file, StateHash) {
  const fs::path dir = temp_dir();
  const Model m = test::fixture_model();
  auto write = [&](const std::string& name, double wall, long last_frame, double energy) {
    const fs::path path = dir / name;
    RunFileWriter w(path, fixture_header(), m, 0.0);
    for (long r = 0; r < 4; ++r) {
      Sample s = test::fixture_sample(r, m.group_names.size());
      s.kinetic_energy += energy;
      const StepReport rep = test::fixture_report(r);
      w.append(SeriesRow{0.01 * static_cast<double>(r), r, wall * static_cast<double>(r + 1), &s, &rep});
    }
    w.append_frame(0.0, test::fixture_frame(m, wall > 1.0 ? 7 : 0));
    w.append_frame(0.03, test::fixture_frame(m, last_frame));
    w.finish(RunStatus::Complete, "done", 3, 1.0);
    return path;
  };
  const std::string a = state_hash(write("a.h5", 1e-5, 1, 0.0));
  EXPECT_TRUE(std::regex_match(a, std::regex("[0-9a-f]{16}"))) << a;
  EXPECT_EQ(state_hash(write("wall.h5", 2.0, 1, 0.0)), a) << "wall_step and the first frame are not hashed";
  EXPECT_NE(state_hash(write("frame.h5", 1e-5, 2, 0.0)), a);
  EXPECT_NE(state_hash(write("energy.h5", 1e-5, 1, 1e-12)), a);
  // The same from data read with every frame (the hash takes the last).
  RunFileParts all;
  all.frames = RunFileParts::Frames::All;
  EXPECT_EQ(state_hash(read_run_file(dir / "a.h5", all)), a);
}

}  // namespace
}  // namespace pbdbench
