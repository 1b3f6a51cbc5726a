// What a run file may replace, and one writer per run file.
//
// A run file is written only where nothing but a run file is lost: the path must be absent or a
// regular file that is a pbdbench run file, checked by its content (an HDF5 file whose root has
// the run file's attributes), never by its name. And one process at a time writes it: the
// writer holds an exclusive lock on "<path>.lock" for the run's life; the lock file says who
// holds it (pid, host, since when) so that a second writer is refused naming the first. The
// kernel drops the lock when the holder dies, however it dies; a lock file left behind by a
// killed process is taken over by the next writer.
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

namespace pbdbench {

// The output path cannot take a run file (bad input: the command line exits 2). The message
// names the path and says why.
class OutputRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// True when `path` is a regular file holding a pbdbench run file (of any status).
bool is_run_file(const std::filesystem::path& path);

// Throws OutputRefused unless a run file may be written at `path`: it does not exist, or it is a
// regular file that is_run_file(), and it is not `protect` (the scenario file) nor a symbolic
// link, a directory, a device or any other non-regular file.
void check_output_path(const std::filesystem::path& path, const std::filesystem::path& protect = {});

// The lock file of a run file's path: "<path>.lock".
std::filesystem::path lock_path(const std::filesystem::path& path);

// "pid 1234 on host node7 since 2026-01-31T12:00:00Z" for the process writing `path` now, or
// nothing when no process holds its lock.
std::optional<std::string> output_holder(const std::filesystem::path& path);

// The exclusive lock of a run file's path, held while the object lives (an open file
// description lock on "<path>.lock", which records the holder). Throws OutputRefused naming the
// holder when another process (or another OutputLock of this one) holds it, or naming the lock
// file when it cannot be created (a missing or read-only folder).
class OutputLock {
 public:
  explicit OutputLock(const std::filesystem::path& path);
  ~OutputLock();  // removes the lock file, then releases the lock
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  std::filesystem::path lock_;
  int fd_ = -1;
};

}  // namespace pbdbench
