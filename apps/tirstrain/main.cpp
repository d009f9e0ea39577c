// tirstrain: fingertip skin strain from TIR contact images. Subcommands live in cmd_<name>.cpp.
#include <algorithm>
#include <csignal>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "core/error.hpp"
#include "core/version.hpp"
#include "tirstrain/commands.hpp"

namespace {

constexpr int kExitUsage = 2;  // the command line is wrong (README, --help)

// CLI11's own message for an unknown subcommand ("arguments were not expected") does not tell a newcomer
// what exists, so the first positional word is checked against the registered subcommands first.
bool report_unknown_subcommand(const CLI::App& app, int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') return false;
  const std::string word = argv[1];
  std::string names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (sub->get_name() == word) return false;
    names += "  " + sub->get_name() + "  " + sub->get_description() + "\n";
  }
  std::cerr << "tirstrain: unknown command '" << word << "'.\nAvailable commands:\n"
            << names << "Run 'tirstrain --help' or 'tirstrain COMMAND --help' for details.\n";
  return true;
}

// Edit distance between two words, for "did you mean".
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// The deepest subcommand the command line reached ("signals psd"), or the root.
const CLI::App* deepest_command(const CLI::App& app) {
  const CLI::App* at = &app;
  while (!at->get_subcommands().empty()) at = at->get_subcommands().front();
  return at;
}

// CLI11 says only "not expected" for a mistyped option: name the command and the closest option it has.
void report_unexpected(const CLI::App& app, const CLI::ExtrasError& error) {
  const CLI::App* command = deepest_command(app);
  std::string path;
  for (const CLI::App* at = command; at != nullptr && at->get_parent() != nullptr; at = at->get_parent())
    path = at->get_name() + (path.empty() ? "" : " " + path);
  const std::vector<std::string> extras = command->remaining();
  std::cerr << "tirstrain: error: " << error.what() << "\n";
  for (const std::string& extra : extras) {
    if (extra.rfind("--", 0) != 0) continue;
    const std::string word = extra.substr(2, extra.find('=') - 2);
    std::string best;
    std::size_t best_distance = std::max<std::size_t>(2, word.size() / 3) + 1;
    for (const CLI::Option* option : command->get_options())
      for (const std::string& name : option->get_lnames())
        if (const std::size_t d = edit_distance(word, name); d < best_distance) {
          best_distance = d;
          best = name;
        }
    if (!best.empty()) std::cerr << "  " << extra << ": did you mean --" << best << "?\n";
  }
  std::cerr << "Run 'tirstrain " << path << (path.empty() ? "" : " ") << "--help' for the options.\n";
}

// An error about an option's value alone (it names the option, and no file, frame or row it was read from)
// is the command line's: the same as a value CLI11 refuses.
bool is_command_line_error(const tirstrain::Error& e) {
  const tirstrain::ErrorContext& c = e.context();
  return c.key.rfind("--", 0) == 0 && c.file.empty() && !c.frame && !c.row;
}

}  // namespace

int main(int argc, char** argv) {
  // A write past the file-size limit (RLIMIT_FSIZE) fails with EFBIG and is reported like a full disk,
  // instead of the signal ending the process wherever it is.
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"tirstrain " + std::string(tirstrain::kVersion) +
               " - fingertip skin deformation from total-internal-reflection contact images.\n"
               "Physical quantities are SI (m, N, Pa, J, s) unless a name says otherwise (_px, _mm, _deg)."};
  app.set_version_flag("--version", std::string("tirstrain ") + tirstrain::kVersion);
  app.require_subcommand(1);
  app.footer(
      "Exit codes: 0 success; 1 the run failed (bad input, unwritable or full output disk, lost camera: the\n"
      "message says what and where; earlier complete outputs are left as they were); 2 the command line is\n"
      "wrong (unknown command or option, bad or missing value); 128+N killed by signal N.");
  app.fallthrough(false);
  // OpenCV's TBB backend sizes its pool from the cores and ignores OPENCV_FOR_THREADS_NUM, so the thread
  // count is set here, before any command runs: trials side by side, a Slurm task's CPUs or a shared machine
  // want fewer than every core.
  int threads = 0;
  app.add_option("--threads", threads,
                 "Threads of the image-processing loops: 0 every core (default), 1 serial. Example: "
                 "tirstrain --threads 1 process REC --out R")
      ->check(CLI::Range(0, 4096));
  app.parse_complete_callback([&threads] {
    if (threads > 0) cv::setNumThreads(threads);
  });
#define TIRSTRAIN_COMMAND(name) tirstrain::cli::add_##name##_command(app);
#include "command_list.inc"
#undef TIRSTRAIN_COMMAND

  if (report_unknown_subcommand(app, argc, argv)) return kExitUsage;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ExtrasError& e) {
    report_unexpected(app, e);
    return kExitUsage;
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : kExitUsage;  // --help and --version are parse "errors" that succeed
  } catch (const tirstrain::Error& e) {
    std::cerr << "tirstrain: error: " << e.what() << '\n';
    return is_command_line_error(e) ? kExitUsage : 1;
  } catch (const std::exception& e) {
    std::cerr << "tirstrain: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
