// libFuzzer target: a scene file (core/scene.hpp load_scene), the YAML every command reads. Bad input must
// end in tirstrain::Error; anything else (a crash, another exception, a hang) is a finding.
#include <cstddef>
#include <cstdint>

#include "core/error.hpp"
#include "core/scene.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = tirstrain::fuzz::write_bytes("scene.yaml", data, size);
  try {
    tirstrain::load_scene(path);
  } catch (const tirstrain::Error&) {
  }
  return 0;
}
