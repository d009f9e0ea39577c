// libFuzzer target: the frames.csv of an image folder (capture/file_sources.hpp), read next to two valid
// frames, then every frame delivered.
#include <cstddef>
#include <cstdint>

#include "capture/file_sources.hpp"
#include "core/error.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace tirstrain;
  fuzz::write_valid_frame("rec/frames/000000.png");
  fuzz::write_valid_frame("rec/frames/000001.png");
  fuzz::write_bytes("rec/frames.csv", data, size);
  try {
    auto source = capture::open_file_source((fuzz::scratch() / "rec").string());
    while (source->next()) {
    }
  } catch (const Error&) {
  }
  return 0;
}
