// Tests of runfile/frame_compressor: deflate round trips, incompressible bytes kept as given,
// chunks taken back in submission order, and take(true) waiting for all of them.
#include "runfile/frame_compressor.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <iterator>
#include <vector>

namespace pbdbench {
namespace {

std::vector<double> smooth(int n, double scale) {
  std::vector<double> v(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) v[static_cast<size_t>(i)] = scale * (i / 3);
  return v;
}

std::vector<std::uint64_t> random_bits(int n) {
  std::vector<std::uint64_t> v(static_cast<size_t>(n));
  std::uint64_t x = 88172645463325252ull;
  for (auto& b : v) {
    x ^= x << 13, x ^= x >> 7, x ^= x << 17;
    b = x;
  }
  return v;
}

TEST(FrameCompressor, DeflatesAndInflatesBackExactly) {
  const std::vector<double> data = smooth(3000, 0.01);
  const size_t bytes = data.size() * sizeof(double);
  const CompressedChunk c = deflate_chunk(data.data(), bytes, 1);
  EXPECT_TRUE(c.deflated);
  EXPECT_LT(c.bytes.size(), bytes / 2);
  const std::vector<unsigned char> back = inflate_chunk(c, bytes);
  ASSERT_EQ(back.size(), bytes);
  EXPECT_EQ(std::memcmp(back.data(), data.data(), bytes), 0);
}

TEST(FrameCompressor, IncompressibleBytesAreKeptAsGiven) {
  const std::vector<std::uint64_t> data = random_bits(512);
  const size_t bytes = data.size() * sizeof(std::uint64_t);
  const CompressedChunk c = deflate_chunk(data.data(), bytes, 1);
  EXPECT_FALSE(c.deflated);
  ASSERT_EQ(c.bytes.size(), bytes);
  EXPECT_EQ(std::memcmp(c.bytes.data(), data.data(), bytes), 0);
}

TEST(FrameCompressor, ChunksComeBackInOrderAndWaitTakesThemAll) {
  FrameCompressor fc(1);
  std::vector<std::vector<double>> sent;
  for (int k = 0; k < 40; ++k) {
    sent.push_back(smooth(3000 + k, 0.5 + k));
    EXPECT_EQ(fc.submit(sent.back().data(), sent.back().size() * sizeof(double)), k);
  }
  std::vector<CompressedChunk> got = fc.take(false);  // whatever is finished, in order
  for (size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].index, static_cast<long long>(i));
  std::vector<CompressedChunk> rest = fc.take(true);
  EXPECT_EQ(fc.outstanding(), 0);
  got.insert(got.end(), std::make_move_iterator(rest.begin()), std::make_move_iterator(rest.end()));
  ASSERT_EQ(got.size(), sent.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].index, static_cast<long long>(i));
    const size_t bytes = sent[i].size() * sizeof(double);
    const std::vector<unsigned char> back = inflate_chunk(got[i], bytes);
    EXPECT_EQ(std::memcmp(back.data(), sent[i].data(), bytes), 0) << i;
  }
  EXPECT_TRUE(fc.take(true).empty());  // nothing outstanding: returns at once
}

// The same bytes give the same chunk (the run file's bytes are a function of the run).
TEST(FrameCompressor, Deterministic) {
  const std::vector<double> data = smooth(5000, 0.3);
  const CompressedChunk a = deflate_chunk(data.data(), data.size() * sizeof(double), 1);
  FrameCompressor fc(1);
  fc.submit(data.data(), data.size() * sizeof(double));
  const std::vector<CompressedChunk> b = fc.take(true);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(a.bytes, b[0].bytes);
}

TEST(FrameCompressor, AStreamWhoseDeflatingDidNotPayIsStoredAsItIsForAWhile) {
  // Two interleaved streams (chunk i in stream i % 2): stream 1 always smooth, stream 0 random
  // bits for its first 3 chunks, smooth after. Stream 1 is deflated every time; stream 0's random
  // chunks are not (the first tried, the next ones skipped), its first kSkipAfterPoor chunks
  // after a poor one are stored untried even once smooth, and the one after is deflated again.
  // Every chunk comes back bit for bit.
  FrameCompressor fc(1, 2);
  const int per_stream = FrameCompressor::kSkipAfterPoor + 6;
  std::vector<std::vector<unsigned char>> sent;
  for (int k = 0; k < per_stream; ++k)
    for (int stream = 0; stream < 2; ++stream) {
      std::vector<unsigned char> bytes;
      if (stream == 0 && k < 3) {
        const std::vector<std::uint64_t> r = random_bits(600 + k);
        bytes.resize(r.size() * sizeof(std::uint64_t));
        std::memcpy(bytes.data(), r.data(), bytes.size());
      } else {
        const std::vector<double> d = smooth(600 + k, 0.25 + k);
        bytes.resize(d.size() * sizeof(double));
        std::memcpy(bytes.data(), d.data(), bytes.size());
      }
      fc.submit(bytes.data(), bytes.size());
      sent.push_back(std::move(bytes));
    }
  const std::vector<CompressedChunk> got = fc.take(true);
  ASSERT_EQ(got.size(), sent.size());
  for (size_t i = 0; i < got.size(); ++i) {
    const std::vector<unsigned char> back = inflate_chunk(got[i], sent[i].size());
    ASSERT_EQ(back, sent[i]) << "chunk " << i;
    const int k = static_cast<int>(i / 2);
    if (i % 2 == 1) {
      EXPECT_TRUE(got[i].deflated) << "stream 1, chunk " << k;
    } else {
      // Stream 0: tried at k = 0 (poor), skipped for k = 1..15 (the random k = 1, 2 and the
      // smooth k = 3..15), tried again at k = 16 (smooth: deflated), and deflated after.
      const bool tried_and_paid = k > FrameCompressor::kSkipAfterPoor;
      EXPECT_EQ(got[i].deflated, tried_and_paid) << "stream 0, chunk " << k;
    }
  }
}

}  // namespace
}  // namespace pbdbench
