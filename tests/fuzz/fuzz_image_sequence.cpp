// libFuzzer target: opening an image sequence whose first frame is the fuzzer's bytes (as PNG, then as
// TIFF) next to a valid second frame, and reading every frame (capture/file_sources.hpp).
#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "capture/file_sources.hpp"
#include "core/error.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace {

void read_folder(const std::string& folder) {
  try {
    auto source = tirstrain::capture::open_file_source((tirstrain::fuzz::scratch() / folder).string());
    while (source->next()) {
    }
  } catch (const tirstrain::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace tirstrain;
  fuzz::write_valid_frame("png/000001.png");
  fuzz::write_bytes("png/000000.png", data, size);
  read_folder("png");
  fuzz::write_valid_frame("tif/000001.tif");
  fuzz::write_bytes("tif/000000.tif", data, size);
  read_folder("tif");
  return 0;
}
