// What an output may replace, and one writer per run file.
//
// One guard for every command that writes a file (run, compare, converge, export, regress, sweep,
// claims, paper, register): an output is written only where nothing but pbdbench's own earlier
// output of the same kind is lost. The path must be absent, or a regular file (never a symbolic
// link, a directory, a device or a pipe) that holds that kind of output, checked by its content
// (an HDF5 file's attributes, a text file's marker), never by its name, and none of the command's
// own inputs. A folder an output goes into must be absent or a folder. A temporary written beside
// an output and renamed onto it ("<path>.tmp") is created afresh, never opened through a link
// planted in its place. Anything else is refused (exit 2), naming the argument and the file.
//
// And one process at a time writes a run file: the writer holds an exclusive lock on
// "<path>.lock" for the run's life; the lock file says who holds it (pid, host, since when) so
// that a second writer is refused naming the first. The kernel drops the lock when the holder
// dies, however it dies; a lock file left behind by a killed process is taken over by the next
// writer.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace pbdbench {

// The output path cannot take a run file (bad input: the command line exits 2). The message
// names the path and says why.
class OutputRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// True when `path` is a regular file holding a pbdbench run file (of any status).
bool is_run_file(const std::filesystem::path& path);

// True when `path` is a regular HDF5 file whose root attribute "content" is `content` (the
// compare, converge and regress files: "pbdbench compare", ...).
bool is_pbdbench_file(const std::filesystem::path& path, const std::string& content);

// True when `path` is a regular file whose first `within` bytes hold `marker` (a text output's
// signature: a report's heading, an export's comment).
bool has_marker(const std::filesystem::path& path, const std::string& marker, std::size_t within = 4096);

// A file a command reads, which none of its outputs may be.
struct OutputInput {
  std::filesystem::path path;
  std::string what;  // "the scenario file", "the reference run file"
};

// An output of a command, as the guard sees it.
struct OutputTarget {
  std::string argument = "--out";  // what named the path, first in every message
  std::string kind = "run file";   // what is written there: "compare file", "ParaView export"
  // True for pbdbench's own earlier output of this kind, which may be replaced.
  std::function<bool(const std::filesystem::path&)> ours;
  std::vector<OutputInput> inputs;  // never replaced, whatever they hold
};

// Throws OutputRefused ("<argument> <path>: why; nothing was written") unless `path` may take the
// output: it does not exist, or it is a regular file that target.ours() accepts and that is none
// of target.inputs (compared as files: a link or another name of an input is that input).
void check_output(const std::filesystem::path& path, const OutputTarget& target);

// Throws OutputRefused unless `folder` may take outputs: absent (it is created), or a folder (a
// symbolic link to a folder is followed, as a results/ linked to a scratch disk), and none of
// `inputs`. The files written in it pass check_output one by one.
void check_output_folder(const std::filesystem::path& folder, const std::string& argument,
                         const std::vector<OutputInput>& inputs = {});

// "<path>.tmp", for an output written there and then renamed onto `path`, once nothing is in its
// way: a regular file of that name (a killed writer's) is removed; a symbolic link, a folder or a
// device there is refused (OutputRefused naming it). Create it exclusively (O_CREAT | O_EXCL,
// H5F_ACC_EXCL: create_exclusive below) so that nothing planted meanwhile is written through.
std::filesystem::path claim_temporary(const std::filesystem::path& path, const std::string& argument = "--out");

// Opens `path` for writing, only if nothing exists there (O_CREAT | O_EXCL | O_NOFOLLOW): the
// file descriptor, or throws OutputRefused naming `argument` and the path.
int create_exclusive(const std::filesystem::path& path, const std::string& argument = "--out");

// Writes `text` to `path` through claim_temporary() and a rename: the file is whole or untouched.
// The caller has checked `path` with check_output. Throws OutputRefused or std::runtime_error.
void write_text_output(const std::filesystem::path& path, const std::string& text, const std::string& argument = "--out");

// check_output for a run file (`run --out`): absent, or a regular file that is_run_file(), and
// not `protect` (the scenario file).
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
