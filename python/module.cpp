// The Python module `tirstrain`: the model, tracker, segmenter, pipeline and signals verbs on NumPy arrays.
// Errors are raised as tirstrain.Error (a RuntimeError) with the message the CLI prints after
// "tirstrain: error: ", the keyword argument named where the CLI names its option.
#include "core/error.hpp"
#include "core/version.hpp"
#include "python/bindings.hpp"

PYBIND11_MODULE(tirstrain, m) {
  m.doc() = "tirstrain: fingertip skin strain from total-internal-reflection contact images (docs/python.md)";
  m.attr("__version__") = tirstrain::kVersion;
  // The library and the pipeline name command-line options ("--frame-rate-Hz"); from Python the same
  // value is the keyword argument frame_rate_Hz.
  static pybind11::exception<tirstrain::Error> error(m, "Error", PyExc_RuntimeError);
  pybind11::register_exception_translator([](std::exception_ptr raised) {
    try {
      if (raised) std::rethrow_exception(raised);
    } catch (const tirstrain::Error& e) {
      tirstrain::ErrorContext where = e.context();
      if (where.key.rfind("--", 0) == 0) {
        where.key.erase(0, 2);
        for (char& c : where.key)
          if (c == '-') c = '_';
      }
      error(tirstrain::Error(e.message(), where).what());
    }
  });
  tirstrain::python::bind_model(m);
  tirstrain::python::bind_flow(m);
  tirstrain::python::bind_contact(m);
  tirstrain::python::bind_pipeline(m);
  tirstrain::python::bind_signals(m);
}
