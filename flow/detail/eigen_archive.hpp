#pragma once
// Eigen matrices in a checkpoint (core/archive.hpp): their size, then their coefficients.
#include <Eigen/Core>

#include <cstdint>

#include "core/archive.hpp"
#include "core/error.hpp"

namespace tirstrain {

template <typename S, int R, int C, int O, int MR, int MC>
void archive(Archive& a, Eigen::Matrix<S, R, C, O, MR, MC>& m) {
  std::int64_t size[2] = {m.rows(), m.cols()};
  a.raw(size, sizeof size);
  if (a.reading()) {
    if constexpr (R == Eigen::Dynamic || C == Eigen::Dynamic) {
      m.resize(size[0], size[1]);
    } else if (size[0] != R || size[1] != C) {
      throw Error("the checkpoint holds a matrix of another size");
    }
  }
  if (m.size() > 0) a.raw(m.data(), static_cast<std::size_t>(m.size()) * sizeof(S));
}

}  // namespace tirstrain
