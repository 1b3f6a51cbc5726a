#include "runfile/disk_worker.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <system_error>

namespace pbdbench {

namespace {

// At most this many writebacks wait: a start is worth little once the file has changed again.
constexpr long kMaxWritebacks = 4;

}  // namespace

DiskWorker::~DiskWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (const auto& job : todo_) ::close(job.second);  // none: the thread drained them
}

void DiskWorker::start_writeback(int fd) {
  const int copy = ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
  if (copy < 0) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto writebacks = std::count_if(todo_.begin(), todo_.end(),
                                          [](const auto& job) { return job.first == Job::Writeback; });
    if (writebacks >= kMaxWritebacks) {
      const auto oldest = std::find_if(todo_.begin(), todo_.end(),
                                       [](const auto& job) { return job.first == Job::Writeback; });
      ::close(oldest->second);
      todo_.erase(oldest);
    }
    todo_.emplace_back(Job::Writeback, copy);
    if (!started_locked()) {  // no thread: the writeback is left to the kernel
      ::close(copy);
      todo_.pop_back();
      return;
    }
  }
  wake_.notify_one();
}

void DiskWorker::drop_writebacks() {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = todo_.begin(); it != todo_.end();) {
    if (it->first != Job::Writeback) {
      ++it;
      continue;
    }
    ::close(it->second);
    it = todo_.erase(it);
  }
}

void DiskWorker::release(int fd) {
  if (fd < 0) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    todo_.emplace_back(Job::Close, fd);
    if (!started_locked()) {  // no thread: closed here
      todo_.pop_back();
      ::close(fd);
      return;
    }
  }
  wake_.notify_one();
}

// Starts the thread if it is not running; false if it cannot be started (the caller then does
// without it: none of this work may fail a run).
bool DiskWorker::started_locked() {
  if (thread_.joinable()) return true;
  try {
    thread_ = std::thread([this] { work(); });
  } catch (const std::system_error&) {
    return false;
  }
  return true;
}

long DiskWorker::done() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return done_;
}

// Works through the queue; once stopped, finishes it (closing what is left) and returns.
void DiskWorker::work() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || !todo_.empty(); });
    if (todo_.empty()) return;  // stopped
    const auto [job, fd] = todo_.front();
    todo_.pop_front();
    const bool stopping = stop_;
    lock.unlock();
    if (job == Job::Writeback && !stopping) ::sync_file_range(fd, 0, 0, SYNC_FILE_RANGE_WRITE);
    ::close(fd);
    lock.lock();
    ++done_;
  }
}

}  // namespace pbdbench
