// libFuzzer target: a force/accelerometer channel CSV (signals/channels.hpp read_channels).
#include <cstddef>
#include <cstdint>

#include "core/error.hpp"
#include "signals/channels.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = tirstrain::fuzz::write_bytes("channels.csv", data, size);
  try {
    tirstrain::signals::ChannelReadOptions options;
    options.required = {"normal_N"};
    tirstrain::signals::read_channels(path, options);
  } catch (const tirstrain::Error&) {
  }
  return 0;
}
