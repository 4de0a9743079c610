# SPDX-License-Identifier: Apache-2.0
# thinslab_add_library / thinslab_add_test / thinslab_add_bench, after COLMAP's CMakeHelper.

set(THINSLAB_WARNING_FLAGS -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wno-deprecated-copy -Wno-maybe-uninitialized)
if(THINSLAB_WERROR)
  list(APPEND THINSLAB_WARNING_FLAGS -Werror)
endif()

if(THINSLAB_SANITIZE)
  # UndefinedBehaviorSanitizer without four of its checks, which took ~40 % of the sanitizer
  # tree's compile time (docs/benchmarks.md, CI): `null` (AddressSanitizer reports the
  # dereference itself), `alignment` (x86 loads any alignment; thinslab packs no structs),
  # `vptr` (dynamic-type checks; the few polymorphic classes are device drivers) and
  # `pointer-overflow`. Added: `float-cast-overflow`, which -fsanitize=undefined leaves out in
  # GCC: a NaN or out-of-range double cast to a pixel index is a bug thinslab can have.
  set(THINSLAB_SANITIZE_FLAGS -fsanitize=address,undefined,float-cast-overflow
      -fno-sanitize=null,alignment,vptr,pointer-overflow)
  add_compile_options(${THINSLAB_SANITIZE_FLAGS} -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  # Eigen stops trusting glibc malloc's 16-byte alignment under ASan and switches to its own
  # aligned allocator; Debian's libceres was built without ASan, so Eigen objects allocated in
  # it and freed in our code would mismatch. ASan's malloc is 16-byte aligned, so keep the
  # glibc assumption (EIGEN_DEFAULT_ALIGN_BYTES is 16 without AVX).
  add_compile_definitions(EIGEN_MALLOC_ALREADY_ALIGNED=1)
  add_link_options(${THINSLAB_SANITIZE_FLAGS})
endif()

# "thinslab/<stage>/<name>.h" resolves in the build tree and, after `cmake --install`, under
# <prefix>/include.
function(thinslab_target_includes target scope)
  target_include_directories(${target} ${scope} "$<BUILD_INTERFACE:${THINSLAB_BUILD_INCLUDE_DIRS}>"
                             $<INSTALL_INTERFACE:include>)
endfunction()

function(thinslab_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;LINK_LIBS" ${ARGN})
  add_library(${ARG_NAME} ${ARG_SRCS})
  target_compile_options(${ARG_NAME} PRIVATE ${THINSLAB_WARNING_FLAGS})
  thinslab_target_includes(${ARG_NAME} PUBLIC)
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_LINK_LIBS})
endfunction()

# NAME is <folder>/<test>; the executable is <folder>_<test>.
function(thinslab_add_test)
  # GTEST_FILTER (optional): the gtest filter this ctest entry runs; further entries for the same
  # executable come from thinslab_add_test_entry.
  cmake_parse_arguments(ARG "" "NAME;TIMEOUT;GTEST_FILTER" "SRCS;LINK_LIBS;LABELS" ${ARGN})
  if(NOT BUILD_TESTING)
    return()
  endif()
  string(REPLACE "/" "_" exe ${ARG_NAME})
  add_executable(${exe} ${ARG_SRCS})
  target_compile_options(${exe} PRIVATE ${THINSLAB_WARNING_FLAGS})
  # Tests also include their helpers as "tests/...".
  target_include_directories(${exe} PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(${exe} PRIVATE ${ARG_LINK_LIBS} GTest::gtest GTest::gtest_main GTest::gmock)
  thinslab_add_test_entry(NAME ${ARG_NAME} EXE ${exe} TIMEOUT "${ARG_TIMEOUT}" GTEST_FILTER "${ARG_GTEST_FILTER}"
                          LABELS ${ARG_LABELS})
endfunction()

# Another ctest entry (its own name, labels and gtest filter) for a test executable.
function(thinslab_add_test_entry)
  cmake_parse_arguments(ARG "" "NAME;EXE;TIMEOUT;GTEST_FILTER" "LABELS" ${ARGN})
  # The device-free stages' tests carry the label `refit` (the refit-only tree runs them, and
  # the target thinslab_refit_tests builds them).
  if(ARG_NAME MATCHES "^(core|optics|calib|fit|pipeline|export)/")
    list(APPEND ARG_LABELS refit)
    add_dependencies(thinslab_refit_tests ${ARG_EXE})
  endif()
  if(NOT "matrix" IN_LIST ARG_LABELS)
    add_dependencies(thinslab_sanitizer_tests ${ARG_EXE})
  endif()
  if(ARG_GTEST_FILTER)
    add_test(NAME ${ARG_NAME} COMMAND ${ARG_EXE} --gtest_filter=${ARG_GTEST_FILTER})
  else()
    add_test(NAME ${ARG_NAME} COMMAND ${ARG_EXE})
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  set_tests_properties(${ARG_NAME} PROPERTIES TIMEOUT ${ARG_TIMEOUT}
    ENVIRONMENT "THINSLAB_SOURCE_DIR=${PROJECT_SOURCE_DIR};THINSLAB_BINARY_DIR=${PROJECT_BINARY_DIR}")
  if(ARG_LABELS)
    set_tests_properties(${ARG_NAME} PROPERTIES LABELS "${ARG_LABELS}")
  endif()
endfunction()

function(thinslab_add_bench)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;LINK_LIBS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_compile_options(${ARG_NAME} PRIVATE ${THINSLAB_WARNING_FLAGS})
  target_include_directories(${ARG_NAME} PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LINK_LIBS} benchmark::benchmark)
endfunction()
