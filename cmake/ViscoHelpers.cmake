# Small helpers so that every library, test and benchmark is declared the same way.

# Compile options for visco's own code (third-party and generated headers come in as SYSTEM includes).
add_library(visco_warnings INTERFACE)
target_compile_options(visco_warnings INTERFACE -Wall -Wextra -Wshadow -Wnon-virtual-dtor -Wpedantic)
if(VISCO_WERROR)
  target_compile_options(visco_warnings INTERFACE -Werror)
endif()
if(VISCO_SANITIZE STREQUAL "address")
  # -fno-sanitize=vptr: UBSan's vptr check misfires inside LCM 1.3.1's header-only C++ subscription callbacks
  # (lcm-cpp-impl.hpp cb_func) although ASan finds no bad access there; every other UB check stays on.
  target_compile_options(visco_warnings INTERFACE -fsanitize=address,undefined -fno-sanitize=vptr
                                                  -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  target_link_options(visco_warnings INTERFACE -fsanitize=address,undefined)
  # GCC 12's flow analysis at -O1 with sanitizers reports -Wmaybe-uninitialized inside system headers instantiated
  # from our code (std::regex's std::function moves, CGAL's Epic_converter): false positives that -Werror would turn
  # into a broken ASan build. The normal build keeps the warning.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(visco_warnings INTERFACE -Wno-maybe-uninitialized)
  endif()
elseif(VISCO_SANITIZE STREQUAL "thread")
  target_compile_options(visco_warnings INTERFACE -fsanitize=thread -fno-omit-frame-pointer)
  target_link_options(visco_warnings INTERFACE -fsanitize=thread)
elseif(NOT VISCO_SANITIZE STREQUAL "")
  message(FATAL_ERROR "VISCO_SANITIZE must be '', 'address' or 'thread', not '${VISCO_SANITIZE}'")
endif()

# The environment of every test in sanitizer builds. Under ThreadSanitizer: stop at the first report, and suppress the
# third-party reports listed (each with its reason) in tests/tsan.supp. visco_add_gtest sets it on the tests it
# discovers; visco_test_environment() on those a directory added with add_test.
set(VISCO_TEST_ENVIRONMENT "")
if(VISCO_SANITIZE STREQUAL "thread")
  set(VISCO_TEST_ENVIRONMENT
      "TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=${PROJECT_SOURCE_DIR}/tests/tsan.supp")
endif()

# visco_test_environment(): sets VISCO_TEST_ENVIRONMENT on every add_test() test of the calling directory so far.
# Call it at the end of each tests/<folder>/CMakeLists.txt that uses add_test (CMake 3.25 cannot set test
# properties of another directory).
function(visco_test_environment)
  get_property(tests DIRECTORY PROPERTY TESTS)
  if(tests AND VISCO_TEST_ENVIRONMENT)
    set_property(TEST ${tests} APPEND PROPERTY ENVIRONMENT "${VISCO_TEST_ENVIRONMENT}")
  endif()
endfunction()

# visco_add_library(NAME <name> [INTERFACE] SOURCES ... PUBLIC_DEPS ... PRIVATE_DEPS ...)
# Declares library visco_<name> with alias visco::<name>. Includes are rooted at the repository top
# (#include "planning/scene.h").
function(visco_add_library)
  cmake_parse_arguments(ARG "INTERFACE" "NAME" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  set(target visco_${ARG_NAME})
  if(ARG_INTERFACE)
    add_library(${target} INTERFACE)
    target_include_directories(${target} INTERFACE $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
                                                   $<INSTALL_INTERFACE:include>)
    target_link_libraries(${target} INTERFACE ${ARG_PUBLIC_DEPS})
  else()
    add_library(${target} STATIC ${ARG_SOURCES})
    target_include_directories(${target} PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
                                                $<INSTALL_INTERFACE:include>)
    target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS}
                                           $<BUILD_INTERFACE:visco_warnings>)
    set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_NAME} POSITION_INDEPENDENT_CODE ON)
  endif()
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_NAME})
  add_library(visco::${ARG_NAME} ALIAS ${target})
  set_property(GLOBAL APPEND PROPERTY VISCO_LIBRARIES ${target})
endfunction()

# visco_add_gtest(NAME <name> SOURCES ... LIBS ... LABELS ... [TIMEOUT s])
# A GoogleTest executable whose tests are registered one by one with CTest (discovered when ctest runs). LABELS may
# be several (e.g. `unit tsan`).
function(visco_add_gtest)
  cmake_parse_arguments(ARG "" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  if(NOT ARG_LABELS)
    message(FATAL_ERROR "visco_add_gtest(${ARG_NAME}): give LABELS (unit, property, integration, hil, replay, tsan)")
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main visco_warnings)
  set(environment)
  if(VISCO_TEST_ENVIRONMENT)
    set(environment ENVIRONMENT "${VISCO_TEST_ENVIRONMENT}")
  endif()
  if("tsan" IN_LIST ARG_LABELS)
    set_property(GLOBAL APPEND PROPERTY VISCO_TSAN_TARGETS ${ARG_NAME})
  endif()
  # Discovery runs the executable (--gtest_list_tests) at every ctest run, also for tests a label filters out: a
  # sanitizer build of a test that links OpenCV, ViSP and GDAL takes 1.5-2 s to list its tests on an idle machine,
  # more than CTest's default 5 s limit on a loaded one.
  set(discovery_timeout 5)
  if(NOT VISCO_SANITIZE STREQUAL "")
    set(discovery_timeout 60)
  endif()
  list(GET ARG_LABELS 0 first_label)
  gtest_discover_tests(${ARG_NAME} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT ${discovery_timeout}
                       PROPERTIES LABELS ${first_label} TIMEOUT ${ARG_TIMEOUT} ${environment}
                       WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
  list(LENGTH ARG_LABELS num_labels)
  if(num_labels GREATER 1)
    # CMake 3.25's gtest_discover_tests flattens a list in PROPERTIES (`LABELS unit tsan` would make `tsan` a property
    # name), so the discovered tests get all their labels from a script CTest runs after the discovery script, which
    # leaves their names in <name>_TESTS.
    set(script ${CMAKE_CURRENT_BINARY_DIR}/${ARG_NAME}_labels.cmake)
    file(GENERATE OUTPUT ${script}
         CONTENT "if(${ARG_NAME}_TESTS)\n  set_tests_properties(\${${ARG_NAME}_TESTS} PROPERTIES LABELS \"${ARG_LABELS}\")\nendif()\n")
    set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES ${script})
  endif()
endfunction()

# visco_add_benchmark(NAME <name> SOURCES ... LIBS ...)
# A Google Benchmark executable, plus a CTest smoke run of it labelled `bench`.
function(visco_add_benchmark)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;LIBS;SMOKE_ARGS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LIBS} benchmark::benchmark visco_warnings)
  add_test(NAME ${ARG_NAME}.smoke
           COMMAND ${ARG_NAME} --benchmark_min_time=0.001 ${ARG_SMOKE_ARGS}
           WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
  # Google Benchmark exits 0 when the filter matches nothing: a smoke run that ran no benchmark fails.
  set_tests_properties(${ARG_NAME}.smoke PROPERTIES LABELS bench TIMEOUT 600
                       FAIL_REGULAR_EXPRESSION "Failed to match any benchmarks")
endfunction()
