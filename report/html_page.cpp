#include "report/html_page.hpp"

#include <string_view>

#include "core/error.hpp"
#include "report/vendored_scripts.hpp"

namespace tirstrain::report {
namespace {

constexpr std::string_view kStyle = R"(
body { font: 15px/1.45 system-ui, sans-serif; color: #222; max-width: 1180px; margin: 24px auto; padding: 0 16px; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
figure { margin: 28px 0; padding: 12px; border: 1px solid #ddd; border-radius: 6px; background: #fff; }
figcaption { margin-top: 8px; color: #333; max-width: 1100px; }
figcaption b { color: #000; }
.plot { overflow-x: auto; }
.table { max-height: 420px; overflow: auto; }
table { border-collapse: collapse; font-size: 13px; }
th, td { border: 1px solid #ddd; padding: 2px 6px; text-align: left; }
th { background: #f4f4f4; position: sticky; top: 0; }
pre { background: #f7f7f7; padding: 8px; overflow-x: auto; font-size: 12px; }
nav a { margin-right: 12px; }
)";

// Tells vega-embed to draw each figure; marks each <figure> and the page when done.
constexpr std::string_view kBootstrap = R"(
(function () {
  var specs = JSON.parse(document.getElementById('tirstrain-specs').textContent);
  var options = function (renderer) {
    return { renderer: renderer, mode: 'vega-lite',
             actions: { export: true, source: false, compiled: false, editor: false } };
  };
  var drawn = specs.map(function (s) {
    return vegaEmbed('#' + s.id + ' .plot', s.spec, options(s.renderer)).then(function () {
      document.getElementById(s.id).setAttribute('data-rendered', 'yes');
    });
  });
  Promise.all(drawn).then(function () {
    document.body.setAttribute('data-rendered', String(specs.length));
  }).catch(function (e) {
    document.body.setAttribute('data-render-error', String(e));
    console.error('tirstrain report: a figure could not be drawn: ' + e);
  });
})();
)";

// JSON placed inside a <script> element must not close it early: "<\/" is the same string in JSON.
std::string json_script_safe(std::string_view text) {
  std::string out(text);
  for (std::size_t at = out.find("</"); at != std::string::npos; at = out.find("</", at + 3))
    out.replace(at, 2, "<\\/");
  return out;
}

// A library's code may hold "</" legitimately outside strings; only "</script" would end the element, and
// the pinned versions hold none (checked here, so that an update that adds one fails loudly).
std::string script_code(const VendoredScript& s) {
  if (s.code.find("</script") != std::string_view::npos)
    throw Error(std::string(s.name) + " holds \"</script\", which would end its inlined <script>");
  return std::string(s.code);
}

std::string figure_html(const Figure& f) {
  std::string html = "<figure id=\"" + f.id + "\" class=\"tirstrain-figure\">";
  if (!f.spec.is_null()) html += "<div class=\"plot\"></div>";
  html += f.html;
  html += "<figcaption><b>" + html_escape(f.title) + ".</b> " + html_escape(f.caption) +
          "</figcaption></figure>\n";
  return html;
}

std::string specs_json(const std::vector<Figure>& figures) {
  nlohmann::json specs = nlohmann::json::array();
  for (const Figure& f : figures)
    if (!f.spec.is_null()) specs.push_back({{"id", f.id}, {"renderer", f.renderer}, {"spec", f.spec}});
  return specs.dump();
}

std::string navigation(const Page& page) {
  std::string html = "<nav>";
  for (const Figure& f : page.figures) html += "<a href=\"#" + f.id + "\">" + html_escape(f.title) + "</a>";
  for (const PageSection& s : page.sections)
    html += "<a href=\"#" + s.id + "\">" + html_escape(s.title) + "</a>";
  return html + "</nav>\n";
}

std::string scripts() {
  std::string html;
  for (const VendoredScript& s : vendored_scripts())
    html += "<script data-library=\"" + std::string(s.name) + "@" + s.version + "\">" + script_code(s) +
            "</script>\n";
  return html;
}

}  // namespace

std::string render_page(const Page& page) {
  std::string html = "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n" +
                     std::string(kGeneratorMeta) + "\n<title>" + html_escape(page.title) +
                     "</title>\n<style>" + std::string(kStyle) + "</style>\n" + scripts() +
                     "</head>\n<body>\n";
  html += "<h1>" + html_escape(page.title) + "</h1>\n" + page.intro_html + navigation(page);
  for (const Figure& f : page.figures) html += figure_html(f);
  for (const PageSection& s : page.sections)
    html += "<section id=\"" + s.id + "\"><h2>" + html_escape(s.title) + "</h2>\n" + s.html + "</section>\n";
  html += std::string(kSpecsScriptId) + json_script_safe(specs_json(page.figures)) + "</script>\n";
  html += "<script>" + std::string(kBootstrap) + "</script>\n</body></html>\n";
  return html;
}

}  // namespace tirstrain::report
