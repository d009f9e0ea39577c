#pragma once
// Two repairs of the outline found along the rays, before its convex hull: noise spikes clipped, and dips
// where a ridge valley runs along the border bridged by an outer-envelope ellipse. `cut` marks the points
// on a cut (frame edge, excluded band): they lie where the view ends, and neither take part nor move.
#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace tirstrain::contact {

// Noise can carry a single ray's edge outward, and the convex hull keeps any outward excursion. Clip each
// free point's distance from `centre` to the median of its 11 neighbours (free ones) plus `spike_px`.
void clip_spikes(std::vector<cv::Point2d>& points, const std::vector<std::uint8_t>& cut,
                 const cv::Point2d& centre, double spike_px);

// Where a ridge valley lies along the border, the contact edge is invisible (a valley reflects like the
// background), so the outline found there dips inward by up to half a ridge period. Such dips are one-sided,
// which lets an outer-envelope ellipse find them: fit, drop points more than `gap_px` inside, refit (twice),
// and move the dropped points onto the ellipse along their ray from its centre. Points on a cut (frame edge,
// excluded band) neither take part nor move.
void bridge_valleys(std::vector<cv::Point2d>& points, const std::vector<std::uint8_t>& cut, double gap_px);

}  // namespace tirstrain::contact
