#include "runfile/frame_compressor.hpp"

#include <libdeflate.h>
#include <pthread.h>
#include <zlib.h>

#include <cstring>
#include <stdexcept>
#include <string>

namespace pbdbench {

namespace {

// One libdeflate compressor per thread and level, kept: allocating one costs more than
// compressing a small frame.
struct Deflater {
  int level = -1;
  libdeflate_compressor* c = nullptr;
  ~Deflater() { libdeflate_free_compressor(c); }
  libdeflate_compressor* at(int wanted) {
    if (c == nullptr || level != wanted) {
      libdeflate_free_compressor(c);
      c = libdeflate_alloc_compressor(wanted);
      if (c == nullptr) throw std::runtime_error("libdeflate: no compressor at level " + std::to_string(wanted));
      level = wanted;
    }
    return c;
  }
};

}  // namespace

CompressedChunk deflate_chunk(const void* data, size_t size, int level) {
  thread_local Deflater deflater;
  CompressedChunk c;
  // An output buffer of the input's size: libdeflate returns 0 when the stream would not fit,
  // that is when deflating would not make the chunk smaller.
  c.bytes.resize(size);
  const size_t n = size == 0 ? 0 : libdeflate_zlib_compress(deflater.at(level), data, size, c.bytes.data(), size);
  if (n > 0 && n < size) {
    c.bytes.resize(n);
    c.deflated = true;
  } else {  // incompressible: stored as it is
    c.bytes.assign(static_cast<const unsigned char*>(data), static_cast<const unsigned char*>(data) + size);
    c.deflated = false;
  }
  return c;
}

std::vector<unsigned char> inflate_chunk(const CompressedChunk& c, size_t size) {
  if (!c.deflated) return c.bytes;
  std::vector<unsigned char> out(size);
  uLongf n = static_cast<uLongf>(size);
  const int rc = uncompress(out.data(), &n, c.bytes.data(), static_cast<uLong>(c.bytes.size()));
  if (rc != Z_OK || n != size) throw std::runtime_error("zlib uncompress failed with code " + std::to_string(rc));
  return out;
}

FrameCompressor::FrameCompressor(int level, int streams)
    : level_(level),
      streams_(streams > 0 ? streams : 1),
      skip_(static_cast<size_t>(streams > 0 ? streams : 1), 0),
      worker_([this] { work(); }) {}

FrameCompressor::~FrameCompressor() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_worker_.notify_all();
  worker_.join();
}

long long FrameCompressor::submit(const void* data, size_t size) { return submit({data}, size); }

long long FrameCompressor::submit(std::initializer_list<const void*> parts, size_t size) {
  // The copies go into buffers the worker has finished with, where there are some: a fresh
  // allocation of a frame's size is a fresh mapping whose pages fault in on every frame.
  std::vector<std::vector<unsigned char>> copies(parts.size());
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& copy : copies) {
      if (spare_.empty()) break;
      copy = std::move(spare_.back());
      spare_.pop_back();
    }
  }
  size_t k = 0;
  for (const void* data : parts)
    copies[k++].assign(static_cast<const unsigned char*>(data), static_cast<const unsigned char*>(data) + size);
  long long first;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    first = submitted_;
    for (auto& copy : copies) todo_.emplace_back(submitted_++, std::move(copy));
  }
  // One wake for the parts together: waking the worker costs the submitting thread a system
  // call (about 14 us each on a 2-core virtual machine, a frame's positions and
  // velocities woken apart).
  wake_worker_.notify_one();
  return first;
}

std::vector<CompressedChunk> FrameCompressor::take(bool wait) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (wait) done_.wait(lock, [this] { return taken_ + static_cast<long long>(finished_.size()) == submitted_; });
  std::vector<CompressedChunk> out;
  while (!finished_.empty()) {
    out.push_back(std::move(finished_.front()));
    finished_.pop_front();
  }
  taken_ += static_cast<long long>(out.size());
  return out;
}

long long FrameCompressor::outstanding() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return submitted_ - taken_;
}

void FrameCompressor::work() {
  pthread_setname_np(pthread_self(), "pbdbench-frames");  // how profilers and top show it
  for (;;) {
    std::pair<long long, std::vector<unsigned char>> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_worker_.wait(lock, [this] { return stop_ || !todo_.empty(); });
      if (todo_.empty()) return;  // stop_ and nothing left
      job = std::move(todo_.front());
      todo_.pop_front();
    }
    CompressedChunk c;
    int& skip = skip_[static_cast<size_t>(job.first % streams_)];
    if (skip > 0) {  // this stream's last try did not pay: stored as it is, untried
      --skip;
      c.bytes = job.second;
      c.deflated = false;
    } else {
      try {
        c = deflate_chunk(job.second.data(), job.second.size(), level_);
      } catch (...) {
        c.bytes = job.second;  // stored as it is: never lose a frame
        c.deflated = false;
      }
      if (static_cast<double>(c.bytes.size()) > kPaysBelow * static_cast<double>(job.second.size()))
        skip = kSkipAfterPoor;
    }
    c.index = job.first;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      finished_.push_back(std::move(c));  // one worker: finished in submission order
      if (!job.second.empty() && spare_.size() < kSpareBuffers) spare_.push_back(std::move(job.second));
    }
    done_.notify_all();
  }
}

}  // namespace pbdbench
