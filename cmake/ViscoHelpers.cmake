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
# A GoogleTest executable whose tests are registered one by one with CTest (discovered when ctest runs).
function(visco_add_gtest)
  cmake_parse_arguments(ARG "" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  if(NOT ARG_LABELS)
    message(FATAL_ERROR "visco_add_gtest(${ARG_NAME}): give LABELS (unit, property, integration, hil, replay)")
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main visco_warnings)
  gtest_discover_tests(${ARG_NAME} DISCOVERY_MODE PRE_TEST
                       PROPERTIES LABELS "${ARG_LABELS}" TIMEOUT ${ARG_TIMEOUT}
                       WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
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
  set_tests_properties(${ARG_NAME}.smoke PROPERTIES LABELS bench TIMEOUT 600)
endfunction()
