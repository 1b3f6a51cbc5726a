# libdeflate (Debian's libdeflate-dev) as an imported target of our own namespace:
#
#   pbdbench::libdeflate   fast DEFLATE/zlib compression (libdeflate.h): the run file's frames
#                          (runfile/frame_compressor.cpp)
#
# Debian 12's libdeflate 1.14 ships a pkg-config file but no CMake config, so the header and the
# library are found by hand, as for SuiteSparse; this file is installed beside the package's
# config, which includes it too.
find_path(PBDBENCH_LIBDEFLATE_INCLUDE_DIR libdeflate.h REQUIRED DOC "directory of libdeflate.h")
find_library(PBDBENCH_LIBDEFLATE_LIBRARY NAMES deflate REQUIRED DOC "the libdeflate library")
if(NOT TARGET pbdbench::libdeflate)
  add_library(pbdbench::libdeflate UNKNOWN IMPORTED)
  set_target_properties(pbdbench::libdeflate PROPERTIES
    IMPORTED_LOCATION "${PBDBENCH_LIBDEFLATE_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${PBDBENCH_LIBDEFLATE_INCLUDE_DIR}")
endif()
