#pragma once
// A picture written for people to look at: encoded as PNG in memory and written through AtomicFile
// (checked writes, a temporary name, renamed when complete), so a full disk is an error naming the file and
// never a cut-off image under the final name.
#include <opencv2/core.hpp>

#include <string>

namespace tirstrain {

// Throws Error naming `path` when the image cannot be encoded or written.
void write_png_file(const std::string& path, const cv::Mat& image);

}  // namespace tirstrain
