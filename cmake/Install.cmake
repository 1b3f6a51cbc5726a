# `cmake --install build --prefix P` (P = CMAKE_INSTALL_PREFIX by default):
#
#   P/bin/pbdbench                  the command; it finds its data beside it at run time
#   P/share/pbdbench/               its data (config/data_dir.hpp): scenarios/, claims/,
#                                   reproductions/, regress/ (registry and baselines), studies/,
#                                   scripts/ (the Python loader and plots, scripts/slurm_check.sh)
#   P/share/doc/pbdbench/           README.md, docs/*.md, run-files.md (results/README.md)
#   P/include/pbdbench/             the headers of the exported libraries (#include "core/model.hpp")
#   P/lib/libpbdbench_*.a           the exported libraries
#   P/lib/cmake/pbdbench/           the CMake package: find_package(pbdbench) gives pbdbench::core
#                                   (the model and state), pbdbench::metrics,
#                                   pbdbench::solver_api (the solver interface),
#                                   pbdbench::solvers and pbdbench::reference (the families),
#                                   pbdbench::catalog (every solver by name: make_solver), and
#                                   pbdbench::runfile (the HDF5 run files), with their own
#                                   dependencies found from Debian's packages
#
# Nothing installed holds a path of the build machine: the tree can be moved as a whole.
include(CMakePackageConfigHelpers)

install(TARGETS pbdbench RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

set(PBDBENCH_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/pbdbench)
install(DIRECTORY scenarios studies DESTINATION ${PBDBENCH_INSTALL_DATADIR})
foreach(_dir claims reproductions regress)
  install(DIRECTORY ${_dir} DESTINATION ${PBDBENCH_INSTALL_DATADIR} FILES_MATCHING PATTERN "*.toml")
endforeach()
file(GLOB _pbdbench_python_scripts ${PROJECT_SOURCE_DIR}/scripts/*.py)
install(PROGRAMS ${_pbdbench_python_scripts} scripts/slurm_check.sh DESTINATION ${PBDBENCH_INSTALL_DATADIR}/scripts)
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR} FILES_MATCHING PATTERN "*.md")
install(FILES results/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR} RENAME run-files.md)

# The exported libraries: these and every pbdbench library they link, found by walking their
# links (so that a library split or moved keeps the export whole).
set(_pbdbench_exported)
function(_pbdbench_collect target)
  if(NOT TARGET ${target} OR target IN_LIST _pbdbench_exported)
    return()
  endif()
  get_target_property(_imported ${target} IMPORTED)
  if(_imported OR NOT target MATCHES "^pbdbench_")
    return()
  endif()
  set(_pbdbench_exported ${_pbdbench_exported} ${target} PARENT_SCOPE)
  set(_pbdbench_exported ${_pbdbench_exported} ${target})
  get_target_property(_links ${target} INTERFACE_LINK_LIBRARIES)
  get_target_property(_type ${target} TYPE)
  if(NOT _type STREQUAL "INTERFACE_LIBRARY")
    get_target_property(_more ${target} LINK_LIBRARIES)
    list(APPEND _links ${_more})
  endif()
  foreach(_link IN LISTS _links)
    if(_link MATCHES "^\\$<LINK_ONLY:(.*)>$")
      set(_link ${CMAKE_MATCH_1})
    endif()
    if(_link MATCHES "^pbdbench_")
      _pbdbench_collect(${_link})
      set(_pbdbench_exported ${_pbdbench_exported} PARENT_SCOPE)
    endif()
  endforeach()
endfunction()
foreach(_target pbdbench_core pbdbench_metrics pbdbench_solver_api pbdbench_solvers pbdbench_reference pbdbench_catalog pbdbench_runfile)
  _pbdbench_collect(${_target})
endforeach()

foreach(_target IN LISTS _pbdbench_exported)
  string(REGEX REPLACE "^pbdbench_" "" _name ${_target})
  set_target_properties(${_target} PROPERTIES EXPORT_NAME ${_name})
  get_target_property(_type ${_target} TYPE)
  if(NOT _type STREQUAL "INTERFACE_LIBRARY")
    # The headers of the library's folder, under the same relative path.
    get_target_property(_src ${_target} SOURCE_DIR)
    file(RELATIVE_PATH _rel ${PROJECT_SOURCE_DIR} ${_src})
    install(DIRECTORY ${_src}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/pbdbench/${_rel}
            FILES_MATCHING PATTERN "*.hpp")
  endif()
endforeach()
install(TARGETS ${_pbdbench_exported} EXPORT pbdbenchTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/pbdbench)
set(PBDBENCH_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/pbdbench)
install(EXPORT pbdbenchTargets NAMESPACE pbdbench:: DESTINATION ${PBDBENCH_CMAKE_DIR})
configure_package_config_file(cmake/pbdbenchConfig.cmake.in ${CMAKE_CURRENT_BINARY_DIR}/pbdbenchConfig.cmake
                              INSTALL_DESTINATION ${PBDBENCH_CMAKE_DIR})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/pbdbenchConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/pbdbenchConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/pbdbenchConfigVersion.cmake
              cmake/SuiteSparse.cmake
              cmake/Libdeflate.cmake
        DESTINATION ${PBDBENCH_CMAKE_DIR})
