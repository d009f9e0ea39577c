#include "report/vendored_scripts.hpp"

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

// Each file is placed in read-only data between a begin and an end symbol by the assembler, followed by a
// NUL so that the bytes are never read as a C string by mistake; the sizes come from the symbols.
#define TIRSTRAIN_EMBED(symbol, file)             \
  asm(".section .rodata\n"                        \
      ".balign 16\n"                              \
      ".global " #symbol "_begin\n" #symbol       \
      "_begin:\n"                                 \
      ".incbin \"" TIRSTRAIN_WEB_MODULES "/" file \
      "\"\n"                                      \
      ".global " #symbol "_end\n" #symbol         \
      "_end:\n"                                   \
      ".byte 0\n"                                 \
      ".previous\n");                             \
  extern "C" const char symbol##_begin[];         \
  extern "C" const char symbol##_end[];

TIRSTRAIN_EMBED(tirstrain_vega_js, "vega/build/vega.min.js")
TIRSTRAIN_EMBED(tirstrain_vega_lite_js, "vega-lite/build/vega-lite.min.js")
TIRSTRAIN_EMBED(tirstrain_vega_embed_js, "vega-embed/build/vega-embed.min.js")
TIRSTRAIN_EMBED(tirstrain_vega_licence, "vega/LICENSE")
TIRSTRAIN_EMBED(tirstrain_vega_lite_licence, "vega-lite/LICENSE")
TIRSTRAIN_EMBED(tirstrain_vega_embed_licence, "vega-embed/LICENSE")
TIRSTRAIN_EMBED(tirstrain_vega_package, "vega/package.json")
TIRSTRAIN_EMBED(tirstrain_vega_lite_package, "vega-lite/package.json")
TIRSTRAIN_EMBED(tirstrain_vega_embed_package, "vega-embed/package.json")

namespace tirstrain::report {
namespace {

std::string_view bytes(const char* begin, const char* end) {
  return {begin, static_cast<std::size_t>(end - begin)};
}

std::string version_of(std::string_view package_json) {
  const auto parsed = nlohmann::json::parse(package_json, nullptr, false);
  return parsed.is_object() ? parsed.value("version", std::string("unknown")) : "unknown";
}

}  // namespace

const std::vector<VendoredScript>& vendored_scripts() {
  static const std::vector<VendoredScript> scripts = [] {
    std::vector<VendoredScript> list;
    list.push_back({"vega", version_of(bytes(tirstrain_vega_package_begin, tirstrain_vega_package_end)),
                    bytes(tirstrain_vega_js_begin, tirstrain_vega_js_end),
                    bytes(tirstrain_vega_licence_begin, tirstrain_vega_licence_end)});
    list.push_back({"vega-lite",
                    version_of(bytes(tirstrain_vega_lite_package_begin, tirstrain_vega_lite_package_end)),
                    bytes(tirstrain_vega_lite_js_begin, tirstrain_vega_lite_js_end),
                    bytes(tirstrain_vega_lite_licence_begin, tirstrain_vega_lite_licence_end)});
    list.push_back({"vega-embed",
                    version_of(bytes(tirstrain_vega_embed_package_begin, tirstrain_vega_embed_package_end)),
                    bytes(tirstrain_vega_embed_js_begin, tirstrain_vega_embed_js_end),
                    bytes(tirstrain_vega_embed_licence_begin, tirstrain_vega_embed_licence_end)});
    return list;
  }();
  return scripts;
}

}  // namespace tirstrain::report
