# CHOLMOD and KLU from SuiteSparse 5.x (Debian's libsuitesparse-dev), as imported targets of our
# own namespace:
#
#   pbdbench::cholmod   supernodal sparse Cholesky (cholmod.h), with AMD, COLAMD, CAMD, CCOLAMD
#   pbdbench::klu       sparse LU with partial pivoting (klu.h), with BTF, AMD, COLAMD
#
# SuiteSparse 5 ships no CMake config and no pkg-config file, so the header and each library are
# found by hand. The names are ours on purpose: find_package(Ceres) defines SuiteSparse::CHOLMOD
# and friends in the caller's scope, and SUNDIALS defines SUNDIALS::KLU.
find_path(PBDBENCH_SUITESPARSE_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED
          DOC "directory of cholmod.h and klu.h (SuiteSparse)")
foreach(_ss_lib cholmod klu btf amd colamd camd ccolamd suitesparseconfig)
  find_library(PBDBENCH_SUITESPARSE_${_ss_lib}_LIBRARY NAMES ${_ss_lib} REQUIRED
               DOC "SuiteSparse library ${_ss_lib}")
  if(NOT TARGET pbdbench::ss_${_ss_lib})
    add_library(pbdbench::ss_${_ss_lib} UNKNOWN IMPORTED)
    set_target_properties(pbdbench::ss_${_ss_lib} PROPERTIES
      IMPORTED_LOCATION "${PBDBENCH_SUITESPARSE_${_ss_lib}_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${PBDBENCH_SUITESPARSE_INCLUDE_DIR}")
  endif()
endforeach()

if(NOT TARGET pbdbench::cholmod)
  add_library(pbdbench::cholmod INTERFACE IMPORTED)
  target_link_libraries(pbdbench::cholmod INTERFACE
    pbdbench::ss_cholmod pbdbench::ss_amd pbdbench::ss_colamd pbdbench::ss_camd
    pbdbench::ss_ccolamd pbdbench::ss_suitesparseconfig)
endif()
if(NOT TARGET pbdbench::klu)
  add_library(pbdbench::klu INTERFACE IMPORTED)
  target_link_libraries(pbdbench::klu INTERFACE
    pbdbench::ss_klu pbdbench::ss_btf pbdbench::ss_amd pbdbench::ss_colamd
    pbdbench::ss_suitesparseconfig)
endif()
