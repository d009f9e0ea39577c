#include <gtest/gtest.h>

#include "cli_support.hpp"
#include "core/version.hpp"

namespace tirstrain {
namespace {

using testing::run_cli;

TEST(Cli, VersionFlagPrintsVersion) {
  const auto r = run_cli("--version");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.output, std::string("tirstrain ") + kVersion + "\n");
}

TEST(Cli, HelpListsCommands) {
  const auto r = run_cli("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.output.find("model"), std::string::npos);
  EXPECT_NE(r.output.find("SI (m, N, Pa, J, s)"), std::string::npos);
}

TEST(Cli, UnknownCommandIsExplained) {
  const auto r = run_cli("procss in --out x");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown command 'procss'"), std::string::npos);
  EXPECT_NE(r.output.find("Available commands:"), std::string::npos);
  EXPECT_NE(r.output.find("  model  "), std::string::npos);
}

TEST(Cli, NoCommandIsAnError) {
  const auto r = run_cli("");
  EXPECT_NE(r.exit_code, 0);
}

}  // namespace
}  // namespace tirstrain
