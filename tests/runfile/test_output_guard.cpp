// Tests of runfile/output_guard and runfile/shadow_file: what a run file may replace (by content),
// one writer per path (the lock names its holder, is released, and is taken over from a dead
// holder), and a publish that writes what changed, not the whole file.
#include "runfile/output_guard.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <H5Cpp.h>

#include <filesystem>
#include <fstream>
#include <cstdio>
#include <memory>
#include <set>
#include <string>

#include "runfile/run_file.hpp"
#include "runfile/shadow_file.hpp"
#include "tests/runfile/fixture_model.hpp"
#include "tests/runfile/test_support.hpp"

namespace pbdbench {
namespace {

namespace fs = std::filesystem;

using test::temp_dir;

RunHeader header(const fs::path& scenario = "scenarios/fixture.toml") {
  return test::fixture_header(scenario.string());
}

void append_rows(RunFileWriter& w, const Model& m, long first, long rows) {
  for (long r = first; r < first + rows; ++r) {
    const Sample s = test::fixture_sample(r, m.group_names.size());
    const StepReport rep = test::fixture_report(r);
    w.append(SeriesRow{0.01 * static_cast<double>(r), r, 0.0, &s, &rep});
  }
}

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// What `check` refused with, or "" when it let the output through.
template <class Check>
std::string refusal_by(Check check) {
  try {
    check();
  } catch (const OutputRefused& e) {
    return e.what();
  }
  return "";
}

std::string refusal(const fs::path& path, const fs::path& scenario = {}) {
  return refusal_by([&] { check_output_path(path, scenario); });
}

TEST(OutputGuard, OnlyARunFileMayBeReplaced) {
  const fs::path dir = temp_dir();
  EXPECT_EQ(refusal(dir / "absent.h5"), "");

  std::ofstream(dir / "notes.h5") << "not HDF5\n";
  EXPECT_NE(refusal(dir / "notes.h5").find("is not a pbdbench run file"), std::string::npos);
  std::ofstream(dir / "empty.h5");
  EXPECT_NE(refusal(dir / "empty.h5").find("is not a pbdbench run file"), std::string::npos);
  EXPECT_NE(refusal(dir).find("is a directory"), std::string::npos);
  EXPECT_NE(refusal("/dev/null").find("character device"), std::string::npos);
  ASSERT_EQ(::mkfifo((dir / "pipe").c_str(), 0644), 0);
  EXPECT_NE(refusal(dir / "pipe").find("named pipe"), std::string::npos);

  const Model m = test::fixture_model();
  {
    RunFileWriter w(dir / "run.h5", header(), m);
    w.finish(RunStatus::Complete, "", 0, 0.0);
  }
  EXPECT_TRUE(is_run_file(dir / "run.h5"));
  EXPECT_EQ(refusal(dir / "run.h5"), "");
  fs::create_symlink(dir / "run.h5", dir / "link.h5");
  EXPECT_NE(refusal(dir / "link.h5").find("symbolic link"), std::string::npos);
  // The scenario file itself, whatever it holds (here even a run file).
  EXPECT_NE(refusal(dir / "run.h5", dir / "run.h5").find("scenario file itself"), std::string::npos);

  // The writer refuses the same, and leaves the file as it was.
  const std::string before = read_all(dir / "notes.h5");
  EXPECT_THROW(RunFileWriter(dir / "notes.h5", header(), m), OutputRefused);
  EXPECT_EQ(read_all(dir / "notes.h5"), before);
  EXPECT_FALSE(fs::exists(dir / "notes.h5.lock"));
}

TEST(OutputGuard, OneWriterPerPathNamingTheHolder) {
  const fs::path dir = temp_dir();
  const fs::path path = dir / "run.h5";
  const Model m = test::fixture_model();
  {
    RunFileWriter first(path, header(), m);
    EXPECT_TRUE(fs::exists(lock_path(path)));
    const auto holder = output_holder(path);
    ASSERT_TRUE(holder.has_value());
    EXPECT_NE(holder->find("pid " + std::to_string(::getpid())), std::string::npos) << *holder;
    try {
      RunFileWriter second(path, header(), m);
      ADD_FAILURE() << "a second writer of " << path;
    } catch (const OutputRefused& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("pid " + std::to_string(::getpid())), std::string::npos) << what;
      EXPECT_NE(what.find("on host "), std::string::npos) << what;
    }
    first.finish(RunStatus::Complete, "", 0, 0.0);
    EXPECT_FALSE(output_holder(path).has_value());  // released at finish
  }
  EXPECT_FALSE(fs::exists(lock_path(path)));
  EXPECT_FALSE(fs::exists(shadow_path(path)));
}

// A holder that dies without cleaning up leaves its lock file; the kernel released the lock.
TEST(OutputGuard, TheLockOfADeadHolderIsTakenOver) {
  const fs::path dir = temp_dir();
  const fs::path path = dir / "run.h5";
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    OutputLock* lock = new OutputLock(path);  // never released: the process ends
    (void)lock;
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(fs::exists(lock_path(path)));
  EXPECT_FALSE(output_holder(path).has_value());
  OutputLock again(path);
  EXPECT_TRUE(output_holder(path).has_value());
}

// The guard every writer shares: the argument and the file named, the kind judged by content,
// the command's inputs never replaced.
std::string refusal_of(const fs::path& path, const OutputTarget& target) {
  return refusal_by([&] { check_output(path, target); });
}

TEST(OutputGuard, OneGuardForEveryKindOfOutput) {
  const fs::path dir = temp_dir();
  const OutputTarget notes{"--notes", "notes file", [](const fs::path& p) { return has_marker(p, "# my notes"); },
                           {{dir / "input.txt", "the input"}}};
  EXPECT_EQ(refusal_of(dir / "absent.txt", notes), "");
  std::ofstream(dir / "ours.txt") << "# my notes\nold\n";
  EXPECT_EQ(refusal_of(dir / "ours.txt", notes), "");
  std::ofstream(dir / "theirs.txt") << "someone else's\n";
  EXPECT_EQ(refusal_of(dir / "theirs.txt", notes),
            "--notes " + (dir / "theirs.txt").string() +
                ": exists and is not a pbdbench notes file (checked by its content): nothing was written; remove it "
                "or choose another path");
  // An input, even one that looks like an earlier output, and by another name of it.
  std::ofstream(dir / "input.txt") << "# my notes\n";
  EXPECT_NE(refusal_of(dir / "input.txt", notes).find("is the input itself"), std::string::npos);
  fs::create_hard_link(dir / "input.txt", dir / "input-too.txt");
  EXPECT_NE(refusal_of(dir / "input-too.txt", notes).find("is the input itself"), std::string::npos);
  EXPECT_NE(refusal_of(dir, notes).find("--notes " + dir.string() + ": is a directory, not a notes file"),
            std::string::npos);
  EXPECT_NE(refusal_of("/dev/null", notes).find("character device"), std::string::npos);
  fs::create_symlink(dir / "ours.txt", dir / "link.txt");
  EXPECT_NE(refusal_of(dir / "link.txt", notes).find("symbolic link"), std::string::npos);
  EXPECT_NE(refusal_of("", notes).find("--notes: the path is empty"), std::string::npos);
  // has_marker looks only as far as it is told.
  std::ofstream(dir / "late.txt") << std::string(100, 'x') << "# my notes\n";
  EXPECT_TRUE(has_marker(dir / "late.txt", "# my notes", 200));
  EXPECT_FALSE(has_marker(dir / "late.txt", "# my notes", 50));
  EXPECT_FALSE(has_marker(dir / "link.txt", "# my notes"));  // never through a link
}

TEST(OutputGuard, PbdbenchFilesAreKnownByTheirContentAttribute) {
  const fs::path dir = temp_dir();
  const Model m = test::fixture_model();
  {
    RunFileWriter w(dir / "run.h5", header(), m);
    w.finish(RunStatus::Complete, "", 0, 0.0);
  }
  EXPECT_FALSE(is_pbdbench_file(dir / "run.h5", "pbdbench compare"));  // a run file has no "content"
  std::ofstream(dir / "text.h5") << "pbdbench compare\n";
  EXPECT_FALSE(is_pbdbench_file(dir / "text.h5", "pbdbench compare"));
  EXPECT_FALSE(is_pbdbench_file(dir / "absent.h5", "pbdbench compare"));
  // The root's "content", a UTF-8 string as the layout writes it (runfile/layout.hpp).
  {
    H5::H5File f((dir / "compare.h5").string(), H5F_ACC_TRUNC);
    H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
    type.setCset(H5T_CSET_UTF8);
    f.createAttribute("content", type, H5::DataSpace(H5S_SCALAR)).write(type, std::string("pbdbench compare"));
  }
  EXPECT_TRUE(is_pbdbench_file(dir / "compare.h5", "pbdbench compare"));
  EXPECT_FALSE(is_pbdbench_file(dir / "compare.h5", "pbdbench converge"));
  fs::create_symlink(dir / "compare.h5", dir / "link.h5");
  EXPECT_FALSE(is_pbdbench_file(dir / "link.h5", "pbdbench compare"));
}

TEST(OutputGuard, FoldersMustBeFolders) {
  const fs::path dir = temp_dir();
  auto refusal = [](const fs::path& p, const std::vector<OutputInput>& inputs = {}) {
    return refusal_by([&] { check_output_folder(p, "--out", inputs); });
  };
  EXPECT_EQ(refusal(dir / "new"), "");
  EXPECT_EQ(refusal(dir), "");
  fs::create_directory(dir / "real");
  fs::create_directory_symlink(dir / "real", dir / "linked");  // a results/ linked to a scratch disk
  EXPECT_EQ(refusal(dir / "linked"), "");
  fs::create_symlink(dir / "nowhere", dir / "dangling");
  EXPECT_NE(refusal(dir / "dangling").find("a symbolic link to nothing"), std::string::npos);
  std::ofstream(dir / "file.txt") << "x";
  EXPECT_EQ(refusal(dir / "file.txt"), "--out " + (dir / "file.txt").string() +
                                           ": is a regular file, not a folder: nothing was written");
  EXPECT_NE(refusal("/dev/null").find("character device"), std::string::npos);
  EXPECT_NE(refusal(dir / "real", {{dir / "real", "the experiments' folder"}}).find("is the experiments' folder itself"),
            std::string::npos);
}

TEST(OutputGuard, TemporariesAreCreatedAfreshNeverThroughALink) {
  const fs::path dir = temp_dir();
  const fs::path out = dir / "out.xdmf";
  std::ofstream(dir / "victim.txt") << "precious\n";
  fs::create_symlink(dir / "victim.txt", dir / "out.xdmf.tmp");
  try {
    write_text_output(out, "new\n", "--out");
    ADD_FAILURE() << "wrote through " << dir / "out.xdmf.tmp";
  } catch (const OutputRefused& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("--out " + out.string() + ": its temporary " + out.string() + ".tmp is in the way and is a "
                        "symbolic link"),
              std::string::npos)
        << what;
  }
  EXPECT_EQ(read_all(dir / "victim.txt"), "precious\n");
  EXPECT_FALSE(fs::exists(out));
  // A killed writer's temporary (a plain file) is replaced; the output is written whole.
  fs::remove(dir / "out.xdmf.tmp");
  std::ofstream(dir / "out.xdmf.tmp") << "half";
  write_text_output(out, "whole\n");
  EXPECT_EQ(read_all(out), "whole\n");
  EXPECT_FALSE(fs::exists(dir / "out.xdmf.tmp"));
  // create_exclusive never opens what is there, a link least of all.
  fs::create_symlink(dir / "victim.txt", dir / "planted");
  EXPECT_THROW(create_exclusive(dir / "planted"), OutputRefused);
  EXPECT_EQ(read_all(dir / "victim.txt"), "precious\n");
}

TEST(OutputGuard, AFileInTheWayOfTheLockIsNotOverwritten) {
  const fs::path dir = temp_dir();
  const fs::path path = dir / "run.h5";
  std::ofstream(lock_path(path)) << "my own file named run.h5.lock\n";
  EXPECT_THROW(OutputLock lock(path), OutputRefused);
  EXPECT_EQ(read_all(lock_path(path)), "my own file named run.h5.lock\n");
}

// /proc/self/io: wchar counts the bytes this process passed to write calls (copy_file_range's
// included).
unsigned long long bytes_written() {
  std::ifstream io("/proc/self/io");
  std::string key;
  unsigned long long value = 0;
  while (io >> key >> value)
    if (key == "wchar:") return value;
  return 0ull;
}

// A publish writes what changed since the previous one (twice: the library's writes into the
// working copy, then the copy into the previous image), not the whole file.
TEST(ShadowFile, APublishCopiesOnlyWhatChanged) {
  const fs::path dir = temp_dir();
  const fs::path path = dir / "run.h5";
  const Model m = test::fixture_model();
  RunFileWriter w(path, header(), m, 1e9);
  append_rows(w, m, 0, 50000);
  w.flush();
  const auto big = fs::file_size(path);
  ASSERT_GT(big, 10u << 20);
  auto written = bytes_written;
  const auto before = written();
  append_rows(w, m, 50000, 10);
  w.flush();
  const auto cost = written() - before;
  EXPECT_LT(cost, big / 20) << "a flush of 10 rows wrote " << cost << " bytes of a " << big << "-byte file";
  EXPECT_TRUE(fs::exists(shadow_path(path)));
  EXPECT_EQ(fs::file_size(shadow_path(path)), fs::file_size(path));
  EXPECT_EQ(read_all(shadow_path(path)), read_all(path));  // the next working copy is up to date
  w.finish(RunStatus::Complete, "", 50009, 1.0);
  EXPECT_FALSE(fs::exists(shadow_path(path)));
  EXPECT_EQ(read_run_file(path).series.at("time").size(), 50010u);
}

// The names a directory's entries were created or moved under, as inotify reported them since
// `fd` was set to watch it (read without waiting).
std::set<std::string> names_created(int fd) {
  std::set<std::string> out;
  alignas(inotify_event) char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n <= 0) break;
    for (ssize_t at = 0; at < n;) {
      const auto* e = reinterpret_cast<const inotify_event*>(buffer + at);
      if (e->len > 0 && (e->mask & (IN_CREATE | IN_MOVED_TO))) out.insert(e->name);
      at += static_cast<ssize_t>(sizeof(inotify_event) + e->len);
    }
  }
  return out;
}

// Whether this directory's filesystem exchanges two names in one step (renameat2).
bool exchanges_names(const fs::path& dir) {
  std::ofstream(dir / "probe_a") << "a";
  std::ofstream(dir / "probe_b") << "b";
  const bool ok = ::renameat2(AT_FDCWD, (dir / "probe_a").c_str(), AT_FDCWD, (dir / "probe_b").c_str(),
                              RENAME_EXCHANGE) == 0;
  fs::remove(dir / "probe_a");
  fs::remove(dir / "probe_b");
  return ok;
}

// A publish after the first exchanges the names of the working copy and the published file in
// one step: no third name ("<path>.previous") is made, the previous image is the next working
// copy, and it is up to date.
TEST(ShadowFile, APublishExchangesTheTwoNames) {
  const fs::path dir = temp_dir();
  if (!exchanges_names(dir)) GTEST_SKIP() << dir << ": the filesystem cannot exchange two names";
  const fs::path path = dir / "run.h5";
  const Model m = test::fixture_model();
  RunFileWriter w(path, header(), m, 1e9);
  append_rows(w, m, 0, 1000);
  w.flush();
  struct stat published {}, working {};
  ASSERT_EQ(::stat(path.c_str(), &published), 0);
  ASSERT_EQ(::stat(shadow_path(path).c_str(), &working), 0);
  const int fd = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_GE(::inotify_add_watch(fd, dir.c_str(), IN_CREATE | IN_MOVED_TO), 0);
  append_rows(w, m, 1000, 10);
  w.flush();
  const std::set<std::string> names = names_created(fd);
  ::close(fd);
  EXPECT_EQ(names, (std::set<std::string>{"run.h5", "run.h5.shadow"}));
  struct stat now_published {}, now_working {};
  ASSERT_EQ(::stat(path.c_str(), &now_published), 0);
  ASSERT_EQ(::stat(shadow_path(path).c_str(), &now_working), 0);
  EXPECT_EQ(now_published.st_ino, working.st_ino);  // the working copy is published
  EXPECT_EQ(now_working.st_ino, published.st_ino);  // the previous image works on
  EXPECT_EQ(read_all(shadow_path(path)), read_all(path));
  w.finish(RunStatus::Complete, "", 1009, 1.0);
  EXPECT_EQ(read_run_file(path).series.at("time").size(), 1010u);
}

// Where the names cannot be exchanged (here: the published file was removed under the writer),
// a publish falls back to renaming the working copy over the path and copying it whole.
TEST(ShadowFile, APublishWithoutAFileToExchangeWithRenames) {
  const fs::path path = temp_dir() / "run.h5";
  const Model m = test::fixture_model();
  RunFileWriter w(path, header(), m, 1e9);
  append_rows(w, m, 0, 100);
  w.flush();
  fs::remove(path);
  append_rows(w, m, 100, 10);
  w.flush();  // nothing to exchange with: renamed, and the next working copy made whole
  EXPECT_EQ(read_run_file(path).series.at("time").size(), 110u);
  EXPECT_EQ(read_all(shadow_path(path)), read_all(path));
  append_rows(w, m, 110, 10);
  w.flush();  // exchanged again
  w.finish(RunStatus::Complete, "", 119, 1.0);
  EXPECT_EQ(read_run_file(path).series.at("time").size(), 120u);
  EXPECT_FALSE(fs::exists(shadow_path(path)));
  EXPECT_FALSE(fs::exists(path.string() + ".previous"));
}

// The last publish (finish, or a writer destroyed unfinished) prepares no next working copy:
// what the library wrote since the publish before is not copied again, and neither the working
// copy nor the previous image is left on disk.
TEST(ShadowFile, TheLastPublishCopiesNothingAndLeavesOneFile) {
  const fs::path dir = temp_dir();
  const Model m = test::fixture_model();
  for (const bool finished : {true, false}) {
    const fs::path path = dir / (finished ? "finished.h5" : "destroyed.h5");
    auto w = std::make_unique<RunFileWriter>(path, header(), m, 1e9);
    w->flush();  // a previous image exists: the case where a next working copy would be made
    // Written into the working copy as they come (in batches of rows), never published.
    append_rows(*w, m, 0, 50000);
    const auto before = bytes_written();
    if (finished)
      w->finish(RunStatus::Complete, "", 49999, 1.0);
    w.reset();
    const auto cost = bytes_written() - before;
    const auto size = fs::file_size(path);
    ASSERT_GT(size, 10u << 20);
    EXPECT_LT(cost, size / 10) << "the last publish of a " << size << "-byte file wrote " << cost << " bytes";
    EXPECT_FALSE(fs::exists(shadow_path(path)));
    EXPECT_FALSE(fs::exists(path.string() + ".previous"));
    const RunFileData data = read_run_file(path);
    EXPECT_EQ(data.series.at("time").size(), 50000u);
    EXPECT_EQ(data.status(), finished ? "complete" : "incomplete");
  }
}

}  // namespace
}  // namespace pbdbench
