#pragma once
// The browser-side libraries a report inlines, embedded at build time from report/web/node_modules (the
// versions pinned in report/web/package-lock.json).
#include <string>
#include <string_view>
#include <vector>

namespace tirstrain::report {

struct VendoredScript {
  std::string_view name;     // npm package name, e.g. "vega-lite"
  std::string version;       // its version, from its package.json
  std::string_view code;     // the minified script (UMD: defines a global)
  std::string_view licence;  // the package's LICENSE text
};

// Vega, Vega-Lite and vega-embed, in the order a page must load them.
const std::vector<VendoredScript>& vendored_scripts();

}  // namespace tirstrain::report
