# cmake --install: the CLI, the libraries with their headers and the CMake package tirstrain (imported
# targets tirstrain::core, ::model, ... for find_package(tirstrain)), the Python module (python/), and the
# Debian packages cpack -G DEB builds from them.
include(CMakePackageConfigHelpers)

# Libraries by the name a consumer links (tirstrain::<name>). fit and samples are there because pipeline
# links them; hdf5, opencv and flags are the interface targets the libraries carry (flags: link options of a
# sanitizer build).
set(tirstrain_exported core model fit signals samples capture contact flow strain pipeline)
set(tirstrain_export_targets "")
foreach(name ${tirstrain_exported})
  set_target_properties(tirstrain_${name} PROPERTIES EXPORT_NAME ${name})
  list(APPEND tirstrain_export_targets tirstrain_${name})
endforeach()
foreach(name hdf5 opencv flags)
  set_target_properties(tirstrain_${name} PROPERTIES EXPORT_NAME detail_${name})
  list(APPEND tirstrain_export_targets tirstrain_${name})
endforeach()

install(TARGETS ${tirstrain_export_targets} EXPORT tirstrainTargets
  ARCHIVE DESTINATION lib COMPONENT dev)
# Public headers only: a module's detail/ folder is its implementation's (core/detail holds the YAML library's
# side of SceneSection), and no public header includes it.
foreach(folder ${tirstrain_exported})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${folder}/ DESTINATION include/tirstrain/${folder} COMPONENT dev
          FILES_MATCHING PATTERN "*.hpp" PATTERN "detail" EXCLUDE)
endforeach()
install(FILES ${PROJECT_BINARY_DIR}/core/generated/core/version.hpp DESTINATION include/tirstrain/core
        COMPONENT dev)

set(tirstrain_cmake_dir lib/cmake/tirstrain)
install(EXPORT tirstrainTargets NAMESPACE tirstrain:: DESTINATION ${tirstrain_cmake_dir} COMPONENT dev)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/tirstrainConfig.cmake.in
  ${PROJECT_BINARY_DIR}/tirstrainConfig.cmake INSTALL_DESTINATION ${tirstrain_cmake_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/tirstrainConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/tirstrainConfig.cmake ${PROJECT_BINARY_DIR}/tirstrainConfigVersion.cmake
  DESTINATION ${tirstrain_cmake_dir} COMPONENT dev)

install(TARGETS tirstrain RUNTIME DESTINATION bin COMPONENT cli)

# Debian packages: tirstrain (the CLI), python3-tirstrain (the module) and tirstrain-dev (headers, static
# libraries, CMake package; depends on the -dev packages the headers and the static libraries' links need).
# The runtime Depends are Debian 12's packages of the shared libraries the CLI and the module link
# (tests/package/check_deb.sh checks every one they need is named); TIRSTRAIN_DEB_SHLIBDEPS computes them
# with dpkg-shlibdeps instead, which takes ~10 s of CPU a package.
option(TIRSTRAIN_DEB_SHLIBDEPS "cpack -G DEB: runtime Depends from dpkg-shlibdeps instead of the list" OFF)
set(TIRSTRAIN_DEB_RUNTIME_DEPENDS
    "libc6 (>= 2.35), libstdc++6 (>= 12), libgcc-s1, libopencv-core406, libopencv-imgproc406, libopencv-imgcodecs406, libopencv-videoio406, libopencv-video406, libopencv-highgui406, libhdf5-103-1, libhdf5-cpp-103-1, libyaml-cpp0.7, libaravis-0.8-0 (>= 0.8.26), libcamera0.0.3, libtiff6, libmatio11, libglib2.0-0, libgmp10, libgoogle-glog0v6, libcholmod3, libcxsparse3, libspqr2, libatlas3-base"
    CACHE STRING "Depends of the tirstrain and python3-tirstrain packages (without TIRSTRAIN_DEB_SHLIBDEPS)")
set(tirstrain_runtime_depends "")
if(NOT TIRSTRAIN_DEB_SHLIBDEPS)
  set(tirstrain_runtime_depends "${TIRSTRAIN_DEB_RUNTIME_DEPENDS}")
  if(TIRSTRAIN_SANITIZE)
    string(APPEND tirstrain_runtime_depends ", libasan8, libubsan1")
  endif()
endif()
set(CPACK_PACKAGE_NAME tirstrain)
set(CPACK_PACKAGE_VENDOR tirstrain)
set(CPACK_PACKAGE_CONTACT "tirstrain maintainers <tirstrain@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Fingertip skin strain from total-internal-reflection contact images")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_GROUPING IGNORE)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_COMPRESSION_TYPE gzip)
set(CPACK_COMPONENTS_ALL cli dev)
if(TIRSTRAIN_BUILD_PYTHON)
  list(APPEND CPACK_COMPONENTS_ALL python)
endif()
set(CPACK_DEBIAN_CLI_PACKAGE_NAME tirstrain)
set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-tirstrain)
set(CPACK_DEBIAN_DEV_PACKAGE_NAME tirstrain-dev)
set(CPACK_DEBIAN_CLI_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_CLI_PACKAGE_SHLIBDEPS ${TIRSTRAIN_DEB_SHLIBDEPS})
set(CPACK_DEBIAN_PYTHON_PACKAGE_SHLIBDEPS ${TIRSTRAIN_DEB_SHLIBDEPS})
set(CPACK_DEBIAN_CLI_PACKAGE_DEPENDS "${tirstrain_runtime_depends}")
# The extension is built for one interpreter version (its file name carries the ABI tag).
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS
    "python3 (>= ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}), python3 (<< ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}.99), python3-numpy")
if(tirstrain_runtime_depends)
  string(APPEND CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS ", ${tirstrain_runtime_depends}")
endif()
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
    "libopencv-dev, libeigen3-dev, libhdf5-dev, libyaml-cpp-dev, nlohmann-json3-dev, libcgal-dev, libceres-dev, libaravis-dev, libcamera-dev, libtiff-dev, libmatio-dev, pkg-config")
include(CPack)

# The packaged binaries record only the shared libraries they use, so that their Depends (above) are the
# same whatever the build type and whatever the dependencies' link lines drag in.
target_link_options(tirstrain PRIVATE -Wl,--as-needed)
if(TIRSTRAIN_BUILD_PYTHON)
  target_link_options(tirstrain_python PRIVATE -Wl,--as-needed)
endif()
