# SPDX-License-Identifier: Apache-2.0
# thinslab_add_library / thinslab_add_test / thinslab_add_bench, after COLMAP's CMakeHelper.

set(THINSLAB_WARNING_FLAGS -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wno-deprecated-copy -Wno-maybe-uninitialized)
if(THINSLAB_WERROR)
  list(APPEND THINSLAB_WARNING_FLAGS -Werror)
endif()

if(THINSLAB_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  # Eigen stops trusting glibc malloc's 16-byte alignment under ASan and switches to its own
  # aligned allocator; Debian's libceres was built without ASan, so Eigen objects allocated in
  # it and freed in our code would mismatch. ASan's malloc is 16-byte aligned, so keep the
  # glibc assumption (EIGEN_DEFAULT_ALIGN_BYTES is 16 without AVX).
  add_compile_definitions(EIGEN_MALLOC_ALREADY_ALIGNED=1)
  add_link_options(-fsanitize=address,undefined)
endif()

function(thinslab_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;LINK_LIBS" ${ARGN})
  add_library(${ARG_NAME} ${ARG_SRCS})
  target_compile_options(${ARG_NAME} PRIVATE ${THINSLAB_WARNING_FLAGS})
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_LINK_LIBS})
endfunction()

# NAME is <folder>/<test>; the executable is <folder>_<test>.
function(thinslab_add_test)
  cmake_parse_arguments(ARG "" "NAME;TIMEOUT" "SRCS;LINK_LIBS;LABELS" ${ARGN})
  string(REPLACE "/" "_" exe ${ARG_NAME})
  add_executable(${exe} ${ARG_SRCS})
  target_compile_options(${exe} PRIVATE ${THINSLAB_WARNING_FLAGS})
  target_link_libraries(${exe} PRIVATE ${ARG_LINK_LIBS} GTest::gtest GTest::gtest_main GTest::gmock)
  add_test(NAME ${ARG_NAME} COMMAND ${exe})
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
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LINK_LIBS} benchmark::benchmark)
endfunction()
