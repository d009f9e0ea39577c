#include "flow/mask_erosion.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdint>
#include <optional>
#include <vector>

#include "flow/subset.hpp"

namespace tirstrain::flow {

namespace {

// erode_for_matching's reach: its 5 × 5 element.
constexpr int kKernelReachPx = 2;

// The elliptic element's row half-widths, read off OpenCV's own element so that the two agree exactly; −1
// for an empty element row.
std::vector<int> element_half_widths(int r) {
  const cv::Mat element = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
  std::vector<int> half(static_cast<std::size_t>(2 * r + 1), -1);
  for (int i = 0; i <= 2 * r; ++i) {
    const std::uint8_t* e = element.ptr<std::uint8_t>(i);
    int first = -1, last = -1;
    for (int j = 0; j <= 2 * r; ++j)
      if (e[j]) {
        if (first < 0) first = j;
        last = j;
      }
    if (first >= 0) {
      CV_Assert(r - first == last - r);  // symmetric about the anchor
      half[static_cast<std::size_t>(i)] = r - first;
    }
  }
  return half;
}

// Per row: the extent of its set pixels [first, last], and one run of pixels whose reach is full (at least
// r + 1 set pixels on both sides) as [deep_first, deep_last]: the longest such run, so that an interior pixel
// of a convex contact is known to survive without testing it.
struct RowExtents {
  std::vector<int> first, last, deep_first, deep_last;
};

// reach(y, x) = min(L, R), L and R the runs of set pixels in row y from x leftwards and rightwards (x
// included; 0 where x is unset), capped at r + 2: the row's pixels [x − w, x + w] are all set iff
// reach ≥ w + 1.
RowExtents row_reach(const cv::Mat& mask, int r, cv::Mat& reach) {
  const int rows = mask.rows, cols = mask.cols, cap = r + 1, top = cap + 1;
  reach.create(rows, cols, CV_8U);
  RowExtents extents;
  for (std::vector<int>* v : {&extents.first, &extents.last, &extents.deep_first, &extents.deep_last})
    v->resize(static_cast<std::size_t>(rows));
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    std::uint8_t* out_row = reach.ptr<std::uint8_t>(y);
    std::fill(out_row, out_row + cols, std::uint8_t{0});
    int f = cols, l = -1, best_first = 0, best_last = -1;
    // Run by run: reach(x) = min(x − s + 1, e − x + 1, cap + 1) on a run [s, e] of set pixels, a ramp up,
    // a plateau and a ramp down.
    for (int x = 0; x < cols;) {
      while (x < cols && m[x] == 0) ++x;
      if (x == cols) break;
      const int s0 = x;
      while (x < cols && m[x] != 0) ++x;
      const int e = x - 1, length = e - s0 + 1;
      if (f == cols) f = s0;
      l = e;
      std::uint8_t* run = out_row + s0;
      if (length >= 2 * top) {
        for (int k = 0; k < top; ++k) run[k] = run[length - 1 - k] = static_cast<std::uint8_t>(k + 1);
        std::fill(run + top, run + length - top, static_cast<std::uint8_t>(top));
      } else {
        for (int k = 0; k < length; ++k)
          run[k] = static_cast<std::uint8_t>(std::min({k + 1, length - k, top}));
      }
      const int deep_s = s0 + cap - 1, deep_e = e - cap + 1;
      if (deep_e >= deep_s && deep_e - deep_s > best_last - best_first)
        best_first = deep_s, best_last = deep_e;
    }
    const auto k = static_cast<std::size_t>(y);
    extents.first[k] = f, extents.last[k] = l, extents.deep_first[k] = best_first,
    extents.deep_last[k] = best_last;
  }
  return extents;
}

// The columns of output row y the element can fit in at all, [lo, hi] (hi < lo: none), and those where it
// fits without a test, [deep_lo, deep_hi], from every element row's extents.
struct RowSpan {
  int lo, hi, deep_lo, deep_hi;
};
std::optional<RowSpan> candidate_span(const RowExtents& extents, const std::vector<int>& half, int y,
                                      int rows, int cols) {
  const int r = static_cast<int>(half.size() / 2);
  RowSpan span{0, cols - 1, 0, cols - 1};
  for (int i = 0; i <= 2 * r; ++i) {
    if (half[static_cast<std::size_t>(i)] < 0) continue;
    const int yy = y + i - r;
    if (yy < 0 || yy >= rows) return std::nullopt;  // the border is 0
    const auto k = static_cast<std::size_t>(yy);
    span.lo = std::max(span.lo, extents.first[k]);
    span.hi = std::min(span.hi, extents.last[k]);
    span.deep_lo = std::max(span.deep_lo, extents.deep_first[k]);
    span.deep_hi = std::min(span.deep_hi, extents.deep_last[k]);
  }
  if (span.hi < span.lo) return std::nullopt;
  if (span.deep_hi < span.deep_lo) {
    span.deep_lo = span.hi + 1;
    span.deep_hi = span.hi;
  }
  span.deep_lo = std::max(span.deep_lo, span.lo);
  span.deep_hi = std::min(span.deep_hi, span.hi);
  return span;
}

}  // namespace

void erode_ellipse(const cv::Mat& mask, int radius_px, cv::Mat& out) {
  CV_Assert(mask.type() == CV_8U && radius_px >= 0 && radius_px <= 250);
  out.create(mask.size(), CV_8U);
  CV_Assert(out.data != mask.data);
  if (radius_px == 0) {
    mask.copyTo(out);
    return;
  }
  const int r = radius_px, rows = mask.rows, cols = mask.cols;
  const std::vector<int> half = element_half_widths(r);
  cv::Mat reach;
  const RowExtents extents = row_reach(mask, r, reach);
  std::vector<std::uint8_t> keep(static_cast<std::size_t>(cols));
  // keep[x] for x in [x0, x1]: every element row's reach covers its half-width.
  const auto test = [&](int y, int x0, int x1) {
    if (x1 < x0) return;
    std::uint8_t* k = keep.data();
    std::fill(k + x0, k + x1 + 1, std::uint8_t{1});
    for (int i = 0; i <= 2 * r; ++i) {
      const int w = half[static_cast<std::size_t>(i)];
      if (w < 0) continue;
      const std::uint8_t* row = reach.ptr<std::uint8_t>(y + i - r);
      const auto need = static_cast<std::uint8_t>(w + 1);
      for (int x = x0; x <= x1; ++x) k[x] = static_cast<std::uint8_t>(k[x] & (row[x] >= need ? 1 : 0));
    }
  };
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    std::uint8_t* o = out.ptr<std::uint8_t>(y);
    std::fill(o, o + cols, std::uint8_t{0});
    const std::optional<RowSpan> span = candidate_span(extents, half, y, rows, cols);
    if (!span) continue;
    // Within every row's full-reach run the element fits at once; the rest of [lo, hi] is tested.
    test(y, span->lo, span->deep_lo - 1);
    test(y, span->deep_hi + 1, span->hi);
    for (int x = span->lo; x <= span->hi; ++x) {
      const bool survives = (x >= span->deep_lo && x <= span->deep_hi) || keep[static_cast<std::size_t>(x)];
      o[x] = survives ? m[x] : std::uint8_t{0};
    }
  }
}

void erode_contact_for_matching(const cv::Mat& mask, cv::Rect box, int exclusion_px,
                                MatchMaskScratch& scratch, cv::Mat& out) {
  const cv::Rect image(0, 0, mask.cols, mask.rows);
  CV_Assert(box == (box & image) && out.size() == box.size() && out.type() == CV_8U);
  if (box.area() == 0) return;
  const int e = std::max(0, exclusion_px);
  // Beyond the image's edge the contact is taken to go on (the edge pixels repeated), far enough that
  // neither erosion reaches back into the image from the padding's own border.
  const int pad = e + kKernelReachPx + 1;
  const int left = box.x == 0 ? pad : 0, top = box.y == 0 ? pad : 0;
  const int right = box.br().x == image.width ? pad : 0, bottom = box.br().y == image.height ? pad : 0;
  cv::copyMakeBorder(mask(box), scratch.padded, top, bottom, left, right, cv::BORDER_REPLICATE);
  erode_for_matching(scratch.padded, scratch.eroded);
  erode_ellipse(scratch.eroded, e, scratch.padded);
  scratch.padded(cv::Rect(left, top, box.width, box.height)).copyTo(out);
  // The kernel still needs its reach of real pixels inside the image's edge.
  const int k = kKernelReachPx;
  const cv::Rect strips[] = {{0, 0, image.width, k},
                             {0, image.height - k, image.width, k},
                             {0, 0, k, image.height},
                             {image.width - k, 0, k, image.height}};
  for (const cv::Rect& strip : strips) {
    const cv::Rect hit = strip & box;
    if (hit.area() > 0) out(hit - box.tl()).setTo(0);
  }
}

}  // namespace tirstrain::flow
