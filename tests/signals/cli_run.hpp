#pragma once
// The signals CLI tests' shared pieces: a folder per test, and the tirstrain command run with its output.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

namespace tirstrain::testing {

// TIRSTRAIN_TEST_TMP/suite/<the running test's name>, created. One folder per test: CTest runs a file's
// tests in parallel processes, and a shared input was rewritten by one test while another read it.
inline std::string test_dir(const std::string& suite) {
  const std::string d = std::string(TIRSTRAIN_TEST_TMP) + "/" + suite + "/" +
                        ::testing::UnitTest::GetInstance()->current_test_info()->name();
  std::filesystem::create_directories(d);
  return d;
}

struct CliRun {
  int code = 0;
  std::string output;  // stdout and stderr
};

inline CliRun run_cli(const std::string& args) {
  const std::string cmd = std::string(TIRSTRAIN_CLI) + " " + args + " 2>&1";
  CliRun r;
  FILE* pipe = popen(cmd.c_str(), "r");
  char buf[512];
  while (pipe && fgets(buf, sizeof buf, pipe)) r.output += buf;
  const int status = pipe ? pclose(pipe) : -1;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace tirstrain::testing
