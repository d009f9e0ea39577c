#pragma once
// The contact ellipse from where ridges show near its border (the segmenter's centre,
// SegmenterOptions::ridge_label_centre).
//
// Where a ridge valley lies along the border, the border is invisible along that arc; where a ridge ends
// against it, the ridge's end marks it. The segmenter's level edge works from the crests, so along valley
// arcs it stops at the last crest, and the centre follows where the fingerprint happens to lie (0.2-3.6 px
// for one small contact, up to 2 px RMS on sliding large ones; BENCHMARKS.md, contact/). Here every pixel
// within 0.75 ridge period of an initial ellipse (on a large contact, those of a lattice a few px apart) is
// labelled:
//   inside  - the ridge signal (frame smoothed by a Gaussian of 1 px, against the local background) exceeds
//             in_sigmas;
//   outside - below out_sigmas, at most a quarter period inside, where the local plane wave of the ridges
//             (fitted just inside the border, per sector) predicts a ridge that would show at the border's
//             crest level;
//   neither - everything else (valleys, faint flanks).
// The ellipse then comes from those labels by one of two methods (RidgeLabelMethod): the logistic fit of its
// five parameters (signed distance over a transition of transition_px, Levenberg-Marquardt from the initial
// ellipse), where thousands of labels pin it where a few extracted ridge ends would not
// (pipeline/contact_observability.hpp measures what they allow); or per-sector brackets, which move the
// centre and correct the size and shape (elongation and its direction). The logistic fit's axes
// run ~2.5 px long (the soft edge's tail is labelled inside), and on a large contact it drifts outward along
// arcs where valleys run along the border; the segmenter uses it on small contacts and the brackets on large
// ones. From the logistic fit it takes the centre and half the shape (SegmenterOptions::
// ridge_label_shape_weight); from the brackets the centre, size and shape.
#include <opencv2/core.hpp>

#include <functional>
#include <optional>

#include "contact/ellipse.hpp"

namespace tirstrain::contact {

// How the labels set the ellipse. logistic: the ellipse's five parameters fitted to the labels. brackets: per
// sector, the border is placed midway between the outermost inside labels and the innermost outside labels
// (sectors with a wide gap between them weigh less); the centre (with a common radial offset) and, in a
// second fit, the border's cos 2 phi and sin 2 phi terms are fitted to those positions. The size comes from
// the sectors where ridges end at the border (a narrow gap), from their inside labels alone: the midway
// border lies ~2 px out there. The ellipse is `initial` moved to that centre and its border moved radially by
// the size change and those terms (the size is `initial`'s when too few sectors show ridge ends).
enum class RidgeLabelMethod { logistic, brackets };

// The border band's intensity fit (contact/border_band.hpp) on top of the labels: off; with_labels (brackets
// only): the centre is the mean of the brackets' and the band fit's; alone: the band fit's centre, no labels
// (for frames too noisy to label: the initial ellipse moved to it).
enum class BorderBandUse { off, with_labels, alone };

struct RidgeLabelOptions {
  RidgeLabelMethod method = RidgeLabelMethod::logistic;
  int sectors = 24;
  double in_sigmas = 4.0;
  double out_sigmas = 1.0;
  double min_sigma_crest_fraction =
      0.005;                    // the noise sigma is taken as at least this much of the crest level
  double visible_sigmas = 4.0;  // a predicted ridge counts only where it would show this clearly
  double predicted_cos = 0.3;   // ... and only on its crest side (cosine of the wave's phase); the brackets
                                // narrow it to the phase the sector's inside labels show, plus:
  double phase_margin_cos = 0.2;
  double transition_px = 1.5;
  double min_fit_fraction = 0.3;  // a sector's wave must explain this fraction of its window's variance
  int min_sectors = 12;           // sectors with a usable wave, else no fit
  int max_iterations = 20;
  double bracket_reach_px =
      1.0;                      // brackets: this far beyond the outermost inside labels, without outside ones
  double bracket_gap_px = 6.7;  // brackets: a sector whose inside and outside labels are this far apart
                                // counts half
  double bracket_prior_px =
      3.0;  // brackets: prior standard deviation of the centre's shift and the shape terms
  // brackets, the size: sectors whose inside and outside labels are at most bracket_size_gap_px apart (ridges
  // end at the border there) place it at their inside labels' bracket_size_quantile of t, when there are at
  // least bracket_size_min_sectors of them.
  double bracket_size_gap_px = 3.5;
  double bracket_size_quantile = 0.9;
  int bracket_size_min_sectors = 4;
  BorderBandUse border_band = BorderBandUse::off;
  // The band fit's pixels: those of the lattice from border_band_inner_periods inside the initial ellipse to
  // 0.75 period outside, every border_band_stride-th of them (border_band_alone_stride-th when alone: noisy
  // frames need more). With the labels every 6th gives the centres all of them do (within 0.05 px over 13
  // fingerprints) at a quarter of the cost; alone, on the noisy scenes, every 3rd is as good as all and every
  // 6th costs ~0.2 px on the worst frame.
  double border_band_inner_periods = 1.5;
  int border_band_stride = 6;
  int border_band_alone_stride = 3;
};

struct RidgeLabelFit {
  Ellipse ellipse;
  // brackets: the border's radial change r(phi) += shape_size_px + shape_cos2_px cos 2 phi + shape_sin2_px
  // sin 2 phi (phi about the centre, from +x towards +y), already in `ellipse`; 0 for the logistic fit.
  double shape_size_px = 0.0, shape_cos2_px = 0.0, shape_sin2_px = 0.0;
  int inside_labels = 0;
  int outside_labels = 0;
  int sectors_used = 0;
  bool border_band_used = false;  // the band fit set (or shared in) the centre
};

// `frame`: the full frame (CV_8UC1, CV_16UC1 or CV_32FC1), `full_scale` its full-scale value (1 for float);
// `initial` in frame pixels; `polarity` -1 when ridges in contact are darker than the background, +1
// brighter. `illumination` (optional): the background's level at a frame pixel (any scale), e.g. the
// segmenter's flat field; the pixels are divided by it so that vignetting does not tilt a sector's background
// across the labelled band. It must be smooth: it is evaluated at three points per row of the band and
// interpolated quadratically between them (exact for a quadratic surface). Nothing when the ellipse leaves
// the frame, too few sectors carry a ridge wave, or the fit fails.
std::optional<RidgeLabelFit> fit_ellipse_to_ridge_labels(
    const cv::Mat& frame, double full_scale, const Ellipse& initial, double period_px, int polarity,
    const RidgeLabelOptions& options = {},
    const std::function<double(double x_px, double y_px)>& illumination = {});

}  // namespace tirstrain::contact
