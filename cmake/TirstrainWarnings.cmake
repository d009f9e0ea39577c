# Compile flags shared by every tirstrain target: applied through tirstrain_target_defaults().
add_library(tirstrain_flags INTERFACE)
# GCC 12 warns on designated initializers that leave defaulted members out (ErrorContext{.file = f}),
# which is the intended use; every other -Wextra warning stays on.
target_compile_options(tirstrain_flags INTERFACE -Wall -Wextra -Wpedantic -Wno-missing-field-initializers)
# GCC 12 at -O3 reports impossible std::string memcpy overlaps inside libstdc++ (GCC bug 105329, a known false
# positive of -Wrestrict), which would fail Release builds with -Werror.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  target_compile_options(tirstrain_flags INTERFACE -Wno-restrict)
endif()
# Every program records only the shared libraries it uses. The dependencies' link lines name all of
# OpenCV (videoio and imgcodecs alone bring in some 250 libraries: FFmpeg, GStreamer, GDAL), and each test
# case is a process of its own, so a test program that loads none of them starts several times faster.
target_link_options(tirstrain_flags INTERFACE -Wl,--as-needed)
if(TIRSTRAIN_WERROR)
  target_compile_options(tirstrain_flags INTERFACE -Werror)
endif()
if(TIRSTRAIN_SANITIZE)
  target_compile_options(tirstrain_flags INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer
                                                   -fno-sanitize-recover=undefined)
  target_link_options(tirstrain_flags INTERFACE -fsanitize=address,undefined)
endif()
if(TIRSTRAIN_FUZZ)
  # Every library instrumented for coverage-guided fuzzing and checked by AddressSanitizer; the targets in
  # tests/fuzz link libFuzzer's main.
  target_compile_options(tirstrain_flags INTERFACE -fsanitize=fuzzer-no-link,address -fno-omit-frame-pointer)
  target_link_options(tirstrain_flags INTERFACE -fsanitize=address)
endif()

# Declares a library for one top-level folder: sources given, public headers at <folder>/*.hpp,
# included as "folder/header.hpp" from the repository root.
function(tirstrain_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  if(ARG_SOURCES)
    add_library(${name} STATIC ${ARG_SOURCES})
    # Installed headers keep their folder: include/tirstrain/<folder>/*.hpp (cmake/TirstrainInstall.cmake).
    target_include_directories(${name} PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
                                              $<INSTALL_INTERFACE:include/tirstrain>)
    target_link_libraries(${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS} tirstrain_flags)
    # The headers use C++20 (std::span, concepts): a consumer of the installed package gets it too.
    target_compile_features(${name} PUBLIC cxx_std_20)
  else()
    add_library(${name} INTERFACE)
    target_include_directories(${name} INTERFACE $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
                                                 $<INSTALL_INTERFACE:include/tirstrain>)
    target_link_libraries(${name} INTERFACE ${ARG_PUBLIC_DEPS})
    target_compile_features(${name} INTERFACE cxx_std_20)
  endif()
endfunction()
