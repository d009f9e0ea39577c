// The Python module `tirstrain`: the model, tracker, segmenter, pipeline and signals verbs on NumPy arrays.
// Errors are raised as tirstrain.Error (a RuntimeError) with the message the CLI prints after
// "tirstrain: error: ", the keyword argument named where the CLI names its option.
#include "core/error.hpp"
#include "core/version.hpp"
#include "python/bindings.hpp"

PYBIND11_MODULE(tirstrain, m) {
  m.doc() = "tirstrain: fingertip skin strain from total-internal-reflection contact images (docs/python.md)";
  m.attr("__version__") = tirstrain::kVersion;
  pybind11::register_exception<tirstrain::Error>(m, "Error", PyExc_RuntimeError);
  tirstrain::python::bind_model(m);
  tirstrain::python::bind_flow(m);
  tirstrain::python::bind_contact(m);
  tirstrain::python::bind_pipeline(m);
  tirstrain::python::bind_signals(m);
}
