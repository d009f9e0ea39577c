#include "signals/phases_json.hpp"

namespace tirstrain::signals {
namespace {

nlohmann::json interval(const std::string& name, double start_s, double end_s) {
  return {{"name", name}, {"start_s", start_s}, {"end_s", end_s}};
}

nlohmann::json channel_tare_json(const ChannelTare& c) {
  return {{"offset_N", c.offset}, {"drift_N_per_s", c.drift_per_s}, {"residual_rms_N", c.residual_rms}};
}

// Approach, press, then loading and slide alternating per stroke, release and the time after contact.
nlohmann::json intervals_json(const Phases& p) {
  nlohmann::json list = nlohmann::json::array();
  list.push_back(interval("approach", p.record_start_s, p.contact_start_s));
  list.push_back(interval("press", p.contact_start_s, p.loaded_s));
  double t = p.loaded_s;
  for (std::size_t k = 0; k < p.strokes.size(); ++k) {
    const Stroke& s = p.strokes[k];
    if (s.slide_start_s > t) list.push_back(interval("loading", t, s.slide_start_s));
    auto slide = interval("slide", s.slide_start_s, s.slide_end_s);
    slide["stroke"] = k;
    list.push_back(slide);
    t = s.slide_end_s;
  }
  if (p.release_s > t) list.push_back(interval(p.strokes.empty() ? "loading" : "hold", t, p.release_s));
  list.push_back(interval("release", p.release_s, p.contact_end_s));
  list.push_back(interval("after_contact", p.contact_end_s, p.record_end_s));
  return list;
}

nlohmann::json tare_json(const Tare& tare) {
  nlohmann::json quiet = nlohmann::json::array();
  for (const TimeStretch& q : tare.quiet) quiet.push_back({q.start_s, q.end_s});
  return {{"model", tare.model},
          {"source", tare.source},
          {"quiet_stretches_s", quiet},
          {"reference_s", tare.reference_s},
          {"baseline", "offset + drift * (t - reference_s), subtracted from the channel"},
          {"normal", channel_tare_json(tare.normal)},
          {"tangential", channel_tare_json(tare.tangential)}};
}

}  // namespace

nlohmann::json warnings_json(const std::vector<PhaseWarning>& warnings) {
  nlohmann::json list = nlohmann::json::array();
  for (const PhaseWarning& w : warnings) list.push_back({{"code", w.code}, {"message", w.message}});
  return list;
}

nlohmann::json phases_json(const Phases& p) {
  nlohmann::json strokes = nlohmann::json::array();
  for (const Stroke& s : p.strokes)
    strokes.push_back({{"slide_start_s", s.slide_start_s},
                       {"slide_end_s", s.slide_end_s},
                       {"mu_mean", s.mu_mean},
                       {"mu_sd", s.mu_sd},
                       {"mu_samples", s.mu_samples},
                       {"direction", s.direction},
                       {"direction_source", s.direction_source}});
  return {{"record_start_s", p.record_start_s},
          {"contact_start_s", p.contact_start_s},
          {"loaded_s", p.loaded_s},
          {"release_s", p.release_s},
          {"contact_end_s", p.contact_end_s},
          {"record_end_s", p.record_end_s},
          {"normal_level_N", p.normal_level_N},
          {"normal_sign", p.normal_sign},
          {"strokes", strokes},
          {"phases", intervals_json(p)},
          {"tare", tare_json(p.tare)},
          {"warnings", warnings_json(p.warnings)}};
}

}  // namespace tirstrain::signals
