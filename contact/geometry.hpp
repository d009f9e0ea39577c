#pragma once
// Polygon helpers for contact outlines (image coordinates, pixels).
#include <opencv2/core.hpp>

#include <vector>

namespace tirstrain::contact {

// `count` points equally spaced along the closed polygon's perimeter, the first at vertex 0.
std::vector<cv::Point2d> resample_closed_polygon(const std::vector<cv::Point2d>& polygon, int count);

// Convex hull (counter-clockwise on screen is not guaranteed; orientation follows cv::convexHull).
std::vector<cv::Point2d> convex_hull(const std::vector<cv::Point2d>& points);

// Shoelace area (absolute) in px^2.
double polygon_area_px2(const std::vector<cv::Point2d>& polygon);

// A filled polygon as a CV_8UC1 mask of `size` (255 inside), rasterised with sub-pixel vertices: a pixel is
// inside when its centre is.
cv::Mat rasterize_polygon(const std::vector<cv::Point2d>& polygon, cv::Size size);

// Intersection over union of two binary masks (non-zero = inside); 1 when both are empty.
double mask_iou(const cv::Mat& a, const cv::Mat& b);

}  // namespace tirstrain::contact
