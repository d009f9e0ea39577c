#include "core/h5_file.hpp"

#include <filesystem>
#include <numeric>

#include "core/atomic_output.hpp"
#include "core/error.hpp"

namespace tirstrain {
namespace {

std::size_t element_count(const H5Shape& shape) {
  return std::accumulate(shape.begin(), shape.end(), std::size_t{1}, std::multiplies<>());
}

// Chunks of about 256 KiB along the first axis keep per-frame appends and partial reads cheap.
std::vector<hsize_t> chunk_shape(const H5Shape& shape, std::size_t element_size) {
  std::vector<hsize_t> chunk(shape.begin(), shape.end());
  std::size_t row_elements = 1;
  for (std::size_t i = 1; i < shape.size(); ++i) row_elements *= shape[i];
  const std::size_t target_rows =
      std::max<std::size_t>(1, (256 * 1024) / std::max<std::size_t>(1, row_elements * element_size));
  chunk[0] = std::max<hsize_t>(1, std::min<hsize_t>(shape[0], target_rows));
  return chunk;
}

// The in-memory file grows in steps of this many bytes.
constexpr std::size_t kCoreIncrementBytes = 4u << 20;

struct SilenceHdf5 {
  SilenceHdf5() { H5::Exception::dontPrint(); }
};

}  // namespace

H5Writer::H5Writer(const std::string& path) : path_(path), partial_path_(path + ".partial") {
  SilenceHdf5 silence;
  // The output file exists (as "<path>.partial") from the start, so a folder that cannot take it fails now.
  out_ = std::make_unique<AtomicFile>(path_);
  try {
    // Built in memory and written out by commit() with checked writes: a full disk is then an ordinary
    // write error naming its cause, never an HDF5 library left half-closed after a failed flush (whose
    // destructors crash).
    H5::FileAccPropList access;
    access.setCore(kCoreIncrementBytes, false);
    file_ = H5::H5File(partial_path_, H5F_ACC_TRUNC, H5::FileCreatPropList::DEFAULT, access);
  } catch (const H5::Exception& e) {
    throw Error("cannot create HDF5 file: " + e.getDetailMsg(), {.file = partial_path_});
  }
}

H5Writer::~H5Writer() {
  if (!committed_) {
    try {
      file_.close();
    } catch (...) {
    }
  }
}

void H5Writer::ensure_parent_groups(const std::string& name) {
  std::size_t pos = 1;
  while ((pos = name.find('/', pos)) != std::string::npos) {
    const std::string group = name.substr(0, pos);
    if (!file_.nameExists(group)) file_.createGroup(group);
    ++pos;
  }
}

template <typename T>
void H5Writer::write_impl(const std::string& name, std::span<const T> data, const H5Shape& shape,
                          const H5::PredType& type) {
  if (element_count(shape) != data.size())
    throw Error("internal: dataset size does not match its shape", {.file = path_, .column = name});
  try {
    ensure_parent_groups(name);
    std::vector<hsize_t> dims(shape.begin(), shape.end());
    H5::DataSpace space(static_cast<int>(dims.size()), dims.data());
    H5::DSetCreatPropList properties;
    if (!shape.empty() && data.size() * sizeof(T) > 16 * 1024 && shape[0] > 0) {
      const auto chunk = chunk_shape(shape, sizeof(T));
      properties.setChunk(static_cast<int>(chunk.size()), chunk.data());
      properties.setShuffle();
      properties.setDeflate(4);
    }
    H5::DataSet set = file_.createDataSet(name, type, space, properties);
    if (!data.empty()) set.write(data.data(), type);
  } catch (const H5::Exception& e) {
    throw Error("cannot write dataset: " + e.getDetailMsg(), {.file = partial_path_, .column = name});
  }
}

void H5Writer::write(const std::string& name, std::span<const double> data, const H5Shape& shape) {
  write_impl(name, data, shape, H5::PredType::NATIVE_DOUBLE);
}
void H5Writer::write(const std::string& name, std::span<const float> data, const H5Shape& shape) {
  write_impl(name, data, shape, H5::PredType::NATIVE_FLOAT);
}
void H5Writer::write(const std::string& name, std::span<const std::int32_t> data, const H5Shape& shape) {
  write_impl(name, data, shape, H5::PredType::NATIVE_INT32);
}
void H5Writer::write(const std::string& name, std::span<const std::int64_t> data, const H5Shape& shape) {
  write_impl(name, data, shape, H5::PredType::NATIVE_INT64);
}
void H5Writer::write(const std::string& name, std::span<const std::int8_t> data, const H5Shape& shape) {
  write_impl(name, data, shape, H5::PredType::NATIVE_INT8);
}
void H5Writer::write(const std::string& name, std::span<const std::uint8_t> data, const H5Shape& shape) {
  write_impl(name, data, shape, H5::PredType::NATIVE_UINT8);
}

H5::H5Object& H5Writer::object(const std::string& name, H5::Group& group_holder, H5::DataSet& set_holder) {
  if (name == "/" || name.empty()) {
    group_holder = file_.openGroup("/");
    return group_holder;
  }
  if (!file_.nameExists(name)) {
    ensure_parent_groups(name + "/");
  }
  if (file_.childObjType(name) == H5O_TYPE_DATASET) {
    set_holder = file_.openDataSet(name);
    return set_holder;
  }
  group_holder = file_.openGroup(name);
  return group_holder;
}

void H5Writer::attribute(const std::string& object_name, const std::string& name, const std::string& value) {
  try {
    H5::Group group;
    H5::DataSet set;
    H5::H5Object& target = object(object_name, group, set);
    H5::StrType type(H5::PredType::C_S1, std::max<std::size_t>(1, value.size()));
    H5::Attribute attr = target.createAttribute(name, type, H5::DataSpace(H5S_SCALAR));
    attr.write(type, value.empty() ? std::string(" ") : value);
  } catch (const H5::Exception& e) {
    throw Error("cannot write attribute '" + name + "': " + e.getDetailMsg(),
                {.file = partial_path_, .column = object_name});
  }
}

void H5Writer::attribute(const std::string& object_name, const std::string& name, double value) {
  try {
    H5::Group group;
    H5::DataSet set;
    H5::H5Object& target = object(object_name, group, set);
    H5::Attribute attr = target.createAttribute(name, H5::PredType::NATIVE_DOUBLE, H5::DataSpace(H5S_SCALAR));
    attr.write(H5::PredType::NATIVE_DOUBLE, &value);
  } catch (const H5::Exception& e) {
    throw Error("cannot write attribute '" + name + "': " + e.getDetailMsg(),
                {.file = partial_path_, .column = object_name});
  }
}

void H5Writer::commit() {
  std::string image;
  try {
    file_.flush(H5F_SCOPE_GLOBAL);
    const ssize_t size = H5Fget_file_image(file_.getId(), nullptr, 0);
    if (size < 0) throw H5::FileIException("H5Fget_file_image", "cannot size the file image");
    image.resize(static_cast<std::size_t>(size));
    if (H5Fget_file_image(file_.getId(), image.data(), image.size()) != size)
      throw H5::FileIException("H5Fget_file_image", "cannot copy the file image");
    file_.close();
  } catch (const H5::Exception& e) {
    throw Error("cannot finish HDF5 file: " + e.getDetailMsg(), {.file = partial_path_});
  }
  out_->append(image);
  out_->commit();
  committed_ = true;
}

H5Reader::H5Reader(const std::string& path) : path_(path) {
  SilenceHdf5 silence;
  if (!std::filesystem::is_regular_file(path)) throw Error("file not found", {.file = path});
  try {
    file_ = H5::H5File(path, H5F_ACC_RDONLY);
  } catch (const H5::Exception& e) {
    throw Error("not a readable HDF5 file: " + e.getDetailMsg(), {.file = path});
  }
}

bool H5Reader::has(const std::string& name) const {
  try {
    // nameExists fails on a missing intermediate group, so check each level.
    std::size_t pos = 1;
    while ((pos = name.find('/', pos)) != std::string::npos) {
      if (!file_.nameExists(name.substr(0, pos))) return false;
      ++pos;
    }
    return file_.nameExists(name);
  } catch (const H5::Exception&) {
    return false;
  }
}

H5Shape H5Reader::shape(const std::string& name) const {
  if (!has(name)) throw Error("no such dataset", {.file = path_, .column = name});
  const H5::DataSpace space = file_.openDataSet(name).getSpace();
  std::vector<hsize_t> dims(static_cast<std::size_t>(space.getSimpleExtentNdims()));
  space.getSimpleExtentDims(dims.data());
  return H5Shape(dims.begin(), dims.end());
}

std::vector<double> H5Reader::read_doubles(const std::string& name, H5Shape* shape_out) const {
  const H5Shape dims = shape(name);
  std::vector<double> data(element_count(dims));
  try {
    if (!data.empty()) file_.openDataSet(name).read(data.data(), H5::PredType::NATIVE_DOUBLE);
  } catch (const H5::Exception& e) {
    throw Error("cannot read dataset as numbers: " + e.getDetailMsg(), {.file = path_, .column = name});
  }
  if (shape_out) *shape_out = dims;
  return data;
}

std::vector<double> H5Reader::read_row_doubles(const std::string& name, std::size_t row,
                                               H5Shape* shape_out) const {
  const H5Shape dims = shape(name);
  if (dims.empty() || row >= dims[0])
    throw Error("row " + std::to_string(row) + " is outside the dataset's " +
                    (dims.empty() ? std::string("0") : std::to_string(dims[0])) + " rows",
                {.file = path_, .column = name});
  const H5Shape row_dims(dims.begin() + 1, dims.end());
  std::vector<double> data(element_count(row_dims));
  try {
    const H5::DataSet set = file_.openDataSet(name);
    H5::DataSpace space = set.getSpace();
    std::vector<hsize_t> start(dims.size(), 0), count(dims.begin(), dims.end());
    start[0] = row;
    count[0] = 1;
    space.selectHyperslab(H5S_SELECT_SET, count.data(), start.data());
    const H5::DataSpace memory(static_cast<int>(count.size()), count.data());
    set.read(data.data(), H5::PredType::NATIVE_DOUBLE, memory, space);
  } catch (const H5::Exception& e) {
    throw Error("cannot read a row of the dataset as numbers: " + e.getDetailMsg(),
                {.file = path_, .column = name});
  }
  if (shape_out) *shape_out = row_dims;
  return data;
}

std::vector<std::int64_t> H5Reader::read_integers(const std::string& name, H5Shape* shape_out) const {
  const H5Shape dims = shape(name);
  std::vector<std::int64_t> data(element_count(dims));
  try {
    if (!data.empty()) file_.openDataSet(name).read(data.data(), H5::PredType::NATIVE_INT64);
  } catch (const H5::Exception& e) {
    throw Error("cannot read dataset as integers: " + e.getDetailMsg(), {.file = path_, .column = name});
  }
  if (shape_out) *shape_out = dims;
  return data;
}

namespace {
H5::Attribute open_attribute(const H5::H5File& file, const std::string& object, const std::string& name) {
  if (object == "/" || object.empty()) return file.openGroup("/").openAttribute(name);
  if (file.childObjType(object) == H5O_TYPE_DATASET) return file.openDataSet(object).openAttribute(name);
  return file.openGroup(object).openAttribute(name);
}
}  // namespace

bool H5Reader::has_attribute(const std::string& object, const std::string& name) const {
  try {
    if (object == "/" || object.empty()) return file_.openGroup("/").attrExists(name);
    if (!has(object)) return false;
    if (file_.childObjType(object) == H5O_TYPE_DATASET) return file_.openDataSet(object).attrExists(name);
    return file_.openGroup(object).attrExists(name);
  } catch (const H5::Exception&) {
    return false;
  }
}

std::string H5Reader::attribute_text(const std::string& object, const std::string& name) const {
  try {
    H5::Attribute attr = open_attribute(file_, object, name);
    std::string value;
    attr.read(attr.getStrType(), value);
    return value;
  } catch (const H5::Exception& e) {
    throw Error("cannot read text attribute '" + name + "': " + e.getDetailMsg(),
                {.file = path_, .column = object});
  }
}

double H5Reader::attribute_number(const std::string& object, const std::string& name) const {
  try {
    H5::Attribute attr = open_attribute(file_, object, name);
    double value = 0.0;
    attr.read(H5::PredType::NATIVE_DOUBLE, &value);
    return value;
  } catch (const H5::Exception& e) {
    throw Error("cannot read number attribute '" + name + "': " + e.getDetailMsg(),
                {.file = path_, .column = object});
  }
}

std::vector<std::string> H5Reader::members(const std::string& group) const {
  std::vector<std::string> names;
  try {
    H5::Group g = file_.openGroup(group);
    for (hsize_t i = 0; i < g.getNumObjs(); ++i) names.push_back(g.getObjnameByIdx(i));
  } catch (const H5::Exception& e) {
    throw Error("cannot list group: " + e.getDetailMsg(), {.file = path_, .column = group});
  }
  return names;
}

}  // namespace tirstrain
