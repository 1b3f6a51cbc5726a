// Compresses the run file's frames off the stepping thread.
//
// A frame of positions and velocities is what a run writes in bulk (2 x n x 3 doubles each
// 1/60 s), and deflating it in the stepping thread was most of the harness's cost on large cloths
// (22 % of a 256 x 256 cloth run's samples under perf record). The writer hands each frame's bytes to a
// FrameCompressor, whose one worker thread deflates them (libdeflate, a zlib stream: the format
// of HDF5's deflate filter) while the run steps on; the writer takes the finished chunks back in order and stores
// them as they are (H5Dwrite_chunk), so every HDF5 call stays on the writer's thread.
//
// Pure byte work: no HDF5 here. The output is a deterministic function of the input bytes.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <initializer_list>
#include <mutex>
#include <thread>
#include <vector>

namespace pbdbench {

// One chunk, deflated when that made it smaller (else `deflated` is false and `bytes` is the
// input as given: HDF5 is then told that the filter was skipped for this chunk).
struct CompressedChunk {
  long long index = 0;  // the order it was submitted in (0, 1, 2, ...)
  std::vector<unsigned char> bytes;
  bool deflated = false;
};

// A zlib stream (RFC 1950, what HDF5's deflate filter reads and writes) of `size` bytes at
// `level` (1 fastest .. 12 smallest), made by libdeflate: on a cloth's frames its level 1 is 2.5
// to 2.8 times as fast as zlib's compress2 at level 1, the output within 1 % of zlib's size
// (bench_solvers frame_deflate/*). Any zlib inflates it.
CompressedChunk deflate_chunk(const void* data, size_t size, int level);
// The inverse, for tests: inflates `c` to `size` bytes (or copies it when it was not deflated).
std::vector<unsigned char> inflate_chunk(const CompressedChunk& c, size_t size);

// Deflating pays on some frames (a flat cloth's regular coordinates shrink to a third) and barely
// on others (a swinging cloth's positions and velocities keep 93 to 95 % of their bytes:
// bench_solvers frame_deflate/*). So the chunks are taken as `streams` interleaved streams (chunk
// i belongs to stream i % streams: the writer's positions and velocities), and after a chunk of a
// stream deflated to more than kPaysBelow of its size, the next kSkipAfterPoor chunks of that
// stream are stored as they are without trying; the one after is tried again. A chunk stored
// as it is is marked so (deflated = false; HDF5's filter mask says the filter was skipped),
// which every reader handles. The choice depends on the bytes alone: the same frames give the
// same file.
class FrameCompressor {
 public:
  static constexpr double kPaysBelow = 0.9;
  static constexpr int kSkipAfterPoor = 15;
  explicit FrameCompressor(int level, int streams = 2);
  ~FrameCompressor();  // waits for the worker (finished chunks not taken are dropped)
  FrameCompressor(const FrameCompressor&) = delete;
  FrameCompressor& operator=(const FrameCompressor&) = delete;

  // Queues a copy of `size` bytes; returns its index (0, 1, 2, ... in call order).
  long long submit(const void* data, size_t size);
  // Queues copies of `size` bytes at each of `parts` as consecutive chunks (a frame's positions
  // and velocities) and wakes the worker once for them all; returns the first one's index.
  long long submit(std::initializer_list<const void*> parts, size_t size);
  // The finished chunks, in submission order, up to the first one not finished yet; with
  // `wait`, every submitted chunk (blocks until the worker is done with all of them).
  std::vector<CompressedChunk> take(bool wait);
  // Chunks submitted and not yet taken.
  long long outstanding() const;

 private:
  void work();

  const int level_;
  const int streams_;
  std::vector<int> skip_;  // per stream: chunks still to store without trying (the worker's)
  mutable std::mutex mutex_;
  std::condition_variable wake_worker_, done_;
  std::deque<std::pair<long long, std::vector<unsigned char>>> todo_;
  std::deque<CompressedChunk> finished_;  // in index order
  static constexpr size_t kSpareBuffers = 4;
  std::vector<std::vector<unsigned char>> spare_;  // input buffers the worker is done with
  long long submitted_ = 0, taken_ = 0;
  bool stop_ = false;
  std::thread worker_;
};

}  // namespace pbdbench
