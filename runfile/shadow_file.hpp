// A run file written through a shadow copy: the HDF5 library writes in place, but never into the
// file readers see.
//
//   <path>          the published file: a complete HDF5 image as of the last publish(), never
//                   written to again once published
//   <path>.shadow   the working copy the library reads and writes (an HDF5 file driver of our
//                   own, ShadowDriver, sends every read and write to it and remembers which byte
//                   ranges were written since the last publish)
//
// publish() makes the working copy the published file atomically, by exchanging the two names
// (renameat2 RENAME_EXCHANGE; where a filesystem cannot, by giving the published file a second
// name and renaming the working copy over it), and then brings the previous image up to date by
// copying into it only the byte ranges written since: it becomes the next working copy.
// So at every moment <path> is a complete image (the previous or the new one), a publish
// writes about twice the bytes the library wrote since the last one (never the whole file),
// and nothing is kept in memory but the list of those ranges. The cost: two copies of the file
// on disk while the run goes. The last publish (finish) prepares no next working copy: the
// previous image is removed, and from then on the driver writes nothing (what the library
// writes while it closes the file is dropped, as it went into a copy that was removed before).
// A filesystem that can neither exchange names nor make hard links falls back to copying the
// whole file at each publish (then the free space a publish needs is the file's size). The
// ranges are copied within the kernel (copy_file_range) where it can, else read and written
// back. Each new image's writeback to disk is started off the run's thread (disk_worker.hpp).
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <string>

#include "runfile/disk_worker.hpp"

namespace pbdbench {

// The HDF5 file driver id (registered on first use). A file access property list with this
// driver: H5Pset_driver(fapl, shadow_driver(), nullptr).
hid_t shadow_driver();

// The working copy's path for a published path: "<path>.shadow".
std::filesystem::path shadow_path(const std::filesystem::path& published);

// What comes after a publish: more writes (the next working copy is prepared), or none.
enum class PublishNext { Working, Last };

struct PublishStats {
  std::uint64_t bytes_copied = 0;  // bytes written into the next working copy by this publish
  bool full_copy = false;          // the whole file was copied (first publish, or no hard links)
  bool exchanged = false;          // the names were exchanged in one step (renameat2)
};

// Publishes the file `file` (opened with shadow_driver() at shadow_path(published)) at
// `published`; H5Fflush it first. With `durable`, the image and the rename are synced to disk.
// With PublishNext::Last the file is sealed: no working copy is left on disk, later writes and
// truncations through the driver do nothing, and only closing the file is left to do.
// With `disk`, the new image's writeback is started there once the next working copy is ready,
// and a file the first publish replaces is closed there (runfile/disk_worker.hpp); the last
// publish drops the writebacks still queued.
// Throws std::runtime_error naming the path on failure; the published file is then the
// previous image.
PublishStats shadow_publish(hid_t file, const std::filesystem::path& published, bool durable,
                            PublishNext next = PublishNext::Working, DiskWorker* disk = nullptr);

}  // namespace pbdbench
