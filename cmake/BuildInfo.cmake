# Generates ${CMAKE_BINARY_DIR}/generated/build_info.cpp at every build (rewritten only when its
# content changes), so the git commit recorded in run files is never stale.
set(PBDBENCH_BUILD_INFO_CPP ${CMAKE_BINARY_DIR}/generated/build_info.cpp)
string(TOUPPER "${CMAKE_BUILD_TYPE}" _bt)
set(_flags "${CMAKE_CXX_FLAGS} ${CMAKE_CXX_FLAGS_${_bt}} -Wall -Wextra -ffp-contract=off")
if(PBDBENCH_SANITIZE)
  list(JOIN PBDBENCH_SANITIZE "," _san_list)  # a ';' would split the custom command's arguments
  string(APPEND _flags " -fsanitize=${_san_list}")
endif()
string(STRIP "${_flags}" _flags)
add_custom_target(pbdbench_build_info_gen
  COMMAND ${CMAKE_COMMAND}
    -DOUT=${PBDBENCH_BUILD_INFO_CPP}
    -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
    -DVERSION=${PROJECT_VERSION}
    "-DCOMPILER=${CMAKE_CXX_COMPILER_ID} ${CMAKE_CXX_COMPILER_VERSION}"
    -DBUILD_TYPE=${CMAKE_BUILD_TYPE}
    "-DFLAGS=${_flags}"
    -P ${PROJECT_SOURCE_DIR}/cmake/WriteBuildInfo.cmake
  BYPRODUCTS ${PBDBENCH_BUILD_INFO_CPP}
  COMMENT "Recording build provenance")
