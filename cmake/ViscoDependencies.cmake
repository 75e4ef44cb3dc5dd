# Third-party dependencies, all from Debian packages (scripts/packages.txt).
find_package(Threads REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs videoio calib3d)
find_package(apriltag CONFIG REQUIRED)
find_package(CGAL CONFIG REQUIRED)
find_package(nlohmann_json 3 CONFIG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(fmt CONFIG REQUIRED)
find_package(spdlog CONFIG REQUIRED)
# ROS camera_info calibrations (vision/ros_camera_info.cc): OpenCV's FileStorage refuses their YAML.
find_package(yaml-cpp CONFIG REQUIRED)
# mimalloc, for the planner program `visco` only (app/CMakeLists.txt): CGAL's exact arithmetic allocates and frees
# small numbers all the time, and mimalloc makes `visco plan` take 0.8x the wall time of glibc's malloc. Not in the
# sanitizer builds, which replace malloc themselves.
if(VISCO_SANITIZE STREQUAL "")
  find_package(mimalloc 2.0 CONFIG REQUIRED)
endif()
find_package(PkgConfig REQUIRED)
# LCM ships no CMake config in Debian.
pkg_check_modules(LCM REQUIRED IMPORTED_TARGET lcm)
pkg_get_variable(LCM_JAVA_CLASSPATH lcm-java classpath)
find_program(LCM_GEN lcm-gen REQUIRED)
find_package(Java 11 COMPONENTS Development)
if(VISCO_BUILD_TESTS)
  find_package(GTest CONFIG REQUIRED)
  find_package(benchmark CONFIG REQUIRED)
  include(GoogleTest)
endif()
