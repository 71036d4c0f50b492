# Helpers shared by every cslam target.

# Warnings for our own code only (third-party headers come in as SYSTEM).
function(cslam_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wno-unused-parameter)
  if(CSLAM_NATIVE)
    target_compile_options(${target} PRIVATE -march=native)
  else()
    # popcnt is on every x86-64 machine of the last 15 years; Hamming distance needs it.
    if(CMAKE_SYSTEM_PROCESSOR MATCHES "x86_64|AMD64")
      target_compile_options(${target} PRIVATE -mpopcnt -msse4.2)
    endif()
  endif()
endfunction()

# cslam_library(NAME SOURCES ... DEPS ...): a static library target cslam_<NAME>
# with include root src/ (so code includes "geometry/camera.h").
function(cslam_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(cslam_${name} STATIC ${ARG_SOURCES})
  target_include_directories(cslam_${name} PUBLIC ${CMAKE_SOURCE_DIR}/src)
  target_link_libraries(cslam_${name} PUBLIC ${ARG_DEPS})
  cslam_warnings(cslam_${name})
endfunction()

# Programs and tests allocate through tcmalloc (cmake/Dependencies.cmake). Nothing references it
# by name, so the linker must not drop it as unneeded.
function(cslam_allocator target)
  target_link_libraries(${target} PRIVATE "-Wl,--push-state,--no-as-needed" PkgConfig::TCMALLOC "-Wl,--pop-state")
endfunction()

# cslam_program(NAME SOURCES ... DEPS ...): an executable in build/bin.
function(cslam_program name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  cslam_allocator(${name})
  cslam_warnings(${name})
endfunction()

# cslam_test(NAME SOURCES ... DEPS ... [LABELS ...] [TIMEOUT s]): a GoogleTest binary registered with CTest.
function(cslam_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  cslam_allocator(${name})
  target_include_directories(${name} PRIVATE ${CMAKE_SOURCE_DIR}/tests)
  target_compile_definitions(${name} PRIVATE
    CSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
    CSLAM_SHARED_DATA_DIR="${CSLAM_SHARED_DATA_DIR}"
    CSLAM_BIN_DIR="${CMAKE_BINARY_DIR}/bin")
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  cslam_warnings(${name})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  add_test(NAME ${name} COMMAND ${name} WORKING_DIRECTORY ${CMAKE_BINARY_DIR})
  set_tests_properties(${name} PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}")
endfunction()

# Adds every immediate subfolder of DIR that has a CMakeLists.txt, in sorted order,
# so modules can be added without editing a shared list.
function(cslam_add_subdirs dir)
  file(GLOB children RELATIVE ${dir} ${dir}/*)
  list(SORT children)
  foreach(child ${children})
    if(IS_DIRECTORY ${dir}/${child} AND EXISTS ${dir}/${child}/CMakeLists.txt)
      file(RELATIVE_PATH rel ${CMAKE_SOURCE_DIR} ${dir}/${child})
      add_subdirectory(${dir}/${child} ${CMAKE_BINARY_DIR}/${rel})
    endif()
  endforeach()
endfunction()
