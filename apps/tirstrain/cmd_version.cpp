// `tirstrain version`: the version and the libraries this build uses, for bug reports and result files.
#include <H5Cpp.h>
#include <opencv2/core/version.hpp>

#include <iostream>

#include "core/version.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {

void add_version_command(CLI::App& app) {
  CLI::App* sub = app.add_subcommand("version", "Print the version and the library versions of this build");
  sub->footer("Example:\n  tirstrain version    # paste into a bug report");
  sub->callback([] {
    unsigned major = 0, minor = 0, release = 0;
    H5::H5Library::getLibVersion(major, minor, release);
    std::cout << "tirstrain " << kVersion << "\nOpenCV " << CV_VERSION << "\nHDF5 " << major << '.' << minor
              << '.' << release << '\n';
  });
}

}  // namespace tirstrain::cli
