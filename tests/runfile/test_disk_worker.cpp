// Tests of runfile/disk_worker: writebacks started and descriptors closed off the caller's thread,
// no descriptor kept or lost, no byte of a file changed; and a run file writer that publishes
// and replaces a file leaves no descriptor open.
#include "runfile/disk_worker.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "runfile/run_file.hpp"
#include "tests/runfile/fixture_model.hpp"
#include "tests/runfile/test_support.hpp"

namespace pbdbench {
namespace {

namespace fs = std::filesystem;

// The descriptors this process has open.
long open_descriptors() {
  long n = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator("/proc/self/fd")) ++n;
  return n;
}

bool is_open(int fd) { return ::fcntl(fd, F_GETFD) != -1; }

std::string contents(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(DiskWorker, StartsWritebacksOnItsOwnCopyOfTheDescriptor) {
  const fs::path path = test::temp_dir() / "pages.bin";
  const std::string bytes(1 << 20, 'x');
  const long before = open_descriptors();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::pwrite(fd, bytes.data(), bytes.size(), 0), static_cast<ssize_t>(bytes.size()));
  {
    DiskWorker disk;
    disk.start_writeback(fd);
    disk.start_writeback(fd);
  }  // joins: both done
  EXPECT_TRUE(is_open(fd)) << "the caller's descriptor is the caller's";
  ::close(fd);
  EXPECT_EQ(open_descriptors(), before);
  EXPECT_EQ(contents(path), bytes);
}

TEST(DiskWorker, ClosesWhatItIsGiven) {
  const fs::path path = test::temp_dir() / "removed.bin";
  std::ofstream(path) << "gone";
  const long before = open_descriptors();
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  fs::remove(path);
  long done = 0;
  {
    DiskWorker disk;
    disk.release(fd);
    disk.release(-1);  // nothing
    while (disk.done() < 1) std::this_thread::yield();
    done = disk.done();
  }
  EXPECT_EQ(done, 1);
  EXPECT_EQ(open_descriptors(), before);
}

TEST(DiskWorker, DroppedAndSurplusWritebacksLeaveNoDescriptor) {
  const fs::path path = test::temp_dir() / "many.bin";
  std::ofstream(path) << "bytes";
  const long before = open_descriptors();
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  {
    DiskWorker disk;
    for (int k = 0; k < 50; ++k) disk.start_writeback(fd);  // more than are kept waiting
    disk.drop_writebacks();
    for (int k = 0; k < 3; ++k) disk.start_writeback(fd);
  }
  {
    DiskWorker never_started;  // a worker given nothing has no thread to join
  }
  ::close(fd);
  EXPECT_EQ(open_descriptors(), before);
}

// A writer publishing many times over a file it replaces (a finished run's) keeps no descriptor
// once destroyed: the replaced file's, the images', the worker's copies.
TEST(DiskWorker, ARunFileWriterLeavesNoDescriptorOpen) {
  const fs::path path = test::temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  const RunHeader h = test::fixture_header();
  for (int run = 0; run < 2; ++run) {  // the second replaces the first's file
    const long before = open_descriptors();
    {
      RunFileWriter w(path, h, m, 1e9);
      for (long k = 0; k < 20; ++k) {
        const Sample s = test::fixture_sample(k, m.group_names.size());
        const StepReport r = test::fixture_report(k);
        w.append(SeriesRow{0.01 * static_cast<double>(k), k, 0.0, &s, &r});
        w.flush();
      }
      w.finish(RunStatus::Complete, "", 19, 1.0);
    }
    EXPECT_EQ(open_descriptors(), before) << "run " << run;
    EXPECT_EQ(read_run_file(path).series.at("time").size(), 20u);
  }
}

}  // namespace
}  // namespace pbdbench
