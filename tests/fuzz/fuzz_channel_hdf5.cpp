// libFuzzer target: channels in an HDF5 or MATLAB file of any version (signals/channels.hpp read_channels;
// MATLAB v4, v5 and v7 through libmatio, recognised by their first bytes).
#include <cstddef>
#include <cstdint>

#include "core/error.hpp"
#include "signals/channels.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = tirstrain::fuzz::write_bytes("channels.mat", data, size);
  // In this process: the crash a child process would catch is what the fuzzer is looking for.
  tirstrain::signals::ChannelReadOptions options;
  options.read_in_child_first = false;
  try {
    tirstrain::signals::read_channels(path, options);
  } catch (const tirstrain::Error&) {
  }
  return 0;
}
