// The shadow-copy file driver and publish(): see shadow_file.hpp.
//
// The driver is HDF5's POSIX driver reduced to what the run file writer needs (pread, pwrite,
// ftruncate on one descriptor), plus the list of byte ranges written since the last publish.
// HDF5 never learns that the descriptor it writes through changes at each publish: after the
// exchange (or rename) the driver's descriptor is swapped for the previous published file's, which by then
// holds the same bytes.
#include "runfile/shadow_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <H5FDpublic.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>  // renameat2
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <utility>
#include <vector>

namespace pbdbench {

namespace {

// One open file of the driver. `pub` must come first: HDF5 sees an H5FD_t*.
struct ShadowFile {
  H5FD_t pub;
  int fd = -1;     // the working copy: every read and write
  int other = -1;  // the published file (after the first publish): the next working copy
  haddr_t eoa = 0;
  haddr_t eof = 0;
  dev_t device = 0;
  ino_t inode = 0;
  std::vector<std::pair<haddr_t, haddr_t>> dirty;  // [begin, end) written since the last publish
  int last_errno = 0;
  bool sealed = false;  // published for the last time: fd is the published file, never written
};

constexpr haddr_t kMaxAddr = (static_cast<haddr_t>(1) << 62) - 1;

ShadowFile* cast(H5FD_t* f) { return reinterpret_cast<ShadowFile*>(f); }
const ShadowFile* cast(const H5FD_t* f) { return reinterpret_cast<const ShadowFile*>(f); }

// Merges the dirty ranges in place (sorted, disjoint).
void merge_ranges(std::vector<std::pair<haddr_t, haddr_t>>& ranges) {
  if (ranges.empty()) return;
  std::sort(ranges.begin(), ranges.end());
  size_t out = 0;
  for (size_t i = 1; i < ranges.size(); ++i) {
    if (ranges[i].first <= ranges[out].second)
      ranges[out].second = std::max(ranges[out].second, ranges[i].second);
    else
      ranges[++out] = ranges[i];
  }
  ranges.resize(out + 1);
}

H5FD_t* shadow_open(const char* name, unsigned flags, hid_t, haddr_t maxaddr) {
  if (!name || !*name || maxaddr == 0 || (maxaddr != HADDR_UNDEF && maxaddr > kMaxAddr)) return nullptr;
  int o = O_CLOEXEC;
  o |= (flags & H5F_ACC_RDWR) ? O_RDWR : O_RDONLY;
  if (flags & H5F_ACC_TRUNC) o |= O_TRUNC;
  if (flags & H5F_ACC_CREAT) o |= O_CREAT;
  if (flags & H5F_ACC_EXCL) o |= O_EXCL;
  const int fd = ::open(name, o, 0644);
  if (fd < 0) return nullptr;
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    return nullptr;
  }
  auto* f = new (std::nothrow) ShadowFile();
  if (!f) {
    ::close(fd);
    return nullptr;
  }
  f->fd = fd;
  f->eof = static_cast<haddr_t>(st.st_size);
  f->device = st.st_dev;
  f->inode = st.st_ino;
  return &f->pub;
}

herr_t shadow_close(H5FD_t* file) {
  ShadowFile* f = cast(file);
  int rc = 0;
  if (f->fd >= 0 && ::close(f->fd) != 0) rc = -1;
  if (f->other >= 0) ::close(f->other);
  delete f;
  return rc;
}

int shadow_cmp(const H5FD_t* a, const H5FD_t* b) {
  const ShadowFile* x = cast(a);
  const ShadowFile* y = cast(b);
  if (x->device != y->device) return x->device < y->device ? -1 : 1;
  if (x->inode != y->inode) return x->inode < y->inode ? -1 : 1;
  return 0;
}

herr_t shadow_query(const H5FD_t*, unsigned long* flags) {
  if (flags)
    *flags = H5FD_FEAT_AGGREGATE_METADATA | H5FD_FEAT_ACCUMULATE_METADATA | H5FD_FEAT_DATA_SIEVE |
             H5FD_FEAT_AGGREGATE_SMALLDATA | H5FD_FEAT_DEFAULT_VFD_COMPATIBLE;
  return 0;
}

haddr_t shadow_get_eoa(const H5FD_t* file, H5FD_mem_t) { return cast(file)->eoa; }

herr_t shadow_set_eoa(H5FD_t* file, H5FD_mem_t, haddr_t addr) {
  cast(file)->eoa = addr;
  return 0;
}

haddr_t shadow_get_eof(const H5FD_t* file, H5FD_mem_t) { return cast(file)->eof; }

// The handle is the driver's own struct: shadow_publish() reaches it through H5Fget_vfd_handle.
herr_t shadow_get_handle(H5FD_t* file, hid_t, void** handle) {
  if (!handle) return -1;
  *handle = file;
  return 0;
}

herr_t shadow_read(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, void* buffer) {
  ShadowFile* f = cast(file);
  if (addr == HADDR_UNDEF || addr + size > f->eoa) return -1;
  auto* out = static_cast<unsigned char*>(buffer);
  while (size > 0) {
    const ssize_t n = ::pread(f->fd, out, size, static_cast<off_t>(addr));
    if (n < 0) {
      if (errno == EINTR) continue;
      f->last_errno = errno;
      return -1;
    }
    if (n == 0) {  // past the end of the file: zeros, as HDF5's own drivers return
      std::memset(out, 0, size);
      break;
    }
    out += n;
    addr += static_cast<haddr_t>(n);
    size -= static_cast<size_t>(n);
  }
  return 0;
}

herr_t shadow_write(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, const void* buffer) {
  ShadowFile* f = cast(file);
  if (addr == HADDR_UNDEF || addr + size > f->eoa) return -1;
  if (f->sealed) return 0;  // after the last publish: dropped (shadow_publish, PublishNext::Last)
  const haddr_t begin = addr;
  const auto* in = static_cast<const unsigned char*>(buffer);
  while (size > 0) {
    const ssize_t n = ::pwrite(f->fd, in, size, static_cast<off_t>(addr));
    if (n < 0) {
      if (errno == EINTR) continue;
      f->last_errno = errno;
      return -1;
    }
    in += n;
    addr += static_cast<haddr_t>(n);
    size -= static_cast<size_t>(n);
  }
  try {
    f->dirty.emplace_back(begin, addr);
    if (f->dirty.size() > 4096) merge_ranges(f->dirty);  // the list stays short
  } catch (...) {
    return -1;
  }
  f->eof = std::max(f->eof, addr);
  return 0;
}

herr_t shadow_truncate(H5FD_t* file, hid_t, hbool_t) {
  ShadowFile* f = cast(file);
  if (f->sealed || f->eoa == f->eof) return 0;
  if (::ftruncate(f->fd, static_cast<off_t>(f->eoa)) != 0) {
    f->last_errno = errno;
    return -1;
  }
  f->eof = f->eoa;
  return 0;
}

H5FD_class_t make_class() {
  H5FD_class_t c{};
  c.name = "pbdbench-shadow";
  c.maxaddr = kMaxAddr;
  c.fc_degree = H5F_CLOSE_WEAK;
  c.open = shadow_open;
  c.close = shadow_close;
  c.cmp = shadow_cmp;
  c.query = shadow_query;
  c.get_eoa = shadow_get_eoa;
  c.set_eoa = shadow_set_eoa;
  c.get_eof = shadow_get_eof;
  c.get_handle = shadow_get_handle;
  c.read = shadow_read;
  c.write = shadow_write;
  c.truncate = shadow_truncate;
  const H5FD_mem_t map[H5FD_MEM_NTYPES] = H5FD_FLMAP_DICHOTOMY;
  std::copy(map, map + H5FD_MEM_NTYPES, c.fl_map);
  return c;
}

[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what, int err) {
  throw std::runtime_error("run file " + path.string() + ": " + what + ": " + std::strerror(err));
}

void write_all(int fd, const unsigned char* data, size_t size, off_t at, const std::filesystem::path& path,
               const char* what) {
  while (size > 0) {
    const ssize_t n = ::pwrite(fd, data, size, at);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail(path, what, errno);
    }
    data += n;
    at += n;
    size -= static_cast<size_t>(n);
  }
}

// Copies byte ranges between two files at the same offsets: within the kernel
// (copy_file_range: the bytes are not brought into this process and written back) while the
// kernel and the filesystems allow it, else through a buffer of this process.
struct RangeCopier {
  bool in_kernel = true;
  std::unique_ptr<unsigned char[]> buffer;  // allocated on first use, not zeroed
  static constexpr size_t kBuffer = 1 << 20;
};

// Copies [begin, end) of `from` into `to` at the same offsets.
std::uint64_t copy_range(int from, int to, haddr_t begin, haddr_t end, RangeCopier& copier,
                         const std::filesystem::path& path) {
  std::uint64_t copied = 0;
  while (begin < end && copier.in_kernel) {
    loff_t in = static_cast<loff_t>(begin), out = static_cast<loff_t>(begin);
    const ssize_t n = ::copy_file_range(from, &in, to, &out, static_cast<size_t>(end - begin), 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      // Not between these files (another filesystem, a kernel without it): the buffer instead.
      if (errno == ENOSYS || errno == EXDEV || errno == EINVAL || errno == EOPNOTSUPP ||
          errno == ENOTSUP || errno == EBADF || errno == EPERM) {
        copier.in_kernel = false;
        break;
      }
      fail(path, "cannot update the working copy", errno);
    }
    if (n == 0) return copied;  // past the end: nothing to copy
    begin += static_cast<haddr_t>(n);
    copied += static_cast<std::uint64_t>(n);
  }
  if (begin < end && !copier.buffer) copier.buffer = std::make_unique_for_overwrite<unsigned char[]>(RangeCopier::kBuffer);
  unsigned char* buffer = copier.buffer.get();
  while (begin < end) {
    const size_t want = static_cast<size_t>(std::min<haddr_t>(end - begin, RangeCopier::kBuffer));
    const ssize_t n = ::pread(from, buffer, want, static_cast<off_t>(begin));
    if (n < 0) {
      if (errno == EINTR) continue;
      fail(path, "cannot read the published file back", errno);
    }
    if (n == 0) break;  // past the end: nothing to copy
    write_all(to, buffer, static_cast<size_t>(n), static_cast<off_t>(begin), path,
              "cannot update the working copy");
    begin += static_cast<haddr_t>(n);
    copied += static_cast<std::uint64_t>(n);
  }
  return copied;
}

void sync_directory(const std::filesystem::path& path) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void next_working_copy(ShadowFile& f, const std::filesystem::path& published, bool exchanged,
                       bool linked, PublishStats& stats);

}  // namespace

hid_t shadow_driver() {
  static std::once_flag once;
  static hid_t id = -1;
  std::call_once(once, [] {
    static const H5FD_class_t cls = make_class();
    id = H5FDregister(&cls);
  });
  if (id < 0) throw std::runtime_error("cannot register the run file's HDF5 driver");
  return id;
}

std::filesystem::path shadow_path(const std::filesystem::path& published) {
  return std::filesystem::path(published.string() + ".shadow");
}

PublishStats shadow_publish(hid_t file, const std::filesystem::path& published, bool durable,
                            PublishNext next, DiskWorker* disk) {
  void* handle = nullptr;
  if (H5Fget_vfd_handle(file, H5P_DEFAULT, &handle) < 0 || !handle)
    throw std::runtime_error("run file " + published.string() + ": not open with the shadow driver");
  ShadowFile& f = *static_cast<ShadowFile*>(handle);
  if (f.sealed) throw std::logic_error("run file " + published.string() + ": published after its last publish");
  const std::filesystem::path shadow = shadow_path(published);
  const std::filesystem::path previous(published.string() + ".previous");
  PublishStats stats;

  // The images published before need not reach the disk now: only this one does, if durable.
  if (next == PublishNext::Last && disk != nullptr) disk->drop_writebacks();
  if (durable && ::fsync(f.fd) != 0) fail(published, "cannot sync " + shadow.string(), errno);

  // 1. The working copy becomes the published file, atomically. Where the previous image is
  // still ours (f.other) and more is to be written, the two names are exchanged in one step
  // (renameat2 RENAME_EXCHANGE): <path> names the new image and the working copy's name the
  // previous one, to be brought up to date below. Exchanging rather than renaming over <path>
  // also keeps ext4 from starting the new image's writeback inside the call, on the run's
  // thread (its replace-by-rename rule, auto_da_alloc, which is for power cuts, which a publish
  // that is not durable does not survive anyway: results/README.md, "Crash safety"); step 3
  // starts it off this thread instead (runfile/disk_worker.hpp).
  // At the first publish over a file that was there before (a finished run's, which the writer
  // may replace: output_guard.hpp), the names are exchanged too and that file's new name removed.
  // Else, or where the exchange fails (a filesystem without it, <path> gone): the published file
  // gets a second name, then the working copy is renamed over it.
  const bool ours = f.other >= 0;
  bool exchanged = false, linked = false;
  if (next == PublishNext::Working) {
    struct stat st {};
    if (ours || (::lstat(published.c_str(), &st) == 0 && S_ISREG(st.st_mode)))
      exchanged = ::renameat2(AT_FDCWD, shadow.c_str(), AT_FDCWD, published.c_str(), RENAME_EXCHANGE) == 0;
    if (exchanged && !ours) {
      // Its pages and blocks are freed in the close of its last descriptor, off this thread.
      const int replaced = disk != nullptr ? ::open(shadow.c_str(), O_RDONLY | O_CLOEXEC) : -1;
      ::unlink(shadow.c_str());
      if (disk != nullptr) disk->release(replaced);
    }
  }
  if (!exchanged) {
    if (f.other >= 0) {
      ::unlink(previous.c_str());  // a leftover of a process killed between the renames
      if (next == PublishNext::Working) linked = ::link(published.c_str(), previous.c_str()) == 0;
    }
    if (::rename(shadow.c_str(), published.c_str()) != 0) {
      const int err = errno;
      if (linked) ::unlink(previous.c_str());
      fail(published, "cannot rename " + shadow.string() + " to it", err);
    }
  }
  stats.exchanged = exchanged;
  if (durable) sync_directory(published);
  if (next == PublishNext::Last) {
    // Sealed: the descriptor is the published file now, read from while the library closes it
    // and never written (shadow_write, shadow_truncate).
    if (f.other >= 0) ::close(f.other);
    f.other = -1;
    f.dirty.clear();
    f.sealed = true;
    return stats;
  }

  // 2. The next working copy: the previous published file brought up to date, or a full copy.
  // Should this fail, the driver must not write into what is now the published file.
  try {
    next_working_copy(f, published, exchanged && ours, linked, stats);
  } catch (...) {
    ::close(f.fd);
    f.fd = -1;
    if (f.other >= 0) ::close(f.other);
    f.other = -1;
    throw;
  }
  // 3. The new image is not written again before the publish after next: its pages may go to
  // disk now, off this thread; and so may the ranges just copied into the next working copy
  // (the final publish's fsync then writes only what the library wrote after this publish).
  if (disk != nullptr) {
    disk->start_writeback(f.other);
    disk->start_writeback(f.fd);
  }
  return stats;
}

namespace {

// `exchanged`: the previous image (f.other) is at the working copy's name already; `linked`: it
// is at "<path>.previous".
void next_working_copy(ShadowFile& f, const std::filesystem::path& published, bool exchanged,
                       bool linked, PublishStats& stats) {
  const std::filesystem::path shadow = shadow_path(published);
  const std::filesystem::path previous(published.string() + ".previous");
  RangeCopier copier;
  int next = -1;
  if (exchanged || (linked && ::rename(previous.c_str(), shadow.c_str()) == 0)) {
    next = f.other;
    merge_ranges(f.dirty);
    for (const auto& [begin, end] : f.dirty)
      stats.bytes_copied += copy_range(f.fd, next, begin, std::min(end, f.eof), copier, published);
  } else {
    if (f.other >= 0) ::close(f.other);
    f.other = -1;
    next = ::open(shadow.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (next < 0) fail(published, "cannot create " + shadow.string(), errno);
    try {
      stats.bytes_copied = copy_range(f.fd, next, 0, f.eof, copier, published);
    } catch (...) {
      ::close(next);
      throw;
    }
    stats.full_copy = true;
  }
  if (::ftruncate(next, static_cast<off_t>(f.eof)) != 0) {
    const int err = errno;
    if (next != f.other) ::close(next);
    fail(published, "cannot resize " + shadow.string(), err);
  }
  f.dirty.clear();
  f.other = f.fd;  // the published file, read from at the next publish
  f.fd = next;
}

}  // namespace

}  // namespace pbdbench
