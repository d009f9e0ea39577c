// tirstrain.process (pipeline/) and tirstrain.read_result: a recording processed into a result folder, and
// any tirstrain HDF5 file read back as NumPy arrays.
#include <pybind11/stl.h>

#include <H5Cpp.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "flow/settings.hpp"
#include "pipeline/process.hpp"
#include "python/arrays.hpp"
#include "python/bindings.hpp"

namespace tirstrain::python {

namespace {

std::string path_text(const py::object& path) {
  return py::str(py::module_::import("os").attr("fspath")(path));
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot read the summary", {.file = path});
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

pipeline::OverlayMode parse_overlay(const std::string& name) {
  static const std::map<std::string, pipeline::OverlayMode> modes = {{"mp4", pipeline::OverlayMode::kMp4},
                                                                     {"png", pipeline::OverlayMode::kPng},
                                                                     {"none", pipeline::OverlayMode::kNone}};
  const auto mode = modes.find(name);
  if (mode == modes.end())
    throw Error("unknown overlay '" + name + "' (use mp4, png or none)", {.key = "overlay"});
  return mode->second;
}

py::object process(const py::object& input, const py::object& out, const std::optional<py::object>& scene,
                   const std::vector<std::string>& compute, const std::string& overlay,
                   const std::string& preset, const std::string& segmentation, bool quiet, bool strict) {
  // Checked here so that the error names the keyword, not the scene file the value is merged into.
  const std::vector<std::string>& presets = flow::preset_names();
  if (!preset.empty() && std::find(presets.begin(), presets.end(), preset) == presets.end()) {
    std::string known;
    for (const std::string& p : presets) known += (known.empty() ? "" : ", ") + p;
    throw Error("'" + preset + "' is not one of: " + known, {.key = "preset"});
  }
  if (!segmentation.empty() && segmentation != "accurate" && segmentation != "balanced" &&
      segmentation != "fast")
    throw Error("'" + segmentation + "' is not one of: accurate, balanced, fast", {.key = "segmentation"});
  pipeline::ProcessOptions options;
  options.input = path_text(input);
  options.out_dir = path_text(out);
  if (scene && !scene->is_none()) options.scene_path = path_text(*scene);
  options.compute = compute;
  options.overlay = parse_overlay(overlay);
  options.tracking_preset = preset;
  options.segmentation_preset = segmentation;
  options.quiet = quiet;
  options.strict = strict;
  {
    py::gil_scoped_release release;
    pipeline::run_process(options);
  }
  return py::module_::import("json").attr("loads")(read_text(options.out_dir + "/summary.json"));
}

// The NumPy dtype a dataset is read into: its own, for the integer and float widths tirstrain writes.
std::pair<py::dtype, H5::PredType> native_type(const H5::DataSet& set, const std::string& file,
                                               const std::string& name) {
  const H5T_class_t type_class = set.getTypeClass();
  if (type_class == H5T_FLOAT) {
    if (set.getFloatType().getSize() == 4) return {py::dtype::of<float>(), H5::PredType::NATIVE_FLOAT};
    return {py::dtype::of<double>(), H5::PredType::NATIVE_DOUBLE};
  }
  if (type_class == H5T_INTEGER) {
    const H5::IntType type = set.getIntType();
    const bool is_signed = type.getSign() != H5T_SGN_NONE;
    switch (type.getSize()) {
      case 1:
        return is_signed ? std::pair{py::dtype::of<std::int8_t>(), H5::PredType::NATIVE_INT8}
                         : std::pair{py::dtype::of<std::uint8_t>(), H5::PredType::NATIVE_UINT8};
      case 2:
        return is_signed ? std::pair{py::dtype::of<std::int16_t>(), H5::PredType::NATIVE_INT16}
                         : std::pair{py::dtype::of<std::uint16_t>(), H5::PredType::NATIVE_UINT16};
      case 4:
        return is_signed ? std::pair{py::dtype::of<std::int32_t>(), H5::PredType::NATIVE_INT32}
                         : std::pair{py::dtype::of<std::uint32_t>(), H5::PredType::NATIVE_UINT32};
      default:
        return is_signed ? std::pair{py::dtype::of<std::int64_t>(), H5::PredType::NATIVE_INT64}
                         : std::pair{py::dtype::of<std::uint64_t>(), H5::PredType::NATIVE_UINT64};
    }
  }
  throw Error("dataset is neither integer nor floating point", {.file = file, .column = name});
}

py::array read_dataset(const H5::DataSet& set, const std::string& file, const std::string& name) {
  const auto [dtype, memory_type] = native_type(set, file, name);
  const H5::DataSpace space = set.getSpace();
  std::vector<hsize_t> dims(static_cast<std::size_t>(space.getSimpleExtentNdims()));
  if (!dims.empty()) space.getSimpleExtentDims(dims.data());
  py::array array(dtype, std::vector<py::ssize_t>(dims.begin(), dims.end()));
  if (array.size() > 0) set.read(array.mutable_data(), memory_type);
  return array;
}

// Every dataset under `group`, keyed by its full path ("/tracks/position_px").
void read_group(const H5::Group& group, const std::string& prefix, const std::string& file, py::dict& out) {
  for (hsize_t i = 0; i < group.getNumObjs(); ++i) {
    const std::string name = group.getObjnameByIdx(i);
    const std::string path = prefix + "/" + name;
    const H5G_obj_t type = group.getObjTypeByIdx(i);
    if (type == H5G_GROUP) read_group(group.openGroup(name), path, file, out);
    if (type == H5G_DATASET) out[py::str(path)] = read_dataset(group.openDataSet(name), file, path);
  }
}

py::dict read_result(const py::object& path_object) {
  const std::string path = path_text(path_object);
  if (!std::ifstream(path)) throw Error("no such file, or it cannot be read", {.file = path});
  py::dict out;
  try {
    H5::Exception::dontPrint();
    const H5::H5File file(path, H5F_ACC_RDONLY);
    read_group(file.openGroup("/"), "", path, out);
  } catch (const H5::Exception& e) {
    throw Error("cannot read HDF5 file: " + e.getDetailMsg(), {.file = path});
  }
  return out;
}

}  // namespace

void bind_pipeline(py::module_& m) {
  using namespace py::literals;
  m.def("process", &process, "input"_a, "out"_a, "scene"_a = py::none(), py::kw_only(),
        "compute"_a = std::vector<std::string>{}, "overlay"_a = "mp4", "preset"_a = "", "segmentation"_a = "",
        "quiet"_a = false, "strict"_a = false,
        "Runs `tirstrain process INPUT --out OUT` (pipeline/): the result folder (result.h5, frames.csv,\n"
        "summary.json, overlay) is built in OUT.partial and swapped in when complete. scene: a scene file\n"
        "(default: INPUT/scene.yaml when present, else the defaults). compute, overlay (mp4, png, none),\n"
        "preset (tracking), segmentation, quiet and strict as the CLI's options. Returns summary.json as\n"
        "a dict.");
  m.def("read_result", &read_result, "path"_a,
        "Reads every dataset of a tirstrain HDF5 file (result.h5, truth.h5, fit.h5) into a dict of NumPy\n"
        "arrays keyed by HDF5 path (e.g. '/tracks/position_px'), each in its stored dtype\n"
        "(docs/formats.md).");
}

}  // namespace tirstrain::python
