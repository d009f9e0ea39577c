#pragma once
// Which pixels a pass over a region needs when its readers sample every `stride`-th pixel: each reader's
// lattice is one class (x mod stride, y mod stride), and only the marked classes are computed.
#include <cstdint>
#include <vector>

namespace tirstrain::flow {

class PixelClasses {
 public:
  PixelClasses() = default;  // every pixel
  explicit PixelClasses(int stride)
      : stride_(stride < 1 ? 1 : stride), used_(static_cast<std::size_t>(stride_ * stride_), 0) {}
  void add(int x, int y) { used_[index(x, y)] = 1; }
  // Whether any marked class has pixels on row y.
  bool has_row(int y) const {
    if (used_.empty()) return true;
    for (int cx = 0; cx < stride_; ++cx)
      if (used_[index(cx, y)]) return true;
    return false;
  }
  // The one column class x mod stride marked on row y, or −1 when none or several are (or all pixels are).
  int single_column_class(int y) const {
    if (used_.empty()) return -1;
    int found = -1;
    for (int cx = 0; cx < stride_; ++cx) {
      if (!used_[index(cx, y)]) continue;
      if (found >= 0) return -1;
      found = cx;
    }
    return found;
  }
  bool has_class(int cx, int cy) const { return used_.empty() || used_[index(cx, cy)] != 0; }
  int stride() const { return stride_; }
  // Calls visit(x) for every pixel of row y in [x_begin, x_end) that belongs to a marked class, in order
  // per class (all pixels, in order, when every class is marked).
  template <class Visit>
  void for_each_in_row(int y, int x_begin, int x_end, Visit&& visit) const {
    if (used_.empty()) {
      for (int x = x_begin; x < x_end; ++x) visit(x);
      return;
    }
    for (int cx = 0; cx < stride_; ++cx) {
      if (!used_[index(cx, y)]) continue;
      const int first = x_begin + ((cx - x_begin) % stride_ + stride_) % stride_;
      for (int x = first; x < x_end; x += stride_) visit(x);
    }
  }

 private:
  std::size_t index(int x, int y) const {
    const int cx = ((x % stride_) + stride_) % stride_, cy = ((y % stride_) + stride_) % stride_;
    return static_cast<std::size_t>(cy * stride_ + cx);
  }
  int stride_ = 1;
  std::vector<std::uint8_t> used_;  // empty: all
};

}  // namespace tirstrain::flow
