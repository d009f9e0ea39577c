// Links the installed tirstrain::pipeline (and through it every library and their private dependencies) and
// checks that it runs: processing a recording that does not exist fails with tirstrain::Error naming it.
#include <cstdio>
#include <string>

#include "core/error.hpp"
#include "pipeline/process.hpp"
#include "strain/mesh.hpp"  // std::span in its interface: the package must carry C++20

int main() {
  tirstrain::pipeline::ProcessOptions options;
  options.input = "/nonexistent/tirstrain-consumer-input";
  options.out_dir = "/nonexistent/tirstrain-consumer-output";
  options.quiet = true;
  try {
    tirstrain::pipeline::run_process(options);
  } catch (const tirstrain::Error& e) {
    const bool named = std::string(e.what()).find(options.input) != std::string::npos;
    std::printf("pipeline: %s (%s)\n", named ? "ok" : "MISSING INPUT NAME", e.what());
    return named ? 0 : 1;
  }
  std::printf("pipeline: processing a missing input did not fail\n");
  return 1;
}
