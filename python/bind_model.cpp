// tirstrain.cattaneo_mindlin: the Hertz + Cattaneo–Mindlin surface field (model/) on arrays of points.
#include <pybind11/stl.h>

#include <cmath>
#include <string>

#include "core/error.hpp"
#include "model/cattaneo_mindlin.hpp"
#include "python/arrays.hpp"
#include "python/bindings.hpp"

namespace tirstrain::python {

namespace {

model::CattaneoMindlin make_model(const model::CattaneoMindlinParams& params) {
  try {
    return model::CattaneoMindlin(params);
  } catch (const model::InvalidParameter& e) {
    // The parameter names are the keyword arguments' names.
    throw Error(e.what(), {.key = e.parameter()});
  }
}

py::dict cattaneo_mindlin(const DoubleArray& x_m, const DoubleArray& y_m, double normal_N,
                          double tangential_N, double radius_m, double young_Pa, double poisson,
                          double friction, double direction_rad) {
  const std::vector<py::ssize_t> shape(x_m.shape(), x_m.shape() + x_m.ndim());
  if (std::vector<py::ssize_t>(y_m.shape(), y_m.shape() + y_m.ndim()) != shape)
    throw Error("x_m and y_m must have the same shape", {.key = "y_m"});
  // A point must be a number: NumPy turns None into NaN on the way in, which would come back as NaN
  // fields without a word.
  for (const auto* array : {&x_m, &y_m}) {
    const double* v = array->data();
    for (py::ssize_t i = 0; i < array->size(); ++i)
      if (!std::isfinite(v[i]))
        throw Error("point " + std::to_string(i) + " is " +
                        (std::isnan(v[i]) ? "NaN (or None)" : "infinite") +
                        ": every point needs a finite position, m",
                    {.key = array == &x_m ? "x_m" : "y_m"});
  }
  const model::CattaneoMindlin cm = make_model({.normal_N = normal_N,
                                                .tangential_N = tangential_N,
                                                .radius_m = radius_m,
                                                .young_Pa = young_Pa,
                                                .poisson = poisson,
                                                .friction = friction,
                                                .direction_rad = direction_rad});
  const char* names[] = {"ux_m", "uy_m", "Exx", "Eyy", "Exy", "energy_density_J_m3"};
  std::vector<py::array_t<double>> out;
  std::vector<double*> dst;
  for (int i = 0; i < 6; ++i) {
    out.push_back(new_array<double>(shape));
    dst.push_back(out.back().mutable_data());
  }
  const double* xs = x_m.data();
  const double* ys = y_m.data();
  const py::ssize_t n = x_m.size();
  {
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n; ++i) {
      const model::FieldSample s = cm.evaluate(xs[i], ys[i]);
      dst[0][i] = s.displacement_m.x;
      dst[1][i] = s.displacement_m.y;
      dst[2][i] = s.strain.xx;
      dst[3][i] = s.strain.yy;
      dst[4][i] = s.strain.xy;
      dst[5][i] = s.energy_density_J_m3;
    }
  }
  py::dict result;
  for (int i = 0; i < 6; ++i) result[names[i]] = out[static_cast<std::size_t>(i)];
  return result;
}

}  // namespace

void bind_model(py::module_& m) {
  using namespace py::literals;
  m.def("cattaneo_mindlin", &cattaneo_mindlin, "x_m"_a, "y_m"_a, py::kw_only(), "normal_N"_a,
        "tangential_N"_a, "radius_m"_a, "young_Pa"_a, "poisson"_a, "friction"_a, "direction_rad"_a = 0.0,
        "Hertz + Cattaneo-Mindlin partial-slip surface field of an elastic sphere on a rigid flat at the\n"
        "points (x_m, y_m) (metres, contact centre at the origin; arrays of one shape). Returns a dict of\n"
        "arrays of that shape: ux_m, uy_m (displacement, m), Exx, Eyy, Exy (Green-Lagrange strain) and\n"
        "energy_density_J_m3. direction_rad: direction of the tangential traction on the skin, from +x\n"
        "towards +y. Formulas: docs/model.md.");
}

}  // namespace tirstrain::python
