#include "contact/level_edge.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "contact/image_stats.hpp"
#include "contact/texture_regions.hpp"

namespace tirstrain::contact {
namespace {

// Inlined: the edge search calls it ~100 times per ray, and a call out of line costs a fifth of the search.
[[gnu::always_inline]] inline float bilinear(const cv::Mat& image, double x, double y) {
  x = std::clamp(x, 0.0, image.cols - 1.0);
  y = std::clamp(y, 0.0, image.rows - 1.0);
  const int x0 = std::min(static_cast<int>(x), image.cols - 2),
            y0 = std::min(static_cast<int>(y), image.rows - 2);
  const double fx = x - x0, fy = y - y0;
  const float* r0 = image.ptr<float>(y0);
  const float* r1 = image.ptr<float>(y0 + 1);
  return static_cast<float>((1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) +
                            fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]));
}

constexpr double kRayStep = 0.25;  // working pixels between samples along a ray

// Where the texture energy along the ray falls through the threshold, from 1.5 px inside `p` to 2.5 px
// beyond it (0: no crossing there).
double energy_crossing(const EdgeSearch& search, cv::Point2d p, cv::Point2d dir) {
  double crossing = 0.0;
  double prev_s = -1.5;
  float prev_e = bilinear(*search.energy, p.x + prev_s * dir.x, p.y + prev_s * dir.y);
  for (double s = prev_s + kRayStep; s <= 2.5 + 1e-9; s += kRayStep) {
    const float e = bilinear(*search.energy, p.x + s * dir.x, p.y + s * dir.y);
    if (prev_e > search.threshold && e <= search.threshold) {
      crossing = prev_s + kRayStep * (prev_e - search.threshold) / std::max(1e-12f, prev_e - e);
      break;
    }
    prev_s = s;
    prev_e = e;
  }
  return crossing;
}

// The merged level along the ray over crossing +- reach_w into `ray`: the plateau's highest value inside
// the crossing (and where), the background's mean over the last working pixel.
struct RayLevels {
  int samples = 0, peak = 0;
  double inside = -1e30, outside = 0.0;
};

RayLevels sample_levels(const EdgeSearch& search, cv::Point2d p, cv::Point2d dir, double crossing,
                        std::vector<float>& ray) {
  RayLevels levels;
  const double reach_w = search.reach_w;
  levels.samples = static_cast<int>(std::lround(2.0 * reach_w / kRayStep)) + 1;
  int outside_n = 0;
  ray.resize(static_cast<std::size_t>(levels.samples));
  for (int k = 0; k < levels.samples; ++k) {
    const double s = crossing - reach_w + k * kRayStep;
    const float v = bilinear(search.images->level, p.x + s * dir.x, p.y + s * dir.y);
    ray[static_cast<std::size_t>(k)] = v;
    if (s <= crossing && v > levels.inside) {
      levels.inside = v;
      levels.peak = k;
    }
    if (s >= crossing + reach_w - 1.0) {
      levels.outside += v;
      ++outside_n;
    }
  }
  levels.outside /= std::max(1, outside_n);
  return levels;
}

// Pixel noise beyond the edge, from the unmerged ridges-bright image over the outer half of the window: the
// levels must stand clear of it, or a faint crest is lost in the background.
double noise_beyond(const EdgeSearch& search, cv::Point2d p, cv::Point2d dir, double crossing) {
  double noise_sum = 0.0, noise_sum2 = 0.0;
  int noise_n = 0;
  for (double s = crossing + 0.5 * search.reach_w; s <= crossing + search.reach_w + 1e-9; s += kRayStep) {
    const double v = bilinear(search.images->bright, p.x + s * dir.x, p.y + s * dir.y);
    noise_sum += v;
    noise_sum2 += v * v;
    ++noise_n;
  }
  const double noise_mean = noise_sum / std::max(1, noise_n);
  return std::sqrt(std::max(0.0, noise_sum2 / std::max(1, noise_n) - noise_mean * noise_mean));
}

// The level edge along one ray, as a distance from `p` (working pixels), or `crossing` when the ray shows
// no clear step. Local levels: the merged crest plateau inside, the background beyond; local, so vignetting
// and illumination drift do not move it.
double level_crossing(const EdgeSearch& search, const RegionView& view, cv::Point2d p, cv::Point2d dir,
                      double crossing, std::vector<float>& ray) {
  const double reach_w = search.reach_w;
  const RayLevels levels = sample_levels(search, p, dir, crossing, ray);
  const double noise = noise_beyond(search, p, dir, crossing);
  const double inside = levels.inside, outside = levels.outside;
  if (!(inside - outside >= search.setup->level_drop_min)) return crossing;
  // Ridge contrast fades towards the border, so the outermost crest is fainter than the plateau and a level
  // relative to the plateau cuts it well inside the edge. Measure that crest instead: find where the merged
  // level is nearly down to the background (5 % of the plateau, clear of the noise); the outermost crest lies
  // within half a period inside that point, and the merged level there is its height. Rays whose window
  // leaves the view keep the plateau.
  int from = levels.peak;
  double top = inside, fraction = search.edge_level;
  const cv::Point2d a = p + (crossing - reach_w) * dir, b = p + (crossing + reach_w) * dir;
  const bool in_view = std::min({a.x, a.y, b.x, b.y}) >= 0.0 &&
                       std::max(a.x, b.x) <= view.size_w.width - 1.0 &&
                       std::max(a.y, b.y) <= view.size_w.height - 1.0;
  if (in_view) {
    const double nearly_out = outside + std::max(0.05 * (inside - outside), 3.0 * noise);
    for (int k = levels.peak + 1; k < levels.samples; ++k)
      if (ray[static_cast<std::size_t>(k)] < nearly_out) {
        from = std::max(levels.peak, k - static_cast<int>(std::lround(0.5 * search.period_w / kRayStep)));
        top = ray[static_cast<std::size_t>(from)];
        fraction = search.crest_edge_level;
        break;
      }
  }
  const double level = outside + std::max(fraction * (top - outside), 2.0 * noise);
  for (int k = from + 1; k < levels.samples; ++k) {
    const float v0 = ray[static_cast<std::size_t>(k - 1)], v1 = ray[static_cast<std::size_t>(k)];
    if (v0 >= level && v1 < level)
      return crossing - reach_w + (k - 1 + (v0 - level) / std::max(1e-12f, v0 - v1)) * kRayStep;
  }
  return crossing;
}

// The refined outline point (working pixels) on the ray from `centroid_w` through `p`.
cv::Point2d edge_on_ray(const EdgeSearch& search, const RegionView& view, cv::Point2d p,
                        cv::Point2d centroid_w, std::vector<float>& ray) {
  cv::Point2d dir = p - centroid_w;
  const double length = cv::norm(dir);
  if (!(length > 1e-9)) return p;
  dir *= 1.0 / length;
  double crossing = energy_crossing(search, p, dir);
  if (search.setup->use_level_edge) crossing = level_crossing(search, view, p, dir, crossing, ray);
  return p + crossing * dir;
}

}  // namespace

bool RegionView::on_cut(const cv::Point2d& p) const {
  if ((frame_left && near_left(p)) || (frame_top && near_top(p)) || (frame_right && near_right(p)) ||
      (frame_bottom && near_bottom(p)))
    return true;
  if (excluded_w.area() > 0) {
    const cv::Rect grown(excluded_w.x - 2, excluded_w.y - 2, excluded_w.width + 4, excluded_w.height + 4);
    return grown.contains(cv::Point(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y))));
  }
  return false;
}

bool RegionView::leaves_region(const cv::Point2d& p) const {
  return (!frame_left && near_left(p)) || (!frame_top && near_top(p)) || (!frame_right && near_right(p)) ||
         (!frame_bottom && near_bottom(p));
}

// Ridges near the contact border run along it, so averaging along the border keeps their profile across it
// while the pixel noise drops by up to sqrt(2 half_taps + 1). "Along the border" is along the ellipse
// through the pixel that is concentric with and similar to `shape` (2 half_taps + 1 samples about one pixel
// apart). Only pixels within `band_px` of `shape` (in its normalised radius) are averaged, the others copied:
// the edge search and the closing before it look no further. Never closer to the centre than 0.3 of the
// radius: there the arcs are short and, at the centre itself, undefined.
void average_along_border(const cv::Mat& src, const Ellipse& shape, int half_taps, double band_px,
                          cv::Mat& dst) {
  dst.create(src.size(), CV_32F);
  const double c = std::cos(shape.angle_rad), s = std::sin(shape.angle_rad);
  const double a = shape.semi_major_px, b = shape.semi_minor_px;
  const double rho_min = std::max(0.3, 1.0 - band_px / b), rho_max = 1.0 + band_px / b;
  const double inv_taps = 1.0 / (2 * half_taps + 1);
  for (int y = 0; y < src.rows; ++y) {
    float* out = dst.ptr<float>(y);
    const float* in = src.ptr<float>(y);
    for (int x = 0; x < src.cols; ++x) {
      const double dx = x - shape.cx_px, dy = y - shape.cy_px;
      const double nx = (c * dx + s * dy) / a, ny = (-s * dx + c * dy) / b;
      const double rho2 = nx * nx + ny * ny;
      if (rho2 < rho_min * rho_min || rho2 > rho_max * rho_max) {
        out[x] = in[x];
        continue;
      }
      const double rho = std::sqrt(rho2);
      const double cos_phi = nx / rho, sin_phi = ny / rho;
      // One pixel of arc: |d(a cos, b sin)/dphi| = sqrt(a^2 sin^2 + b^2 cos^2) per unit phi at rho = 1. Below
      // 0.2 rad (the usual case) two Taylor terms are exact to 1e-5; small contacts near rho_min take more.
      const double step = 1.0 / (rho * std::sqrt(a * a * sin_phi * sin_phi + b * b * cos_phi * cos_phi));
      const double cs = step < 0.2 ? 1.0 - 0.5 * step * step : std::cos(step);
      const double sn = step < 0.2 ? step * (1.0 - step * step / 6.0) : std::sin(step);
      double sum = in[x];
      for (int side = -1; side <= 1; side += 2) {
        double u = cos_phi, v = sin_phi;
        for (int j = 1; j <= half_taps; ++j) {
          const double un = u * cs - side * v * sn, vn = v * cs + side * u * sn;
          u = un;
          v = vn;
          const double ex = rho * a * u, ey = rho * b * v;
          sum += bilinear(src, shape.cx_px + c * ex - s * ey, shape.cy_px + s * ex + c * ey);
        }
      }
      out[x] = static_cast<float>(sum * inv_taps);
    }
  }
}

LevelEdgeSetup prepare_level_edge(const CoarseContact& contact, const RegionView& view, double period_px,
                                  double reach_w, const SegmenterOptions& options, LevelImages& images,
                                  cv::Mat& mask_scratch) {
  LevelEdgeSetup setup;
  if (contact.polarity == 0) return setup;
  const cv::Mat& work = *contact.work;
  const int f = view.factor;
  const double period_w = period_px / f;
  if (options.flat_field) {
    // The background around the contact: clear of it by the rays' reach and a period, outside the excluded
    // band.
    const int grow = odd_at_least(2.0 * (reach_w + period_w) + 1.0, 3);
    cv::dilate(*contact.hull_mask, mask_scratch,
               cv::getStructuringElement(cv::MORPH_RECT, cv::Size(grow, grow)));
    if (view.excluded_w.area() > 0) mask_scratch(view.excluded_w).setTo(1);
    // At least 1/40 of the frame, sampled every 3rd pixel each way.
    setup.background = fit_background(work, mask_scratch, contact.centroid_w,
                                      std::max(64, static_cast<int>(work.total() / 360)));
  }
  if (setup.background) {
    flatten(work, *setup.background, contact.polarity, images.bright);
    // Pixel noise as it would be at the automatic working resolution (5.5 pixels per ridge period; block
    // averaging over f x f divides white noise by f), so the decision does not depend on the resolution.
    const double reference_factor = std::max(1.0, period_px / 5.5);
    const double noise = setup.background->residual_rms * f / reference_factor;
    setup.texture_snr = noise > 0.0 ? std::min(contact.texture_energy / noise, 1e9) : 1e9;
  } else if (contact.polarity < 0) {
    cv::subtract(1.0, work, images.bright);
  } else {
    work.copyTo(images.bright);
  }
  const int half_taps = static_cast<int>(std::lround(0.5 * options.border_average_periods * period_w));
  if (setup.background && setup.texture_snr < options.border_average_snr && half_taps > 0) {
    // The coarse hull is within a pixel or two of the edge; the rays look 1.5 periods either side of it and
    // the closing one period further.
    const std::optional<Ellipse> shape = fit_ellipse_direct(*contact.hull_w);
    if (shape && shape->semi_minor_px >= 5.0) {
      average_along_border(images.bright, *shape, half_taps, reach_w + period_w + 2.0, images.scratch);
      std::swap(images.bright, images.scratch);
      setup.border_averaged = true;
    }
  }
  // Grey closing over one period merges ridges and valleys into a plateau at crest level (and keeps its
  // outer edge); opening over half a period removes specks.
  close_then_open(images.bright, odd_at_least(period_w + 1.0, 3), odd_at_least(0.5 * period_w, 3),
                  images.scratch, images.level);
  const MaskedMeans means = masked_means(images.level, *contact.hull_mask);
  if (means.inside_count > 0 && means.outside_count > 0) {
    // A step must carry a fair part of the contrast between the contact and the background to count.
    setup.level_drop_min = 0.25 * (means.inside - means.outside);
  }
  setup.use_level_edge = setup.level_drop_min > 0.0;
  return setup;
}

RefinedOutline refine_outline(const std::vector<cv::Point2d>& samples_w, cv::Point2d centroid_w,
                              const RegionView& view, const EdgeSearch& search, std::vector<float>& ray) {
  RefinedOutline outline;
  outline.points_px.reserve(samples_w.size());
  for (const auto& p : samples_w) {
    if (view.leaves_region(p)) outline.left_region = true;
    const bool at_cut = view.on_cut(p);
    cv::Point2d q = view.to_frame(at_cut ? p : edge_on_ray(search, view, p, centroid_w, ray));
    if (at_cut) {
      // Push cut points onto the frame edge (or the excluded band), so the area counts the visible contact.
      if (view.frame_left && view.near_left(p)) q.x = -0.5;
      if (view.frame_top && view.near_top(p)) q.y = -0.5;
      if (view.frame_right && view.near_right(p)) q.x = view.frame_size.width - 0.5;
      if (view.frame_bottom && view.near_bottom(p)) q.y = view.frame_size.height - 0.5;
      outline.touches_edge = true;
    }
    q.x = std::clamp(q.x, -0.5, view.frame_size.width - 0.5);
    q.y = std::clamp(q.y, -0.5, view.frame_size.height - 0.5);
    outline.points_px.push_back(q);
    outline.cut.push_back(at_cut ? 1 : 0);
  }
  return outline;
}

}  // namespace tirstrain::contact
