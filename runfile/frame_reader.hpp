// The frames of a run file one at a time (runfile/run_file.hpp's /frames), for readers whose
// memory must not grow with the run's length: the ParaView export (runfile/xdmf.cpp) holds one
// frame, where read_run_file with RunFileParts::Frames::All holds them all (a 60 s run of a
// 64 x 64 cloth: 3,600 frames, 1.4 GB of positions and velocities).
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <vector>

#include "core/types.hpp"

namespace pbdbench {

// Called with the frame's index (from 0), its time (s), its positions and, when the file has
// them and they were asked for, its velocities (else nullptr).
using FrameVisitor = std::function<void(std::size_t frame, double time, const Points& x, const Points* v)>;

// Visits the frames of `path` in order, reading one at a time, and returns their times (empty
// when the file has none). Throws std::runtime_error naming the path when the file or its frames
// cannot be read (shapes as read_run_file checks them); what `visit` throws passes through.
std::vector<double> for_each_frame(const std::filesystem::path& path, bool velocities, const FrameVisitor& visit);

}  // namespace pbdbench
