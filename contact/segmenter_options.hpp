#pragma once
// The contact segmentation's settings (contact/segmenter.hpp; docs/contact.md explains each step they tune)
// and the three presets that set its costly switches together.
#include <opencv2/core.hpp>

#include <optional>

namespace tirstrain::contact {

struct SegmenterOptions {
  // Frame pixels per mm on the glass, px/mm; > 0. Default 52.
  double px_per_mm = 52.0;
  // Fixed ridge period, frame px (> 0); unset (default): measured from the spectrum of the first frames that
  // show a clear ridge ring, default_period_mm used until then.
  std::optional<double> ridge_period_px;
  // Ridge period assumed until one is measured, mm; > 0. Default 0.45.
  double default_period_mm = 0.45;
  // Shortest ridge period the spectrum is searched for, mm; > 0. Default 0.25.
  double min_period_mm = 0.25;
  // Longest ridge period the spectrum is searched for, mm; > min_period_mm. Default 1.2.
  double max_period_mm = 1.2;
  // Spectral peak over its surroundings needed to accept a measured period (ratio, >= 0). Default 6.
  double min_period_confidence = 6.0;
  // Ridges in contact: -1 darker than the background, +1 brighter, 0 measured per frame (default).
  int polarity = 0;
  // Working-resolution factor f (frame px per working px, >= 0): 0 automatic, floor(period / 5.5 px)
  // (default); 1 full resolution.
  int downsample = 0;
  // Points along the reported hull's perimeter (hull_px), >= 3. Default 50.
  int hull_points = 50;
  // Side of the ridge orientation blocks, frame px; >= 1. Default 32.
  int block_px = 32;
  // Whether the ridge orientation field is computed (orientation_rad, coherence). Default true.
  bool orientation = true;
  // Frame pixels never taken as contact (e.g. the reference pattern band on the glass), px; width and
  // height >= 0. Default: none.
  std::optional<cv::Rect> exclude_px;
  // Smaller textured regions are noise, not contact, mm^2; >= 0. Default 0.5.
  double min_area_mm2 = 0.5;
  // Texture energy inside over outside needed to call it contact (ratio, >= 0). Default 3.
  double min_energy_ratio = 3.0;
  // Texture energy inside needed to call it contact, fraction of full scale; >= 0. Default 0.003.
  double min_energy = 0.003;
  // A region joins the largest one when it is at least merge_fraction of its area (>= 0; default 0.1) and no
  // further from it than merge_gap_periods ridge periods (>= 0; default 2). One fingertip makes one contact:
  // what splits it (a dry or wet patch, a faint stretch of border) leaves gaps of a ridge period or so, while
  // another textured thing in view (a patterned band on the glass, an object at the image's edge) lies apart.
  double merge_fraction = 0.1;
  double merge_gap_periods = 2.0;
  // Fraction of the frame's pixels at full scale from which it is flagged saturated, in [0, 1]. Default 0.02.
  double saturated_fraction = 0.02;
  // Whether the level edge is searched on the frame divided by a quadratic surface fitted to the background
  // around the contact (vignetting, the light's tilt). Without it, grey closing flattens a background that
  // rises outward next to the contact, which puts the edge too far in wherever the ridge contrast is small
  // against that slope (docs/contact.md, "Flat field"). Default true.
  bool flat_field = true;
  // Texture SNR (band-pass envelope inside the contact over the background's pixel noise, the noise scaled to
  // the automatic working resolution) below which the ridges-bright image is averaged along the border over
  // border_average_periods ridge periods before the edge search: ridges near the border run along it, so its
  // profile across the border is kept while the noise that hides the faint outermost crest drops.
  // border_average_snr: ratio, >= 0 (0: never), default 20; border_average_periods: ridge periods, >= 0,
  // default 0.7.
  double border_average_snr = 20.0;
  double border_average_periods = 0.7;
  // The outline is where the merged ridge level falls to crest_edge_level of the way from the background to
  // the outermost crest (ridge contrast fades towards the border where skin only nearly touches, so that
  // crest is fainter than the contact's plateau). Below one half, because where a valley runs along the
  // border the edge lies somewhere in that valley, beyond the crest's flank. Rays that cannot see that crest
  // clearly (window leaving the view, crest lost in noise) use edge_level of the way to the plateau. Both
  // fractions in [0, 1]; defaults 0.18 and 0.14.
  double crest_edge_level = 0.18;
  double edge_level = 0.14;
  // Outline dips deeper than this inside the outer-envelope ellipse are valleys along the border and are
  // bridged by the ellipse (contact/outline_repair.hpp), ridge periods; >= 0. Default 0.1.
  double valley_gap_periods = 0.1;
  // A single ray's edge further out than the median of its neighbours by more than this is a noise spike
  // and is clipped back (contact/outline_repair.hpp), ridge periods; >= 0. Default 0.1.
  double spike_periods = 0.1;
  // With automatic resolution, a contact whose equivalent radius is below this many ridge periods is
  // segmented again at half the working factor (about 11 working pixels per period); >= 0. Default 3.
  double small_contact_periods = 3.0;
  // The centre from where ridges show near the border (contact/ridge_labels.hpp): the outline is moved so
  // that the ellipse's centre is the one the ridge labels give. The level edge works from the crests, so
  // where a ridge valley runs along the border it stops at the last crest, and the centre follows where the
  // fingerprint happens to lie. Contacts whose equivalent radius sqrt(a b) is under
  // ridge_label_below_periods ridge periods (>= 0, 0: none; default 5) get the logistic ellipse fit to the
  // labels; larger ones, when ridge_label_centre (default true), the per-sector brackets (there the logistic
  // fit drifts outward along valley arcs). The brackets also give the outline's size (from the sectors where
  // ridges end at the border) and its shape (the border's cos 2 phi and sin 2 phi terms). Never applied when
  // the contact touches the frame's edge, the frame is saturated or was averaged along the border (the
  // labels would be clipped or noise-limited), or the shift would exceed half a ridge period. What each
  // gains and costs: BENCHMARKS.md, contact/.
  double ridge_label_below_periods = 5.0;
  bool ridge_label_centre = true;
  // Small contacts (the logistic fit): the ellipse's elongation and its direction are this weight of the
  // fit's, the rest the level edge's; the size stays the level edge's (the fit's axes run ~2.5 px long). Each
  // errs by where the fingerprint's valleys lie along the border, partly independently, so the blend errs
  // less than either. In [0, 1] (0: the level edge's shape); default 0.5.
  double ridge_label_shape_weight = 0.5;
  // Small contacts (under ridge_label_below_periods in radius, not touching the frame's edge): the reported
  // outline (hull_px, outline_px, area) is the ellipse's. Between the ridges the border is only bridged,
  // so the traced outline carries lobes of a few ridge periods whose size (~1 px) is, on a contact of a few
  // periods, larger than the contact's own departure from its ellipse; the ellipse averages them over the
  // whole border. Default true.
  bool small_contact_ellipse_outline = true;
  // The border band's intensity fit (contact/border_band.hpp) for large contacts, with ridge_label_centre:
  // the centre becomes the mean of the brackets' and the fit's, and on frames averaged along the border (too
  // noisy for labels) the fit's alone. The accuracy targets hold on every shipped trial only with it; it
  // costs ~2 ms a frame (BENCHMARKS.md, contact/). SegmentationPreset::balanced turns it off. Default true.
  bool border_band_centre = true;
  // Texture energy (about 0.6 x the ridge amplitude) below which the frame is flagged low contrast (kept,
  // less sure), fraction of full scale; >= 0. Default 0.02.
  double low_contrast = 0.02;
  // Region tracking: after a frame with a contact, the next frames are segmented only around it (its
  // bounding box grown by the larger of region_margin_periods ridge periods (>= 0; default 4) and
  // region_margin_fraction of its size (>= 0; default 0.15), when that is at most 60 % of the frame); a whole
  // frame again every full_frame_every frames (>= 1; default 10), when a new region elsewhere is seen, and
  // at once when the contact is lost or reaches the region's side. track_region: default true.
  bool track_region = true;
  int full_frame_every = 10;
  double region_margin_periods = 4.0;
  double region_margin_fraction = 0.15;

  // Throws tirstrain::Error naming the first field out of the ranges above (and its value).
  void check() const;
};

// Three settings of the costly switches by what they cost and give (BENCHMARKS.md, contact/: 1280x1024, the
// 19 shipped synthetic trials, worst frame):
//   accurate (the defaults): ~4.2 ms a frame, centre 0.93 px, semi-axes 2.0 %, IoU 0.956;
//   balanced: the border band off: ~2.0 ms, centre 1.11 px, semi-axes 2.0 %;
//   fast: the flat field, the border averaging, the ridge labels and the band off: ~1.1 ms, centre 2.5 px,
//         semi-axes 3.5 % (the default scene's IoU 0.975).
enum class SegmentationPreset { fast, balanced, accurate };

// `options` with the preset's switches (flat_field, border_average_snr, ridge_label_centre,
// ridge_label_below_periods, ridge_label_shape_weight, border_band_centre) set; everything else kept.
SegmenterOptions with_preset(SegmenterOptions options, SegmentationPreset preset);

}  // namespace tirstrain::contact
