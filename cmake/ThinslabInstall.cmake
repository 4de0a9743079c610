# SPDX-License-Identifier: Apache-2.0
# `cmake --install` (issue #25): headers under include/thinslab/<stage>/, the stage libraries,
# the CLI, data/ (found by the installed CLI relative to itself, app/data_directory.h), docs and
# a thinslabConfig.cmake with imported targets thinslab::<stage>, thinslab::refit (device-free)
# and thinslab::devices (acquisition and back-ends).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(THINSLAB_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/thinslab)
set(THINSLAB_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/thinslab/data)

# Umbrella targets: what a refit program links, and what an acquisition program adds.
add_library(thinslab_refit INTERFACE)
target_link_libraries(thinslab_refit INTERFACE thinslab_export thinslab_pipeline thinslab_fit thinslab_calib thinslab_optics
                                               thinslab_core)
add_library(thinslab_devices INTERFACE)
target_link_libraries(thinslab_devices INTERFACE thinslab_acquire thinslab_drivers)
set(thinslab_exported thinslab_core thinslab_optics thinslab_display_patterns thinslab_drivers thinslab_acquire
    thinslab_calib thinslab_fit thinslab_pipeline thinslab_export thinslab_sim thinslab_synth thinslab_refit thinslab_devices)
foreach(backend thinslab_aravis thinslab_v4l2 thinslab_display thinslab_usb_laser)
  if(TARGET ${backend})
    target_link_libraries(thinslab_devices INTERFACE ${backend})
    list(APPEND thinslab_exported ${backend})
  endif()
endforeach()
foreach(target IN LISTS thinslab_exported)
  string(REGEX REPLACE "^thinslab_" "" export_name ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${export_name})
  add_library(thinslab::${export_name} ALIAS ${target})
endforeach()

install(TARGETS ${thinslab_exported} EXPORT thinslabTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS thinslab RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The bash completion app/CMakeLists.txt generates after each build of the binary.
install(FILES ${PROJECT_BINARY_DIR}/share/bash-completion/completions/thinslab
        DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions)

# Public headers: every stage but app/ (the CLI's own), without test helpers and without the
# headers of back-ends this build left out.
set(thinslab_header_excludes PATTERN "*test*" EXCLUDE)
foreach(backend ARAVIS:aravis_* V4L2:v4l2_* SDL:pattern_window.h USB:usb_laser.h)
  string(REPLACE ":" ";" pair ${backend})
  list(GET pair 0 option)
  list(GET pair 1 pattern)
  if(NOT THINSLAB_WITH_${option})
    list(APPEND thinslab_header_excludes PATTERN "${pattern}" EXCLUDE)
  endif()
endforeach()
foreach(stage IN LISTS THINSLAB_STAGES)
  if(NOT stage STREQUAL "app")
    install(DIRECTORY ${PROJECT_SOURCE_DIR}/${stage}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/thinslab/${stage}
            FILES_MATCHING PATTERN "*.h" ${thinslab_header_excludes})
  endif()
endforeach()
install(FILES ${PROJECT_BINARY_DIR}/generated/thinslab/core/version.h
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/thinslab/core)

install(DIRECTORY ${PROJECT_SOURCE_DIR}/data/ DESTINATION ${THINSLAB_INSTALL_DATADIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})

install(EXPORT thinslabTargets NAMESPACE thinslab:: DESTINATION ${THINSLAB_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/thinslabConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/thinslabConfig.cmake
                              INSTALL_DESTINATION ${THINSLAB_INSTALL_CMAKEDIR}
                              PATH_VARS THINSLAB_INSTALL_DATADIR)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/thinslabConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/thinslabConfig.cmake ${PROJECT_BINARY_DIR}/thinslabConfigVersion.cmake
        DESTINATION ${THINSLAB_INSTALL_CMAKEDIR})
