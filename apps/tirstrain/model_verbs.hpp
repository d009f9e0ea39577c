#pragma once
// `tirstrain model` verbs defined outside cmd_model.cpp (support_model_*.cpp), registered by it.
#include <CLI/CLI.hpp>

namespace tirstrain::cli {

// `model texture-interaction`: the spectral lines a fingerprint receives from a periodic texture.
void add_model_texture_interaction_verb(CLI::App& model);

}  // namespace tirstrain::cli
