// The run file's work with the disk that the run need not wait for, on a thread of its own:
// starting the writeback of published images, and closing the last descriptor of files removed.
//
// A published image (runfile/shadow_file.hpp) is not written again until the publish after next
// makes it the working copy, so its pages can go to disk at once, while the run goes on. Left
// alone, they waited for the final publish's fsync, which then wrote the whole image at the end
// of the run (192 ms at the end of a 20 s run of the 256 x 256 cloth, whose file is 370 MB), or,
// while the working copy was renamed over the published file, for ext4 to start them inside each
// rename, on the run's thread (about 100 ms over the same run).
// Here each one's writeback is started (sync_file_range with SYNC_FILE_RANGE_WRITE: the dirty
// pages are queued for the disk, nothing waits for them to get there). And a removed file's
// pages and blocks are freed by the kernel in the close of its last descriptor (9.5 ms for the
// 25 MB file of a 64 x 64 cloth's run that a new run replaces): that close is done here too.
// Neither changes a byte of any file.
#pragma once

#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>

namespace pbdbench {

class DiskWorker {
 public:
  DiskWorker() = default;
  ~DiskWorker();  // does what is queued and joins
  DiskWorker(const DiskWorker&) = delete;
  DiskWorker& operator=(const DiskWorker&) = delete;

  // Queues the start of the writeback of the file open as `fd` (a duplicate of the descriptor is
  // kept until it is done; the caller keeps its own). The thread starts on first use. Failures
  // (no descriptor to spare, no thread) are ignored: the pages then reach the disk when the
  // kernel or a later fsync writes them, as without this.
  void start_writeback(int fd);
  // Drops the writebacks not yet started (their files need not reach the disk).
  void drop_writebacks();
  // Takes `fd` over and closes it (here, if no thread can be started).
  void release(int fd);
  // Jobs done so far (for tests).
  long done() const;

 private:
  enum class Job { Writeback, Close };
  bool started_locked();  // with mutex_ held
  void work();

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::pair<Job, int>> todo_;  // descriptors this object owns
  long done_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace pbdbench
