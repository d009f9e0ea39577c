// tirstrain: fingertip skin strain from TIR contact images. Subcommands live in cmd_<name>.cpp.
#include <cstring>
#include <exception>
#include <iostream>
#include <string>

#include "core/error.hpp"
#include "core/version.hpp"
#include "tirstrain/commands.hpp"

namespace {

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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"tirstrain " + std::string(tirstrain::kVersion) +
               " - fingertip skin deformation from total-internal-reflection contact images.\n"
               "Physical quantities are SI (m, N, Pa, J, s) unless a name says otherwise (_px, _mm, _deg)."};
  app.set_version_flag("--version", std::string("tirstrain ") + tirstrain::kVersion);
  app.require_subcommand(1);
  app.fallthrough(false);
#define TIRSTRAIN_COMMAND(name) tirstrain::cli::add_##name##_command(app);
#include "command_list.inc"
#undef TIRSTRAIN_COMMAND

  if (report_unknown_subcommand(app, argc, argv)) return 2;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const tirstrain::Error& e) {
    std::cerr << "tirstrain: error: " << e.what() << '\n';
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "tirstrain: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
