#pragma once
// Each subcommand registers itself on the root CLI app from its own cmd_<name>.cpp.
#include <CLI/CLI.hpp>

namespace tirstrain::cli {

#define TIRSTRAIN_COMMAND(name) void add_##name##_command(CLI::App& app);
#include "command_list.inc"
#undef TIRSTRAIN_COMMAND

}  // namespace tirstrain::cli
