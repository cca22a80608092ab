# Build rules shared by every unit: one place for warnings, language
# restrictions and instrumentation, so that no unit can drift from them.

set(TCPEST_WARNINGS -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow
    -Wdouble-promotion -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Wnull-dereference
    -Werror)

# The same bits on x86-64 and ARM64 (docs/architecture.md, "Reproducible
# arithmetic"): no fused multiply-add, which GCC and Clang otherwise emit on
# ARM64 and which rounds once where x86-64 rounds twice; and Eigen's scalar
# paths, since its NEON kernels fuse and its packets sum in another order
# than SSE's. libm's transcendental functions are replaced by common/dmath.
# Every target built here gets them (tests, benchmarks and tools too, also
# those that link no tcpest library). The interface target carries the same
# flags, as usage requirements of every tcpest library, to the code of a
# project that links the installed libraries: Eigen's types in the public
# headers (the solver's) must be compiled alike on both sides.
set(TCPEST_ARITHMETIC_OPTIONS -ffp-contract=off)
set(TCPEST_ARITHMETIC_DEFINITIONS EIGEN_DONT_VECTORIZE)
add_compile_options(${TCPEST_ARITHMETIC_OPTIONS})
add_compile_definitions(${TCPEST_ARITHMETIC_DEFINITIONS})
add_library(tcpest_arithmetic INTERFACE)
target_compile_options(tcpest_arithmetic INTERFACE ${TCPEST_ARITHMETIC_OPTIONS})
target_compile_definitions(tcpest_arithmetic INTERFACE ${TCPEST_ARITHMETIC_DEFINITIONS})
set_target_properties(tcpest_arithmetic PROPERTIES EXPORT_NAME arithmetic)

# float-cast-overflow is not part of GCC's "undefined": a double out of an
# integer's range converts to INT_MIN on x86-64 and saturates on ARM64, so
# such a cast would make the two builds differ.
if(TCPEST_SANITIZE)
  add_compile_options(-fsanitize=address,undefined,float-cast-overflow -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined,float-cast-overflow)
endif()
# Fuzzing (fuzz/, docs/fuzzing.md): every library the targets link carries
# libFuzzer's coverage hooks and the sanitizers; fuzz/ links the fuzzer's main.
if(TCPEST_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "TCPEST_FUZZ needs clang (libFuzzer): configure with the fuzz preset")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all
                      -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
endif()
# Coverage (toolchain/coverage.sh): -Og keeps line counts close to the
# source and the image tests about ten times faster than -O0.
if(TCPEST_COVERAGE)
  add_compile_options(--coverage -Og -g)
  add_link_options(--coverage)
endif()

# Core libraries (solver, vision, can_iface, and what they depend on): no
# exceptions, no RTTI, every warning an error.
function(tcpest_core_library name)
  add_library(${name} ${ARGN})
  target_compile_options(${name} PRIVATE ${TCPEST_WARNINGS} -fno-exceptions -fno-rtti)
  target_compile_features(${name} PUBLIC cxx_std_17)
  target_link_libraries(${name} PUBLIC tcpest_arithmetic)
endfunction()

# Other first-party code (hal backends, the loop, the command): same warnings.
function(tcpest_library name)
  add_library(${name} ${ARGN})
  target_compile_options(${name} PRIVATE ${TCPEST_WARNINGS})
  target_compile_features(${name} PUBLIC cxx_std_17)
  target_link_libraries(${name} PUBLIC tcpest_arithmetic)
endfunction()

# A GoogleTest program registered with CTest. LABELS default to "unit".
# Usage: tcpest_test(NAME name SOURCES ... LIBS ... [LABELS ...])
function(tcpest_test)
  cmake_parse_arguments(T "" "NAME" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_compile_options(${T_NAME} PRIVATE ${TCPEST_WARNINGS} -Wno-sign-conversion)
  target_link_libraries(${T_NAME} PRIVATE ${T_LIBS} tcpest_test_support GTest::gtest)
  target_compile_definitions(${T_NAME} PRIVATE TCPEST_TEST_DATA_DIR="${PROJECT_SOURCE_DIR}/tests/data")
  if(NOT T_LABELS)
    set(T_LABELS unit)
  endif()
  include(GoogleTest)
  gtest_discover_tests(${T_NAME} PROPERTIES LABELS "${T_LABELS}" DISCOVERY_TIMEOUT 60)
endfunction()

# A Google Benchmark program (not a test: performance is shown by running
# it, never asserted in CTest). Usage: tcpest_benchmark(NAME n SOURCES ... LIBS ...)
function(tcpest_benchmark)
  if(NOT TCPEST_BUILD_BENCHMARKS)
    return()
  endif()
  find_package(benchmark QUIET)
  if(NOT benchmark_FOUND)
    message(STATUS "Google Benchmark not found: ${ARGV1} not built")
    return()
  endif()
  cmake_parse_arguments(B "" "NAME" "SOURCES;LIBS" ${ARGN})
  add_executable(${B_NAME} ${B_SOURCES})
  target_compile_options(${B_NAME} PRIVATE ${TCPEST_WARNINGS})
  target_link_libraries(${B_NAME} PRIVATE ${B_LIBS} benchmark::benchmark)
endfunction()

# Fails the configuration when `target`'s link closure (its link libraries,
# theirs, and so on) holds one of the FORBIDDEN targets: the flight libraries
# must not link simulation, rendering or tools.
# Usage: tcpest_check_flight_closure(target FORBIDDEN t1 t2 ...)
function(tcpest_check_flight_closure target)
  cmake_parse_arguments(F "" "" "FORBIDDEN" ${ARGN})
  set(pending ${target})
  set(seen "")
  while(pending)
    list(POP_FRONT pending current)
    if(current IN_LIST seen OR NOT TARGET ${current})
      continue()
    endif()
    list(APPEND seen ${current})
    if(current IN_LIST F_FORBIDDEN)
      message(FATAL_ERROR "flight library ${target} links ${current} (simulation or tools code)")
    endif()
    get_target_property(libs ${current} LINK_LIBRARIES)
    get_target_property(interface ${current} INTERFACE_LINK_LIBRARIES)
    foreach(lib IN LISTS libs interface)
      if(lib AND NOT lib MATCHES "NOTFOUND$" AND NOT lib MATCHES "^\\$<")
        list(APPEND pending ${lib})
      endif()
    endforeach()
  endwhile()
  set_property(GLOBAL APPEND PROPERTY TCPEST_FLIGHT_CLOSURE_CHECKED ${target})
endfunction()
