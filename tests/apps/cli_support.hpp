#pragma once
// Runs the real tirstrain binary and captures its exit code and combined output.
#include <sys/wait.h>
#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

namespace tirstrain::testing {

struct CliResult {
  int exit_code = -1;
  std::string output;
};

inline CliResult run_cli(const std::string& arguments) {
  const std::string command = std::string(TIRSTRAIN_CLI) + " " + arguments + " 2>&1";
  CliResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe)) result.output += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

inline std::string fresh_dir(const std::string& name) {
  const std::string dir = std::string(TIRSTRAIN_TEST_TMP) + "/" + name;
  std::filesystem::remove_all(dir);
  return dir;
}

}  // namespace tirstrain::testing
