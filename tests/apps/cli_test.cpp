#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "core/version.hpp"
#include "tests/support/scratch.hpp"

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

TEST(Cli, HelpDocumentsTheExitCodes) {
  const auto r = run_cli("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* part :
       {"Exit codes: 0 success; 1 the run failed", "2 the command line is", "128+N killed"})
    EXPECT_NE(r.output.find(part), std::string::npos) << part << "\n" << r.output;
}

// The commands listed under SUBCOMMANDS in a --help text: the section's lines "  name   summary" up to its
// first blank line.
std::vector<std::string> subcommands_in(const std::string& help) {
  std::vector<std::string> names;
  const std::size_t from = std::min(help.find("SUBCOMMANDS:"), help.find("Subcommands:"));  // CLI11 1.x / 2.x
  if (from == std::string::npos) return names;
  std::istringstream lines(help.substr(from));
  std::string line;
  std::getline(lines, line);
  while (std::getline(lines, line) && !line.empty()) {
    if (line.rfind("  ", 0) != 0 || line.size() < 3 || !std::islower(static_cast<unsigned char>(line[2])))
      continue;
    names.push_back(line.substr(2, line.find(' ', 2) - 2));
  }
  return names;
}

TEST(Cli, EveryCommandsHelpGivesAnExample) {
  std::vector<std::string> pending = subcommands_in(run_cli("--help").output);
  ASSERT_GE(pending.size(), 15u);
  int leaves = 0;
  while (!pending.empty()) {
    const std::string command = pending.back();
    pending.pop_back();
    const auto r = run_cli(command + " --help");
    ASSERT_EQ(r.exit_code, 0) << command;
    const std::vector<std::string> below = subcommands_in(r.output);
    ASSERT_LE(std::count(command.begin(), command.end(), ' '), 2) << command;
    for (const std::string& name : below) pending.push_back(command + " " + name);
    if (!below.empty()) continue;
    ++leaves;
    EXPECT_NE(r.output.find("Example"), std::string::npos) << "tirstrain " << command << " --help";
  }
  EXPECT_GE(leaves, 30);
}

// A value the command line gives that a command refuses by itself (not through the option parser) is a
// usage error all the same: exit 2, the option named. A run failure is 1.
TEST(Cli, RefusedOptionValuesExitWithTheUsageCode) {
  const std::string dir = testing::scratch_dir("cli", "usage_codes").string();
  for (const std::string& args : {std::string("validate --out ") + dir + "/v",
                                  "track " + dir + " --grid 20 --roi a,b,c,d --out " + dir + "/t.csv",
                                  "track " + dir + " --grid 20 --preset foo --out " + dir + "/t.csv",
                                  "process " + dir + " --compute bogus --out " + dir + "/p"}) {
    const auto r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("'--"), std::string::npos) << args << "\n" << r.output;
  }
  const auto missing = run_cli("process " + dir + "/no_such_recording --out " + dir + "/p");
  EXPECT_EQ(missing.exit_code, 1) << missing.output;
}

TEST(Cli, MistypedOptionGetsASuggestionAndUsageExitCode) {
  const auto r = run_cli("process in --ovrlay png --out x");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--ovrlay: did you mean --overlay?"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("tirstrain process --help"), std::string::npos) << r.output;
  const auto far = run_cli("process in --zzzzzzzz --out x");
  EXPECT_EQ(far.exit_code, 2) << far.output;
  EXPECT_EQ(far.output.find("did you mean"), std::string::npos) << far.output;
}

TEST(Cli, NegativeValuesAreRefusedByName) {
  const auto overlap = run_cli("signals psd in.csv --out o.csv --column c --segment 64 --overlap -10");
  EXPECT_EQ(overlap.exit_code, 2) << overlap.output;
  EXPECT_NE(overlap.output.find("--overlap: must be a whole number of samples, 0 or more; got -10"),
            std::string::npos)
      << overlap.output;
  const auto cutoff = run_cli("signals filter in.csv --out o.csv --column c --lowpass-Hz -5");
  EXPECT_EQ(cutoff.exit_code, 2) << cutoff.output;
  EXPECT_NE(cutoff.output.find("--lowpass-Hz: must be a frequency above 0 Hz; got -5"), std::string::npos)
      << cutoff.output;
  EXPECT_EQ(cutoff.output.find("give exactly one of"), std::string::npos) << cutoff.output;
  const auto frames = run_cli("record in --out o --frames 0");
  EXPECT_EQ(frames.exit_code, 2) << frames.output;
  EXPECT_NE(frames.output.find("--frames: must be a number above 0; got 0"), std::string::npos)
      << frames.output;
  EXPECT_EQ(frames.output.find("1797693"), std::string::npos) << frames.output;  // no 300-digit limit
  const auto queue = run_cli("record in --out o --queue-MiB 0");
  EXPECT_EQ(queue.exit_code, 2) << queue.output;
  EXPECT_NE(queue.output.find("--queue-MiB"), std::string::npos) << queue.output;
}

TEST(Cli, TooShortChannelNamesTheColumnNotAMadeUpOption) {
  const std::string dir = testing::fresh_dir("cli_short_channel");
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/short.csv") << "t_s,normal_N\n0,1\n0.001,2\n0.002,3\n0.003,2\n0.004,1\n";
  const auto r = run_cli("signals filter " + dir + "/short.csv --out " + dir +
                         "/o.csv --column normal_N --lowpass-Hz 10");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("column 'normal_N'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("signal has 5 samples"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("'--x'"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir + "/o.csv.partial"));
}

TEST(Cli, UnknownSourceSchemeListsTheSchemes) {
  const std::string dir = testing::fresh_dir("cli_scheme");
  const auto r = run_cli("record aravsi:Fake --out " + dir + "/rec --frames 1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("unknown source scheme 'aravsi:'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("v4l2:/dev/videoN"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace tirstrain
