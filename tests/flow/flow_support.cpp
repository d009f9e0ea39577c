#include "flow_support.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace tirstrain::flow::testing {

Score run_and_score(const samples::Trial& trial, const RenderedTrial& frames, const TrackerOptions& settings,
                    bool with_plate) {
  std::optional<RoiPx> plate_roi;
  if (with_plate) plate_roi = trial.config().scene.reference_pattern_roi;
  FeatureTracker tracker(settings, plate_roi);
  Score s;
  const int n = static_cast<int>(frames.frames.size());
  s.frame_rms_px.assign(static_cast<std::size_t>(n), 0.0);
  s.frame_alive.assign(static_cast<std::size_t>(n), 0);
  s.frame_seconds.assign(static_cast<std::size_t>(n), 0.0);
  double sum2 = 0.0, birth2 = 0.0, plate2 = 0.0;
  int plate_n = 0;
  double seconds = 0.0;
  // FLOW_DUMP_CSV=path: one row per live track and frame, for diagnosing where the error comes from.
  std::FILE* dump = nullptr;
  if (const char* path = std::getenv("FLOW_DUMP_CSV")) {
    dump = std::fopen(path, "w");
    if (dump)
      std::fprintf(
          dump,
          "frame,id,born,status,X,Y,x,y,ex,ey,border_px,stick_px,ridge_nx,ridge_ny,zncc,gxx,gxy,gyx,gyy,"
          "txx,txy,tyx,tyy\n");
  }
  long alive_before = 0;
  for (int f = 0; f < n; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    if (f == 0)
      tracker.start(frames.frames[0], frames.mask, trial.frame_times_s()[0]);
    else
      tracker.track(frames.frames[static_cast<std::size_t>(f)], frames.mask,
                    trial.frame_times_s()[static_cast<std::size_t>(f)]);
    const double frame_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    s.frame_seconds[static_cast<std::size_t>(f)] = frame_seconds;
    seconds += frame_seconds;
    if (f > 0) {
      s.main_matched += tracker.stats().main_matched;
      s.entering += alive_before;
    }
    alive_before = tracker.stats().alive;
    s.rest_frames_averaged += tracker.stats().rest_frames_averaged;
    s.rest_frames_on_fit += tracker.stats().at_rest ? 1 : 0;
    if (f == 0) s.tracks_started = static_cast<int>(tracker.tracks().size());
    const samples::FrameField field = trial.field(f);
    double frame2 = 0.0;
    int alive = 0;
    for (const Track& t : tracker.tracks()) {
      if (!is_alive(t.status)) continue;
      ++alive;
      if (t.status == TrackStatus::kBorn && f > 0) {
        const Vec2 truth = field.invert(t.position_px).reference_px;
        const double e = std::hypot(truth.x - t.reference_px.x, truth.y - t.reference_px.y);
        birth2 += e * e;
        s.birth_max_px = std::max(s.birth_max_px, e);
        ++s.born;
      }
      if (f == 0) continue;
      const Vec2 u = field.displacement_px(t.reference_px);
      const double e =
          std::hypot(t.reference_px.x + u.x - t.position_px.x, t.reference_px.y + u.y - t.position_px.y);
      frame2 += e * e;
      if (dump) {
        const Vec2 x_true{t.reference_px.x + u.x, t.reference_px.y + u.y};
        double stick_px = std::nan("");
        const samples::LoadState load = trial.load(f);
        if (field.model() && load.stick_radius_m > 0.0) {
          const Vec2 pm = field.model_point_m(t.reference_px);
          stick_px = (std::hypot(pm.x, pm.y) - load.stick_radius_m) * trial.history().px_per_m();
        }
        // Ridge normal at X: gradient of the ridge indicator (a unit vector across the ridges).
        const samples::Fingerprint& fp = trial.fingerprint();
        const Vec2 X = t.reference_px;
        double gx = 0.0, gy = 0.0;
        for (int k = 0; k < 8; ++k) {  // average over a small neighbourhood: orientation, not phase
          const double a = k * 0.785398, ox = 3.0 * std::cos(a), oy = 3.0 * std::sin(a);
          const double dx = fp.ridge({X.x + ox + 0.5, X.y + oy}) - fp.ridge({X.x + ox - 0.5, X.y + oy});
          const double dy = fp.ridge({X.x + ox, X.y + oy + 0.5}) - fp.ridge({X.x + ox, X.y + oy - 0.5});
          // double-angle average
          gx += dx * dx - dy * dy;
          gy += 2.0 * dx * dy;
        }
        const double ang = 0.5 * std::atan2(gy, gx);
        const samples::FieldValue fv = field.evaluate(t.reference_px);
        std::fprintf(dump,
                     "%d,%ld,%d,%d,%.3f,%.3f,%.4f,%.4f,%.5f,%.5f,%.2f,%.2f,%.4f,%.4f,%.4f,%.5f,%.5f,%.5f,%."
                     "5f,%.5f,%.5f,%.5f,%.5f\n",
                     f, static_cast<long>(t.id), t.born_frame, static_cast<int>(t.status), X.x, X.y,
                     t.position_px.x, t.position_px.y, t.position_px.x - x_true.x, t.position_px.y - x_true.y,
                     trial.contact_signed_distance_px(t.position_px), stick_px, std::cos(ang), std::sin(ang),
                     t.zncc, t.gradient.xx, t.gradient.xy, t.gradient.yx, t.gradient.yy, fv.gradient.xx,
                     fv.gradient.xy, fv.gradient.yx, fv.gradient.yy);
      }
      s.max_px = std::max(s.max_px, e);
      if (e > 1.0) ++s.wrong;
      if (e > 2.0 && std::getenv("FLOW_DUMP_WRONG"))
        std::fprintf(stderr,
                     "frame %d id %ld born %d X %.1f %.1f x %.2f %.2f truth %.2f %.2f zncc %.3f status %d\n",
                     f, static_cast<long>(t.id), t.born_frame, t.reference_px.x, t.reference_px.y,
                     t.position_px.x, t.position_px.y, t.reference_px.x + u.x, t.reference_px.y + u.y, t.zncc,
                     static_cast<int>(t.status));
    }
    s.frame_alive[static_cast<std::size_t>(f)] = alive;
    if (alive > 0 && f > 0) s.frame_rms_px[static_cast<std::size_t>(f)] = std::sqrt(frame2 / alive);
    sum2 += frame2;
    if (f > 0) s.samples += alive;
    if (with_plate && f > 0 && tracker.plate_displacement_px()) {
      const Vec2 d = *tracker.plate_displacement_px();
      const Vec2 truth = trial.load(f).plate_px;
      const double e = std::hypot(d.x - truth.x, d.y - truth.y);
      plate2 += e * e;
      if (std::getenv("PLATE_VERBOSE"))
        std::fprintf(stderr, "plate frame %d d %.3f %.3f truth %.3f %.3f err %.3f\n", f, d.x, d.y, truth.x,
                     truth.y, e);
      s.plate_max_px = std::max(s.plate_max_px, e);
      ++plate_n;
    }
  }
  if (dump) {
    std::fclose(dump);
    int reasons[16] = {};
    for (const Track& t : tracker.tracks())
      if (!is_alive(t.status)) ++reasons[static_cast<int>(t.status) & 15];
    std::fprintf(stderr, "retired: left_contact %d, fb %d, poor %d, inconsistent %d, left_image %d\n",
                 reasons[10], reasons[11], reasons[12], reasons[13], reasons[14]);
  }
  s.rms_px = s.samples > 0 ? std::sqrt(sum2 / static_cast<double>(s.samples)) : 0.0;
  s.birth_rms_px = s.born > 0 ? std::sqrt(birth2 / s.born) : 0.0;
  s.plate_rms_px = plate_n > 0 ? std::sqrt(plate2 / plate_n) : 0.0;
  s.seconds = seconds;
  return s;
}

}  // namespace tirstrain::flow::testing
