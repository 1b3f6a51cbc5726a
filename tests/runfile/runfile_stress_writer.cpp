// Helper of the kill test (tests/runfile/kill_test.py): writes a run file continuously until it is
// killed. Prints "ready" on stdout once the file exists.
//
//   runfile_stress_writer DESIGN PATH [FLUSH_SECONDS] [STEP_MICROSECONDS] [PARTICLES]
//
// DESIGN
//   publish         RunFileWriter as shipped: the file is built in memory and published by
//                   writing "<path>.tmp" and renaming it over <path>.
//   inplace         the HDF5 library writes <path> in place (sec2 driver, default file format),
//                   buffered rows written and H5Fflush called every FLUSH_SECONDS.
//   inplace-latest  as inplace with the latest file format (superblock version 3).
//   swmr            as inplace-latest, switched to SWMR writing after the objects are created.
//
// Every design writes the same content: row r has time = 0.01 r, step = r and the fixture
// sample and report of row r (tests/runfile/fixture_model.hpp); a frame every 20 rows, frame f
// at time 0.2 f holding rest_positions + 1e-3 f. The kill test checks the file against this.
#include <hdf5.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "runfile/run_file.hpp"
#include "runfile/series.hpp"
#include "tests/runfile/fixture_model.hpp"

namespace pbdbench {
namespace {

using Clock = std::chrono::steady_clock;

constexpr long kRowsPerFrame = 20;

Model stress_model(int particles) {
  Model m;
  m.name = "stress";
  m.rest_positions.resize(particles, 3);
  for (int p = 0; p < particles; ++p)
    m.rest_positions.row(p) = Vec3(0.01 * p, std::sin(0.1 * p), std::cos(0.1 * p)).transpose();
  m.inv_mass.assign(static_cast<size_t>(particles), 1.0);
  m.radius.assign(static_cast<size_t>(particles), 0.005);
  m.group_names = {"stretch", "bending"};
  return m;
}

// The writer under test.
class Writer {
 public:
  virtual ~Writer() = default;
  virtual void append(const SeriesRow& row) = 0;
  virtual void frame(double time, const Points& x) = 0;
};

class PublishWriter : public Writer {
 public:
  PublishWriter(const std::string& path, const Model& m, double flush) {
    RunHeader h;
    h.scenario = "stress";
    h.scenario_file = "(kill test)";
    h.solver = "none";
    h.config = test::fixture_config("none", 1, 1);
    h.dt = 0.01;
    h.steps_planned = 1000000000;
    w_ = std::make_unique<RunFileWriter>(path, h, m, flush);
  }
  void append(const SeriesRow& row) override { w_->append(row); }
  void frame(double time, const Points& x) override { w_->append_frame(time, x); }

 private:
  std::unique_ptr<RunFileWriter> w_;
};

void check(herr_t status, const char* what) {
  if (status < 0) throw std::runtime_error(std::string("HDF5 call failed: ") + what);
}

hid_t checked(hid_t id, const char* what) {
  if (id < 0) throw std::runtime_error(std::string("HDF5 call failed: ") + what);
  return id;
}

void string_attr(hid_t obj, const char* name, const char* value) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, H5T_VARIABLE);
  H5Tset_cset(type, H5T_CSET_UTF8);
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t attr = checked(H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT), name);
  check(H5Awrite(attr, type, &value), name);
  H5Aclose(attr);
  H5Sclose(space);
  H5Tclose(type);
}

// The same datasets as RunFileWriter, written in place by the library.
class InPlaceWriter : public Writer {
 public:
  InPlaceWriter(const std::string& path, const Model& m, double flush, bool latest, bool swmr)
      : flush_(flush), n_(m.particle_count()), groups_(m.group_names.size()) {
    const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    if (latest) check(H5Pset_libver_bounds(fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST), "libver");
    file_ = checked(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl), "create");
    H5Pclose(fapl);
    string_attr(file_, "status", "incomplete");

    const hid_t model = checked(H5Gcreate2(file_, "model", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                                "model");
    const hsize_t rest_dims[2] = {static_cast<hsize_t>(n_), 3};
    const hid_t rest_space = H5Screate_simple(2, rest_dims, nullptr);
    const hid_t rest = checked(H5Dcreate2(model, "rest_positions", H5T_IEEE_F64LE, rest_space,
                                          H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                               "rest_positions");
    check(H5Dwrite(rest, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, m.rest_positions.data()),
          "rest_positions");
    H5Dclose(rest);
    H5Sclose(rest_space);
    H5Gclose(model);

    const hid_t series = checked(
        H5Gcreate2(file_, "series", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "series");
    for (const SeriesSpec& s : series_table()) add_series(series, std::string(s.name), s.width);
    for (const GroupSeriesSpec& g : group_series_table())
      for (const std::string& group : m.group_names)
        add_series(series, std::string(g.prefix) + group, 1);
    H5Gclose(series);

    const hid_t frames = checked(
        H5Gcreate2(file_, "frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "frames");
    {
      const hsize_t dims[1] = {0}, maxdims[1] = {H5S_UNLIMITED}, chunk[1] = {256};
      const hid_t space = H5Screate_simple(1, dims, maxdims);
      const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(dcpl, 1, chunk);
      frame_time_ = checked(
          H5Dcreate2(frames, "time", H5T_IEEE_F64LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
          "time");
      H5Pclose(dcpl);
      H5Sclose(space);
    }
    {
      const hsize_t n = static_cast<hsize_t>(n_);
      const hsize_t dims[3] = {0, n, 3}, maxdims[3] = {H5S_UNLIMITED, n, 3}, chunk[3] = {1, n, 3};
      const hid_t space = H5Screate_simple(3, dims, maxdims);
      const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(dcpl, 3, chunk);
      H5Pset_shuffle(dcpl);
      H5Pset_deflate(dcpl, 4);
      frame_pos_ = checked(
          H5Dcreate2(frames, "positions", H5T_IEEE_F64LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
          "positions");
      H5Pclose(dcpl);
      H5Sclose(space);
    }
    H5Gclose(frames);
    if (swmr) check(H5Fstart_swmr_write(file_), "start_swmr_write");
    check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "flush");
    last_flush_ = Clock::now();
  }

  void append(const SeriesRow& row) override {
    double v[3];
    size_t k = 0;
    for (const SeriesSpec& s : series_table()) {
      s.read(row, v);
      std::vector<double>& pending = series_[k++].pending;
      pending.insert(pending.end(), v, v + s.width);
    }
    for (const GroupSeriesSpec& g : group_series_table())
      for (size_t i = 0; i < groups_; ++i)
        series_[k++].pending.push_back(g.read(row.sample->groups[i]));
    ++pending_;
    if (std::chrono::duration<double>(Clock::now() - last_flush_).count() >= flush_) flush();
  }

  void frame(double time, const Points& x) override {
    write_rows();
    extend_write(frame_time_, frames_, 1, {}, &time);
    extend_write(frame_pos_, frames_, 1, {static_cast<hsize_t>(n_), 3}, x.data());
    ++frames_;
    check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "flush");
    last_flush_ = Clock::now();
  }

 private:
  struct Series {
    hid_t ds;
    int width;
    std::vector<double> pending;
  };

  void add_series(hid_t group, const std::string& name, int width) {
    const int rank = width == 1 ? 1 : 2;
    const hsize_t dims[2] = {0, 3}, maxdims[2] = {H5S_UNLIMITED, 3}, chunk[2] = {256, 3};
    const hid_t space = H5Screate_simple(rank, dims, maxdims);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, rank, chunk);
    const hid_t ds = checked(
        H5Dcreate2(group, name.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
        name.c_str());
    H5Pclose(dcpl);
    H5Sclose(space);
    series_.push_back(Series{ds, width, {}});
  }

  void extend_write(hid_t ds, hsize_t at, hsize_t count, std::vector<hsize_t> row_dims,
                    const double* data) {
    std::vector<hsize_t> size{at + count}, start{at}, block{count};
    for (hsize_t d : row_dims) {
      size.push_back(d);
      start.push_back(0);
      block.push_back(d);
    }
    check(H5Dset_extent(ds, size.data()), "set_extent");
    const hid_t fspace = H5Dget_space(ds);
    check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start.data(), nullptr, block.data(), nullptr),
          "select");
    const hid_t mspace = H5Screate_simple(static_cast<int>(block.size()), block.data(), nullptr);
    check(H5Dwrite(ds, H5T_NATIVE_DOUBLE, mspace, fspace, H5P_DEFAULT, data), "write");
    H5Sclose(mspace);
    H5Sclose(fspace);
  }

  void write_rows() {
    if (pending_ == 0) return;
    for (Series& s : series_) {
      std::vector<hsize_t> row_dims;
      if (s.width != 1) row_dims.push_back(3);
      extend_write(s.ds, rows_, pending_, row_dims, s.pending.data());
      s.pending.clear();
    }
    rows_ += pending_;
    pending_ = 0;
  }

  void flush() {
    write_rows();
    check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "flush");
    last_flush_ = Clock::now();
  }

  double flush_;
  int n_;
  size_t groups_;
  hid_t file_ = -1, frame_time_ = -1, frame_pos_ = -1;
  std::vector<Series> series_;
  hsize_t rows_ = 0, pending_ = 0, frames_ = 0;
  Clock::time_point last_flush_;
};

int run(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: " << argv[0]
              << " publish|inplace|inplace-latest|swmr PATH"
                 " [FLUSH_SECONDS] [STEP_US] [PARTICLES]\n";
    return 2;
  }
  const std::string design = argv[1];
  const std::string path = argv[2];
  const double flush = argc > 3 ? std::atof(argv[3]) : 0.02;
  const long step_us = argc > 4 ? std::atol(argv[4]) : 200;
  const int particles = argc > 5 ? std::atoi(argv[5]) : 200;
  const Model m = stress_model(particles);

  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  std::unique_ptr<Writer> w;
  if (design == "publish") w = std::make_unique<PublishWriter>(path, m, flush);
  else if (design == "inplace") w = std::make_unique<InPlaceWriter>(path, m, flush, false, false);
  else if (design == "inplace-latest")
    w = std::make_unique<InPlaceWriter>(path, m, flush, true, false);
  else if (design == "swmr") w = std::make_unique<InPlaceWriter>(path, m, flush, true, true);
  else {
    std::cerr << "unknown design " << design << "\n";
    return 2;
  }
  std::cout << "ready" << std::endl;

  for (long r = 0;; ++r) {
    const Sample s = test::fixture_sample(r, m.group_names.size());
    const StepReport rep = test::fixture_report(r);
    w->append(SeriesRow{0.01 * static_cast<double>(r), r, 1e-5, &s, &rep});
    if (r % kRowsPerFrame == 0) {
      const long f = r / kRowsPerFrame;
      Points x = m.rest_positions;
      x.array() += 1e-3 * static_cast<double>(f);
      w->frame(0.2 * static_cast<double>(f), x);
    }
    if (step_us > 0) std::this_thread::sleep_for(std::chrono::microseconds(step_us));
  }
}

}  // namespace
}  // namespace pbdbench

int main(int argc, char** argv) {
  try {
    return pbdbench::run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "runfile_stress_writer: " << e.what() << "\n";
    return 1;
  }
}
