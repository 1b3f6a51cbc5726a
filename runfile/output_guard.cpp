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

[[noreturn]] void refuse(const std::string& argument, const fs::path& path, const std::string& why) {
  throw OutputRefused(argument + " " + path.string() + ": " + why);
}

[[noreturn]] void refuse(const fs::path& path, const std::string& why) { refuse("--out", path, why); }

std::string kind_of(mode_t mode) {
  if (S_ISREG(mode)) return "a regular file";
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

bool is_pbdbench_file(const fs::path& path, const std::string& content) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  if (!has_hdf5_signature(path)) return false;
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_file_locking(fapl, false, true);
  bool ok = false;
  H5E_BEGIN_TRY {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
    if (file >= 0) {
      if (H5Aexists(file, "content") > 0) {
        const hid_t attr = H5Aopen(file, "content", H5P_DEFAULT);
        const hid_t type = attr >= 0 ? H5Aget_type(attr) : -1;
        if (type >= 0 && H5Tget_class(type) == H5T_STRING) {
          const hid_t space = H5Aget_space(attr);
          if (space >= 0 && H5Sget_simple_extent_type(space) == H5S_SCALAR) {
            if (H5Tis_variable_str(type) > 0) {
              char* text = nullptr;
              const hid_t mem = H5Tcopy(H5T_C_S1);
              H5Tset_size(mem, H5T_VARIABLE);
              H5Tset_cset(mem, H5Tget_cset(type));  // pbdbench writes UTF-8: no conversion
              if (H5Aread(attr, mem, &text) >= 0 && text != nullptr) {
                ok = content == text;
                H5free_memory(text);
              }
              H5Tclose(mem);
            } else {
              const size_t size = H5Tget_size(type);
              std::string text(size, '\0');
              const hid_t mem = H5Tcopy(H5T_C_S1);
              H5Tset_size(mem, size);
              H5Tset_cset(mem, H5Tget_cset(type));
              if (size > 0 && H5Aread(attr, mem, text.data()) >= 0) {
                text.resize(std::strlen(text.c_str()));
                ok = content == text;
              }
              H5Tclose(mem);
            }
          }
          if (space >= 0) H5Sclose(space);
        }
        if (type >= 0) H5Tclose(type);
        if (attr >= 0) H5Aclose(attr);
      }
      H5Fclose(file);
    }
  }
  H5E_END_TRY;
  H5Pclose(fapl);
  return ok;
}

bool has_marker(const fs::path& path, const std::string& marker, std::size_t within) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  std::ifstream in(path, std::ios::binary);
  std::string head(within, '\0');
  in.read(head.data(), static_cast<std::streamsize>(within));
  head.resize(static_cast<size_t>(in.gcount()));
  return head.find(marker) != std::string::npos;
}

void check_output(const fs::path& path, const OutputTarget& target) {
  const std::string& arg = target.argument;
  if (path.empty()) throw OutputRefused(arg + ": the path is empty");
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    refuse(arg, path, std::string("cannot be examined: ") + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode))
    refuse(arg, path, "is " + kind_of(st.st_mode) + ", not a " + target.kind + ": nothing was written");
  for (const OutputInput& input : target.inputs) {
    std::error_code ec;
    if (!input.path.empty() && fs::equivalent(path, input.path, ec))
      refuse(arg, path, "is " + input.what + " itself: nothing was written");
  }
  if (!target.ours || !target.ours(path))
    refuse(arg, path, "exists and is not a pbdbench " + target.kind +
                          " (checked by its content): nothing was written; remove it or choose another path");
}

void check_output_folder(const fs::path& folder, const std::string& argument, const std::vector<OutputInput>& inputs) {
  if (folder.empty()) throw OutputRefused(argument + ": the path is empty");
  struct stat st {};
  if (::lstat(folder.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    refuse(argument, folder, std::string("cannot be examined: ") + std::strerror(errno));
  }
  if (S_ISLNK(st.st_mode) && ::stat(folder.c_str(), &st) != 0)
    refuse(argument, folder, "is a symbolic link to nothing (" + std::string(std::strerror(errno)) +
                                 "), not a folder: nothing was written");
  for (const OutputInput& input : inputs) {
    std::error_code ec;
    if (!input.path.empty() && fs::equivalent(folder, input.path, ec))
      refuse(argument, folder, "is " + input.what + " itself: nothing was written");
  }
  if (!S_ISDIR(st.st_mode))
    refuse(argument, folder, "is " + kind_of(st.st_mode) + ", not a folder: nothing was written");
}

fs::path claim_temporary(const fs::path& path, const std::string& argument) {
  const fs::path tmp(path.string() + ".tmp");
  struct stat st {};
  if (::lstat(tmp.c_str(), &st) != 0) return tmp;
  if (!S_ISREG(st.st_mode))
    refuse(argument, path, "its temporary " + tmp.string() + " is in the way and is " + kind_of(st.st_mode) +
                               ": nothing was written");
  ::unlink(tmp.c_str());  // a killed writer's
  return tmp;
}

int create_exclusive(const fs::path& path, const std::string& argument) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    refuse(argument, path, std::string("cannot create it afresh: ") + std::strerror(err) +
                               (err == EEXIST ? " (something was put there meanwhile)" : "") + ": nothing was written");
  }
  return fd;
}

void write_text_output(const fs::path& path, const std::string& text, const std::string& argument) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  const fs::path tmp = claim_temporary(path, argument);
  const int fd = create_exclusive(tmp, argument);
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(err));
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  }
  fs::rename(tmp, path);
}

void check_output_path(const fs::path& path, const fs::path& protect) {
  check_output(path, OutputTarget{"--out", "run file", is_run_file, {{protect, "the scenario file"}}});
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
