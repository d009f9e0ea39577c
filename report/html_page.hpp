#pragma once
// A self-contained HTML page: the vendored plotting scripts, the figures' specifications and the styles are
// inlined, so the file opens offline and can be mailed or archived as one file. Each figure is a <figure>
// with a <figcaption>; a small script renders every specification with vega-embed and marks the page
// `data-rendered` (the figure count) when all are drawn, or `data-render-error` with the reason.
#include <string>
#include <vector>

#include "report/figures.hpp"

namespace tirstrain::report {

// A part of the page that is text rather than a plot (settings, versions); `html` is already escaped.
struct PageSection {
  std::string id;
  std::string title;
  std::string html;
};

struct Page {
  std::string title;       // <title> and the heading
  std::string intro_html;  // paragraph(s) under the heading, already escaped
  std::vector<Figure> figures;
  std::vector<PageSection> sections;  // after the figures
};

// In every page's head: how a later run knows an existing file is an earlier page it may replace.
inline constexpr const char* kGeneratorMeta = "<meta name=\"generator\" content=\"tirstrain report\">";
// The script element holding the figures' specifications, in every page (also those written before the meta).
inline constexpr const char* kSpecsScriptId = "<script type=\"application/json\" id=\"tirstrain-specs\">";

std::string render_page(const Page& page);

}  // namespace tirstrain::report
