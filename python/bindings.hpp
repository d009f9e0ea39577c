#pragma once
// One function per library, each adding its functions to the module (python/module.cpp).
#include <pybind11/pybind11.h>

namespace tirstrain::python {

void bind_model(pybind11::module_& m);
void bind_flow(pybind11::module_& m);
void bind_contact(pybind11::module_& m);
void bind_pipeline(pybind11::module_& m);
void bind_signals(pybind11::module_& m);

}  // namespace tirstrain::python
