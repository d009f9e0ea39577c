#pragma once
// The output folder of `process`: replaced as a whole when a run completes (core/atomic_output.hpp
// StagingDirectory), so it must hold nothing but an earlier run's results, and never the input.
#include <string>
#include <vector>

namespace tirstrain::pipeline {

// The files and folders a process run writes into its output folder.
const std::vector<std::string>& process_output_names();

// The paths on disk an input names: a folder or file itself, the folder of a printf or glob pattern;
// nothing for a camera URI (aravis:, v4l2:, libcamera:).
std::vector<std::string> input_locations(const std::string& input);

// Throws Error (naming --out) when `out_dir` is one of `inputs`, holds one of them, or exists and holds
// anything a process run does not write (which the swap would delete).
void check_output_folder(const std::string& out_dir, const std::vector<std::string>& inputs);

}  // namespace tirstrain::pipeline
