#pragma once
// NumPy <-> C++ helpers shared by the binding files: new arrays, image views on NumPy buffers (no copy) and
// argument checks that raise tirstrain.Error like the CLI's messages.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace tirstrain::python {

namespace py = pybind11;

// Read-only double input, converted only when it is not already C-contiguous float64.
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// A C-ordered array of the given shape, uninitialised.
template <typename T>
py::array_t<T> new_array(const std::vector<py::ssize_t>& shape) {
  return py::array_t<T>(shape);
}

// A NumPy image and the cv::Mat header on its buffer. `owner` keeps the buffer alive (it is the caller's
// array, or a contiguous copy when the rows were not contiguous).
struct ImageView {
  py::array owner;
  cv::Mat mat;
};

// A 2-D uint8, uint16 or float32 array as a cv::Mat without copying; throws Error naming `what` otherwise.
ImageView image_view(const py::handle& image, const std::string& what);

// The elements of a 1-D array (the signals functions take std::vector).
std::vector<double> to_vector(const DoubleArray& x, const std::string& what);

// A 1-D float64 array holding `values`.
py::array_t<double> to_array(const std::vector<double>& values);

}  // namespace tirstrain::python
