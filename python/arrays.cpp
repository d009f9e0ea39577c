#include "python/arrays.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"

namespace tirstrain::python {

namespace {

int cv_type_of(const py::dtype& dtype) {
  if (dtype.is(py::dtype::of<std::uint8_t>())) return CV_8U;
  if (dtype.is(py::dtype::of<std::uint16_t>())) return CV_16U;
  if (dtype.is(py::dtype::of<float>())) return CV_32F;
  return -1;
}

}  // namespace

ImageView image_view(const py::handle& image, const std::string& what) {
  if (!py::isinstance<py::array>(image))
    throw Error("expected a 2-D NumPy array (uint8, uint16 or float32), got " +
                    std::string(py::str(py::type::of(image).attr("__name__"))),
                {.key = what});
  py::array array = py::reinterpret_borrow<py::array>(image);
  const int type = cv_type_of(array.dtype());
  if (array.ndim() != 2 || type < 0)
    throw Error("expected a 2-D uint8, uint16 or float32 image, got a " + std::to_string(array.ndim()) +
                    "-D " + std::string(py::str(array.dtype())) + " array",
                {.key = what});
  if (array.shape(0) < 1 || array.shape(1) < 1) throw Error("the image is empty", {.key = what});
  // Rows may be strided (a crop of a larger image); pixels within a row must be adjacent for cv::Mat.
  if (array.strides(1) != array.itemsize() || array.strides(0) < array.shape(1) * array.itemsize())
    array = py::array::ensure(array, py::array::c_style);
  const cv::Mat mat(static_cast<int>(array.shape(0)), static_cast<int>(array.shape(1)), type,
                    const_cast<void*>(array.data()), static_cast<std::size_t>(array.strides(0)));
  // A NaN or infinite pixel would spread through every filter over it; the file readers never give one.
  cv::Point bad;
  if (type == CV_32F && !cv::checkRange(mat, true, &bad))
    throw Error(
        "pixel (x " + std::to_string(bad.x) + ", y " + std::to_string(bad.y) + ") is not a finite number",
        {.key = what});
  return {array, mat};
}

std::vector<double> to_vector(const DoubleArray& x, const std::string& what) {
  if (x.ndim() != 1)
    throw Error("expected a 1-D array, got " + std::to_string(x.ndim()) + "-D", {.key = what});
  std::vector<double> values(x.data(), x.data() + x.size());
  const auto bad = std::find_if(values.begin(), values.end(), [](double v) { return !std::isfinite(v); });
  if (bad != values.end())
    throw Error("sample " + std::to_string(bad - values.begin()) + " (0-based) is not a finite number",
                {.key = what});
  return values;
}

py::array_t<double> to_array(const std::vector<double>& values) {
  py::array_t<double> out(static_cast<py::ssize_t>(values.size()));
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

}  // namespace tirstrain::python
