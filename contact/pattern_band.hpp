#pragma once
// The band of the image that shows the pattern printed on the glass plate (a dense field of small dots),
// found from the image when the scene does not give it.
//
// What sets the band apart: it is a 2-D texture (dots) that fills a whole strip along one image edge, while
// the fingerprint is a 1-D texture (ridges) and the background is flat. The smaller eigenvalue of the
// structure tensor, lambda_min, is large only where the image varies in every direction: on the dots, and
// not on ridges (one direction) or on a flat background (none). Per edge, the median of lambda_min along each
// line parallel to that edge is a profile against the distance from the edge: the median needs more than half
// of a line to be dotted, which a full-length strip is and a fingertip contact or a corner object is not. A
// band is a run of lines from the edge whose level stands well above the level of the image's typical line;
// its inner boundary is where the profile falls to the geometric mean of the two levels. A fingertip whose
// contact fills an image edge also raises lambda_min there (its ridges curve and fork), so the band must
// also be isotropic: lambda_min a sizeable share of lambda_max, as on dots and never on ridges.
#include <opencv2/core.hpp>

#include <string>

namespace tirstrain::contact {

enum class ImageEdge { kNone, kTop, kBottom, kLeft, kRight };

// "top", "bottom", "left", "right" or "none".
std::string to_string(ImageEdge edge);

struct PatternBandOptions {
  // Gaussian smoothing before the gradients (px): pixel noise's lambda_min falls as sigma^-4 while that of
  // dots a few pixels wide falls far less (at 2 px the synthetic heavy-noise trial's band stands 34 times
  // above its noise, at 1 px 8 times).
  double presmooth_sigma_px = 2.0;
  // Integration scale of the structure tensor (px): a few dots' spacing would blur the inner boundary; this
  // spans about one dot spacing of the patterns seen (0.2 mm at 52 px/mm is 11 px).
  double integration_sigma_px = 3.0;
  // The band's level over the typical line's level: below min_contrast no band; the confidence reaches 1
  // at full_contrast (log scale between).
  double min_contrast = 4.0;
  double full_contrast = 40.0;
  // The band's level over what its own pixel noise would give (a strip that is only noisier than the rest,
  // e.g. brighter under shot noise, has contrast but no structure): likewise a minimum and a full score.
  double min_snr = 6.0;
  double full_snr = 60.0;
  // Share of the band's pixels above the boundary level: a band fills its strip.
  double min_fill = 0.7;
  // The band's median lambda_min / lambda_max: dots vary alike in every direction (about 0.4 on the printed
  // patterns seen), ridges in one (0.03-0.07, also a fingertip whose contact runs along an image edge).
  double min_isotropy = 0.15;
  // Width limits as fractions of the image's size across the edge, and in pixels.
  double max_width_fraction = 0.4;
  int min_width_px = 6;
  // The rectangle ends this far inside the boundary found (after rounding down): the boundary moves by about
  // +-2 px from frame to frame as the plate carries the dots it cuts, and a rectangle reaching past the band
  // would average the still background into the plate's motion (paper_camera_1280: 1 px past, plate error
  // +12 %), while one too far inside gives the plate fewer subsets (2 px: hard_heavy_noise +14 %; 1 px: every
  // shipped trial within 7 % of the scene's band).
  int inset_px = 1;
};

struct PatternBand {
  ImageEdge edge = ImageEdge::kNone;
  // The inner boundary's distance from the edge (px, sub-pixel); roi_px ends inset_px inside it, in whole
  // pixels, so that the plate is measured on pattern only.
  double width_px = 0.0;
  cv::Rect roi_px;  // empty when edge is kNone
  // How far past roi_px the band may reach: the inset plus the boundary's frame-to-frame scatter, what a
  // consumer that must leave out all of the band (contact segmentation) adds on the inner side.
  int margin_px = 0;
  double confidence = 0.0;  // 0..1; 0 with no band
  double contrast = 0.0;    // band level over the typical line's level (the best edge's, also when none)
  double snr = 0.0;         // band level over its pixel noise's
  double fill = 0.0;        // share of the band's pixels above the boundary level
  double isotropy = 0.0;    // median lambda_min / lambda_max over the band (0 until the fill passes)
};

// Finds the band in one frame (CV_8UC1, CV_16UC1 or CV_32FC1); kNone when no edge carries one. Throws Error
// for another image type.
PatternBand detect_pattern_band(const cv::Mat& image, const PatternBandOptions& options = {});

}  // namespace tirstrain::contact
