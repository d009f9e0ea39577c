// `tirstrain model texture-interaction`: the fingerprint–texture overlap model
// (model/texture_interaction.hpp) for a ridge period, one or more texture periods, a speed and a contact
// length → the spectral lines the finger receives, the strongest one, and the zone (texture finer than,
// comparable to or coarser than the ridges).
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "model/texture_interaction.hpp"
#include "tirstrain/model_verbs.hpp"

namespace tirstrain::cli {
namespace {

using nlohmann::json;

struct TextureOptions {
  double ridge_period_mm = 0.45;           // λ_f, fingerprint ridge period
  std::vector<double> texture_periods_mm;  // λ_s, one prediction each
  double speed_mm_s = 50.0;                // v, sliding speed
  double contact_length_mm = 10.0;         // L, contact length along the sliding direction
  double ridge_amplitude_um = 50.0;        // a_f
  double texture_amplitude_um = 50.0;      // a_s
  double interpenetration = 0.5;           // fraction of a_f + a_s that overlaps
  double zone_tolerance = 0.25;            // |λ_s − λ_f| <= tol·λ_f is "comparable"
  double min_line_fraction = 0.01;         // lines weaker than this fraction of the peak are not listed
  std::string out;                         // JSON (optional)
};

std::string option_of(const std::string& field) {
  if (field.find("ridge_period") != std::string::npos) return "--ridge-period-mm";
  if (field.find("surface_wavelength") != std::string::npos) return "--texture-period-mm";
  if (field.find("speed") != std::string::npos) return "--speed-mm-s";
  if (field.find("contact_length") != std::string::npos) return "--contact-length-mm";
  if (field.find("ridge_amplitude") != std::string::npos) return "--ridge-amplitude-um";
  if (field.find("surface_amplitude") != std::string::npos) return "--texture-amplitude-um";
  if (field.find("interpenetration") != std::string::npos) return "--interpenetration";
  return "";
}

// The model's messages name its fields in SI units; the user gave options in mm and um.
std::string in_the_options_words(std::string message) {
  const std::pair<const char*, const char*> words[] = {{"surface_wavelength_m", "the texture period"},
                                                       {"ridge_period_m", "the ridge period"},
                                                       {"speed_m_s", "the speed"},
                                                       {"contact_length_m", "the contact length"},
                                                       {"ridge_amplitude_m", "the ridge height"},
                                                       {"surface_amplitude_m", "the texture height"}};
  for (const auto& [field, words_for] : words)
    if (const std::size_t at = message.find(field); at != std::string::npos)
      message.replace(at, std::string(field).size(), words_for);
  return message;
}

model::InteractionPrediction predict(const TextureOptions& o, double texture_period_mm) {
  model::TextureInteractionParams p;
  p.ridge_period_m = o.ridge_period_mm * 1e-3;
  p.surface_wavelength_m = texture_period_mm * 1e-3;
  p.speed_m_s = o.speed_mm_s * 1e-3;
  p.contact_length_m = o.contact_length_mm * 1e-3;
  p.ridge_amplitude_m = o.ridge_amplitude_um * 1e-6;
  p.surface_amplitude_m = o.texture_amplitude_um * 1e-6;
  p.interpenetration = o.interpenetration;
  try {
    return model::predict_interaction(p, o.zone_tolerance);
  } catch (const std::invalid_argument& e) {
    throw Error(in_the_options_words(e.what()), {.key = option_of(e.what())});
  }
}

json prediction_json(const model::InteractionPrediction& r, double texture_period_mm, double min_fraction) {
  json lines = json::array();
  for (const auto& line : r.lines)
    if (line.amplitude_m2 >= min_fraction * r.modulation_m2)
      lines.push_back(
          {{"harmonic", line.harmonic},
           {"frequency_Hz", line.frequency_Hz},
           {"amplitude_um2", line.amplitude_m2 * 1e12},
           {"relative_amplitude", r.modulation_m2 > 0.0 ? line.amplitude_m2 / r.modulation_m2 : 0.0}});
  return {{"texture_period_mm", texture_period_mm},
          {"zone", model::to_string(r.zone)},
          {"surface_frequency_Hz", r.surface_frequency_Hz},
          {"ridge_frequency_Hz", r.ridge_frequency_Hz},
          {"peak_frequency_Hz", r.peak_frequency_Hz},
          {"peak_harmonic", r.peak_harmonic},
          {"peak_amplitude_um2", r.modulation_m2 * 1e12},
          {"mean_overlap_um2", r.mean_area_m2 * 1e12},
          {"lines", lines}};
}

void print_row(const json& j) {
  std::printf("%10.4g  %-22s %12.4g %12.4g %12.4g %5d\n", j["texture_period_mm"].get<double>(),
              j["zone"].get<std::string>().c_str(), j["surface_frequency_Hz"].get<double>(),
              j["ridge_frequency_Hz"].get<double>(), j["peak_frequency_Hz"].get<double>(),
              j["peak_harmonic"].get<int>());
}

}  // namespace

void add_model_texture_interaction_verb(CLI::App& model) {
  auto o = std::make_shared<TextureOptions>();
  CLI::App* sub = model.add_subcommand(
      "texture-interaction",
      "Spectral lines a fingerprint receives sliding on a periodic texture, and the texture's zone");
  sub->footer(
      "Model (1-D along the sliding direction): sinusoidal ridges of period lambda_f fixed in a contact of "
      "length L; a sinusoidal texture of period lambda_s sliding past at speed v; the overlap area where the "
      "two profiles interpenetrate is periodic with period lambda_s/v, so its lines are the harmonics "
      "m*v/lambda_s. The strongest line and the zone (texture finer than, comparable to within "
      "--zone-tolerance, or coarser than the ridges) are printed per texture period; --out writes them with "
      "every line above --min-line-fraction of the strongest as JSON.\n"
      "Example: tirstrain model texture-interaction --texture-period-mm 0.2 0.45 1.0 2.0 --speed-mm-s 50");
  sub->add_option("--texture-period-mm", o->texture_periods_mm, "texture period(s) lambda_s, mm")->required();
  sub->add_option("--ridge-period-mm", o->ridge_period_mm, "fingerprint ridge period lambda_f, mm")
      ->capture_default_str();
  sub->add_option("--speed-mm-s", o->speed_mm_s, "sliding speed v, mm/s")->capture_default_str();
  sub->add_option("--contact-length-mm", o->contact_length_mm, "contact length L along the sliding, mm")
      ->capture_default_str();
  sub->add_option("--ridge-amplitude-um", o->ridge_amplitude_um, "ridge height a_f, um")
      ->capture_default_str();
  sub->add_option("--texture-amplitude-um", o->texture_amplitude_um, "texture height a_s, um")
      ->capture_default_str();
  sub->add_option("--interpenetration", o->interpenetration, "overlapping fraction of a_f + a_s, (0, 1]")
      ->capture_default_str();
  sub->add_option("--zone-tolerance", o->zone_tolerance, "relative band of the comparable zone, [0, 1)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.999));
  sub->add_option("--min-line-fraction", o->min_line_fraction,
                  "lines listed in --out above this fraction of the strongest, [0, 1]")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--out", o->out, "JSON with every texture period's prediction and lines");
  sub->callback([o] {
    json predictions = json::array();
    for (double period : o->texture_periods_mm)
      predictions.push_back(prediction_json(predict(*o, period), period, o->min_line_fraction));
    std::printf("%10s  %-22s %12s %12s %12s %5s\n", "lambda_mm", "zone", "v/lambda_Hz", "ridges_Hz",
                "peak_Hz", "m");
    for (const auto& p : predictions) print_row(p);
    if (o->out.empty()) return;
    write_text_file(o->out, json{{"ridge_period_mm", o->ridge_period_mm},
                                 {"speed_mm_s", o->speed_mm_s},
                                 {"contact_length_mm", o->contact_length_mm},
                                 {"ridge_amplitude_um", o->ridge_amplitude_um},
                                 {"texture_amplitude_um", o->texture_amplitude_um},
                                 {"interpenetration", o->interpenetration},
                                 {"zone_tolerance", o->zone_tolerance},
                                 {"predictions", predictions}}
                                    .dump(2) +
                                "\n");
  });
}

}  // namespace tirstrain::cli
