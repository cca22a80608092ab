# What `cmake --install` puts where (docs/install.md), the exported CMake
# package (`find_package(tcpest)`, targets tcpest::<unit>), the pkg-config
# file and the Debian package (`cpack -G DEB`). Included last by the top
# CMakeLists.txt, when every target exists.
#
# The units name their include directory for the build only
# ($<BUILD_INTERFACE:...>); the installed targets find the headers under
# ${CMAKE_INSTALL_INCLUDEDIR} (INCLUDES DESTINATION below).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# Installing and packaging need the installed targets only, not the tests
# and benchmarks of `all`: `cpack` (and the install target) start at once;
# toolchain/check-install.sh and check-package.sh build what they install.
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)

set(TCPEST_CMAKE_DIR "${CMAKE_INSTALL_LIBDIR}/cmake/tcpest")
set(TCPEST_DATA_DIR "${CMAKE_INSTALL_DATADIR}/tcpest")

# The flight libraries, what an integrator builds against: the four core
# units, the loop and the hal backends it links. Not installed: the
# renderer, the simulation and the command's own library (tools, tests).
set(TCPEST_EXPORTED_LIBRARIES tcpest_common tcpest_solver tcpest_vision tcpest_can_iface
    tcpest_hal_camera tcpest_hal_can tcpest_hal_clock tcpest_loop)
foreach(lib IN LISTS TCPEST_EXPORTED_LIBRARIES)
  string(REGEX REPLACE "^tcpest_" "" export_name "${lib}")
  set_target_properties(${lib} PROPERTIES EXPORT_NAME ${export_name})
endforeach()

install(TARGETS tcpest_arithmetic ${TCPEST_EXPORTED_LIBRARIES}
        EXPORT tcpestTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS tcpest RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# Public headers: include/tcpest/<unit>/ of each exported library. The
# loop's folder also holds the simulation's headers (tcpest_loop_sim), which
# need the renderer: left out.
# vision's folder also holds the offline dense fit's (tcpest_vision_dense,
# a research tool outside the flight libraries): left out.
foreach(dir common solver can_iface hal/camera hal/can hal/clock)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endforeach()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/vision/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        PATTERN dense_fit.hpp EXCLUDE
        PATTERN dense_estimate.hpp EXCLUDE)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/firmware_like/loop/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        PATTERN memory_node.hpp EXCLUDE
        PATTERN motion.hpp EXCLUDE
        PATTERN prerendered_source.hpp EXCLUDE
        PATTERN rendered_scene.hpp EXCLUDE)

# Shipped defaults, the deployment example, the systemd unit, the DBC and the docs.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/config/ DESTINATION ${TCPEST_DATA_DIR}/config)
install(FILES ${PROJECT_SOURCE_DIR}/toolchain/tcpest.service DESTINATION lib/systemd/system)
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR})

# The CMake package: tcpestTargets.cmake, tcpestConfig.cmake (the
# dependencies of the exported targets) and its version file.
install(EXPORT tcpestTargets NAMESPACE tcpest:: DESTINATION ${TCPEST_CMAKE_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/tcpestConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/tcpestConfig.cmake
                              INSTALL_DESTINATION ${TCPEST_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/tcpestConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${PROJECT_BINARY_DIR}/tcpestConfig.cmake ${PROJECT_BINARY_DIR}/tcpestConfigVersion.cmake
        DESTINATION ${TCPEST_CMAKE_DIR})

# pkg-config: relocatable (prefix found from the .pc file's own place), the
# same arithmetic flags as tcpest::arithmetic, the libraries in link order.
file(RELATIVE_PATH TCPEST_PC_TO_PREFIX "/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/")
string(REGEX REPLACE "/$" "" TCPEST_PC_TO_PREFIX "${TCPEST_PC_TO_PREFIX}")
set(TCPEST_PC_CFLAGS "${TCPEST_ARITHMETIC_OPTIONS}")
foreach(definition IN LISTS TCPEST_ARITHMETIC_DEFINITIONS)
  list(APPEND TCPEST_PC_CFLAGS "-D${definition}")
endforeach()
list(JOIN TCPEST_PC_CFLAGS " " TCPEST_PC_CFLAGS)
set(TCPEST_PC_LIBS "")
foreach(lib tcpest_loop tcpest_hal_can tcpest_hal_camera tcpest_hal_clock tcpest_vision tcpest_can_iface
            tcpest_solver tcpest_common)
  string(APPEND TCPEST_PC_LIBS " -l${lib}")
endforeach()
configure_file(${CMAKE_CURRENT_LIST_DIR}/tcpest.pc.in ${PROJECT_BINARY_DIR}/tcpest.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/tcpest.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# Debian package (`cpack -G DEB` in the build folder): everything above,
# installed under /usr. Its dependencies are the runtime libraries the
# binary links, found by dpkg-shlibdeps; the headers also need Eigen and
# libjpeg's headers, which are suggested only.
set(CPACK_PACKAGE_NAME tcpest)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_PACKAGE_CONTACT "tcpest maintainers <maintainers@users.noreply.h-seed-27d420e7.example>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
    "Estimates the 3D tip position of a bendable surgical instrument from the endoscope's
images and sends it over CAN (CANopen-shaped node, E2E protection). Ships the tcpest
command, its systemd unit, the default configuration, the DBC, and the static
libraries with their headers (CMake package tcpest, pkg-config tcpest).")
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "iproute2")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "can-utils, libeigen3-dev, libjpeg62-turbo-dev")
include(CPack)
