# Installable CMake package: find_package(visco) gives visco::<library> targets, the lcm-gen headers and the
# LCM jar, and the `visco` program.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)
get_property(visco_libraries GLOBAL PROPERTY VISCO_LIBRARIES)
install(TARGETS ${visco_libraries} visco_warnings EXPORT viscoTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY common lcmtypes face_contact drivers control vision planning replay
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")
install(DIRECTORY app/sim DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/app FILES_MATCHING PATTERN "*.h")
install(EXPORT viscoTargets NAMESPACE visco:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/visco)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/viscoConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/viscoConfig.cmake
                              INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/visco)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/viscoConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/viscoConfig.cmake ${PROJECT_BINARY_DIR}/viscoConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/visco)
