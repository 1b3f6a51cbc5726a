#include "runfile/output_guard.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <hdf5.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>

#include "runfile/utc_now.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

namespace {

constexpr char kLockMagic[] = "pbdbench run file lock\n";
constexpr unsigned char kHdf5Signature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};

[[noreturn]] void refuse(const fs::path& path, const std::string& why) {
  throw OutputRefused("--out " + path.string() + ": " + why);
}

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISLNK(mode)) return "a symbolic link";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISFIFO(mode)) return "a named pipe";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

bool has_hdf5_signature(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char head[8] = {};
  if (!in.read(reinterpret_cast<char*>(head), sizeof head)) return false;
  return std::memcmp(head, kHdf5Signature, sizeof head) == 0;
}

std::string host_name() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0) return "?";
  return buf;
}

// "pid 1234 on host node7 since ..." from a lock file's text, or "" when it has none.
std::string holder_from_text(const std::string& text) {
  if (text.rfind(kLockMagic, 0) != 0) return "";
  std::istringstream in(text.substr(sizeof kLockMagic - 1));
  std::string key, pid, host, since;
  while (in >> key) {
    if (key == "pid") in >> pid;
    else if (key == "host") in >> host;
    else if (key == "since") in >> since;
  }
  if (pid.empty()) return "";
  return "pid " + pid + " on host " + (host.empty() ? "?" : host) + (since.empty() ? "" : " since " + since);
}

std::string read_fd_text(int fd) {
  std::string text;
  char buf[512];
  off_t at = 0;
  for (;;) {
    const ssize_t n = ::pread(fd, buf, sizeof buf, at);
    if (n <= 0 || text.size() > 4096) break;
    text.append(buf, static_cast<size_t>(n));
    at += n;
  }
  return text;
}

}  // namespace

bool is_run_file(const fs::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  if (!has_hdf5_signature(path)) return false;
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_file_locking(fapl, false, true);  // a reader needs no lock, and NFS may refuse one
  bool ok = false;
  H5E_BEGIN_TRY {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
    if (file >= 0) {
      ok = H5Aexists(file, "format_version") > 0 && H5Aexists(file, "status") > 0 &&
           H5Aexists(file, "steps_planned") > 0 && H5Aexists(file, "pbdbench_version") > 0;
      H5Fclose(file);
    }
  }
  H5E_END_TRY;
  H5Pclose(fapl);
  return ok;
}

void check_output_path(const fs::path& path, const fs::path& protect) {
  if (path.empty()) throw OutputRefused("--out: the path is empty");
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    refuse(path, std::string("cannot be examined: ") + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode)) refuse(path, "is " + kind_of(st.st_mode) + ", not a run file: nothing was written");
  std::error_code ec;
  if (!protect.empty() && fs::equivalent(path, protect, ec))
    refuse(path, "is the scenario file itself: nothing was written");
  if (!is_run_file(path))
    refuse(path, "exists and is not a pbdbench run file (checked by its content): nothing was written; "
                 "remove it or choose another path");
}

fs::path lock_path(const fs::path& path) { return fs::path(path.string() + ".lock"); }

std::optional<std::string> output_holder(const fs::path& path) {
  const fs::path lock = lock_path(path);
  const int fd = ::open(lock.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
  if (fd < 0) return std::nullopt;
  struct flock fl {};
  fl.l_type = F_WRLCK;
  fl.l_whence = SEEK_SET;
  std::optional<std::string> holder;
  if (::fcntl(fd, F_OFD_GETLK, &fl) == 0 && fl.l_type != F_UNLCK) {
    const std::string who = holder_from_text(read_fd_text(fd));
    holder = who.empty() ? "an unknown process" : who;
  }
  ::close(fd);
  return holder;
}

OutputLock::OutputLock(const fs::path& path) : lock_(lock_path(path)) {
  for (int attempt = 0; attempt < 20; ++attempt) {
    const int fd = ::open(lock_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd < 0) {
      const int err = errno;
      if (err == ELOOP) refuse(path, "its lock file " + lock_.string() + " is a symbolic link");
      std::string why = "cannot create its lock file " + lock_.string() + ": " + std::strerror(err);
      if (err == ENOENT) why += " (the folder does not exist)";
      if (err == EACCES || err == EROFS) why += " (the folder is not writable)";
      refuse(path, why);
    }
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      refuse(path, "its lock file " + lock_.string() + " is not a regular file");
    }
    struct flock fl {};
    fl.l_type = F_WRLCK;
    fl.l_whence = SEEK_SET;
    if (::fcntl(fd, F_OFD_SETLK, &fl) != 0) {
      const int err = errno;
      const std::string who = holder_from_text(read_fd_text(fd));
      ::close(fd);
      if (err == EAGAIN || err == EACCES)
        refuse(path, "is being written by another run (" + (who.empty() ? "an unknown process" : who) +
                         "; its lock " + lock_.string() + "): one writer per file");
      refuse(path, "cannot lock " + lock_.string() + ": " + std::strerror(err));
    }
    // The lock must be on the file that has the name now: a holder removes it as it ends.
    struct stat named {};
    if (::stat(lock_.c_str(), &named) != 0 || named.st_ino != st.st_ino || named.st_dev != st.st_dev) {
      ::close(fd);
      continue;
    }
    const std::string old = read_fd_text(fd);
    if (!old.empty() && old.rfind(kLockMagic, 0) != 0) {
      ::close(fd);
      refuse(path, "its lock file " + lock_.string() + " exists and is not a pbdbench lock file: "
                   "nothing was written");
    }
    std::ostringstream text;
    text << kLockMagic << "pid " << ::getpid() << "\nhost " << host_name() << "\nsince " << utc_now() << "\n";
    const std::string s = text.str();
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, s.data(), s.size(), 0) != static_cast<ssize_t>(s.size())) {
      const int err = errno;
      ::close(fd);
      refuse(path, "cannot write its lock file " + lock_.string() + ": " + std::strerror(err));
    }
    fd_ = fd;
    return;
  }
  refuse(path, "its lock file " + lock_.string() + " keeps being replaced by another process");
}

OutputLock::~OutputLock() {
  if (fd_ < 0) return;
  ::unlink(lock_.c_str());  // while still holding the lock: see the check in the constructor
  ::close(fd_);
}

}  // namespace pbdbench
