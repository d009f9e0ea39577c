#pragma once
// What many test suites need: a fresh scratch folder under the build's test area, and the message of the
// tirstrain::Error a call throws.
#include <filesystem>
#include <functional>
#include <string>

#include "core/error.hpp"

namespace tirstrain::testing {

// TIRSTRAIN_TEST_TMP/suite/name, emptied and created; a staging folder "name.partial" that an earlier run
// of the test left beside it (a killed run, a build before the staging marker) is removed too.
inline std::filesystem::path scratch_dir(const std::string& suite, const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(TIRSTRAIN_TEST_TMP) / suite / name;
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(dir.string() + ".partial");
  std::filesystem::create_directories(dir);
  return dir;
}

// The message of the Error `f` throws, or "(no error)".
inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace tirstrain::testing
