#include "libsabo/io/hdf5.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "libsabo/core/error.hpp"

namespace sabo::io::hdf5 {
namespace {

constexpr unsigned kSwmrReadAttempts = 10;

// HDF5 prints its error stack to stderr by default; we report it in the
// exception instead. Called by every entry point that can start a session.
void silence_library() {
  static const bool silenced = [] {
    H5open();
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)silenced;
}

struct ErrorStack {
  std::string innermost;  // the deepest frame's description: the root cause
  std::string text;       // every frame, outermost first
};

ErrorStack take_stack() {
  ErrorStack result;
  hid_t stack = H5Eget_current_stack();  // also clears the current stack
  if (stack < 0) return result;
  H5Ewalk2(
      stack, H5E_WALK_DOWNWARD,
      [](unsigned depth, const H5E_error2_t* error, void* data) -> herr_t {
        auto& out = *static_cast<ErrorStack*>(data);
        std::array<char, 256> major{};
        std::array<char, 256> minor{};
        H5Eget_msg(error->maj_num, nullptr, major.data(), major.size());
        H5Eget_msg(error->min_num, nullptr, minor.data(), minor.size());
        out.innermost = error->desc ? error->desc : "";
        out.text += fmt::format("  #{:03} {}:{} in {}(): {}\n        major: {}; minor: {}\n", depth,
                                error->file_name ? error->file_name : "?", error->line,
                                error->func_name ? error->func_name : "?", out.innermost, major.data(), minor.data());
        return 0;
      },
      &result);
  H5Eclose_stack(stack);
  return result;
}

[[noreturn]] void fail(const std::string& what) {
  const ErrorStack stack = take_stack();
  throw LibraryError(fmt::format("HDF5: {}{}{}", what, stack.innermost.empty() ? "" : ": " + stack.innermost,
                                 stack.text.empty() ? "" : "\nHDF5 error stack:\n" + stack.text));
}

hid_t memory_type(Type type) {
  switch (type) {
    case Type::float64: return H5T_NATIVE_DOUBLE;
    case Type::uint64: return H5T_NATIVE_UINT64;
    case Type::uint32: return H5T_NATIVE_UINT32;
    case Type::uint8: return H5T_NATIVE_UINT8;
  }
  return H5T_NATIVE_DOUBLE;
}

hid_t file_type(Type type) {
  switch (type) {
    case Type::float64: return H5T_IEEE_F64LE;
    case Type::uint64: return H5T_STD_U64LE;
    case Type::uint32: return H5T_STD_U32LE;
    case Type::uint8: return H5T_STD_U8LE;
  }
  return H5T_IEEE_F64LE;
}

// The element type of a stored dataset, or throws naming the stored type.
Type classify(hid_t stored_type, const std::string& context) {
  const H5T_class_t type_class = H5Tget_class(stored_type);
  const std::size_t size = H5Tget_size(stored_type);
  if (type_class == H5T_FLOAT && size == 8) return Type::float64;
  if (type_class == H5T_INTEGER && H5Tget_sign(stored_type) == H5T_SGN_NONE) {
    if (size == 8) return Type::uint64;
    if (size == 4) return Type::uint32;
    if (size == 1) return Type::uint8;
  }
  throw LibraryError(
      fmt::format("HDF5: {}: the dataset's element type (class {}, {} bytes) is none of float64, "
                  "uint64, uint32, uint8. Fix: write it with sabo's HDF5 wrapper",
                  context, static_cast<int>(type_class), size));
}

std::string string_of_path(const std::filesystem::path& path) {
  return path.string();
}

// A scalar dataspace, closed on scope exit.
Handle scalar_space() {
  hid_t space = H5Screate(H5S_SCALAR);
  if (space < 0) fail("could not create a scalar dataspace");
  return Handle(space);
}

}  // namespace

const char* type_name(Type type) {
  switch (type) {
    case Type::float64: return "float64";
    case Type::uint64: return "uint64";
    case Type::uint32: return "uint32";
    case Type::uint8: return "uint8";
  }
  return "?";
}

std::string take_error_stack() {
  return take_stack().text;
}

// ---------------------------------------------------------------- Handle

Handle::Handle(const Handle& other) : id_(other.id_) {
  if (valid()) H5Iinc_ref(id_);
}

Handle::Handle(Handle&& other) noexcept : id_(other.id_) {
  other.id_ = H5I_INVALID_HID;
}

Handle& Handle::operator=(const Handle& other) {
  if (this != &other) {
    reset();
    id_ = other.id_;
    if (valid()) H5Iinc_ref(id_);
  }
  return *this;
}

Handle& Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    reset();
    id_ = other.id_;
    other.id_ = H5I_INVALID_HID;
  }
  return *this;
}

Handle::~Handle() {
  reset();
}

void Handle::reset() {
  if (valid()) {
    // A failure here (library already shut down) leaves nothing to clean up.
    H5Idec_ref(id_);
    H5Eclear2(H5E_DEFAULT);
  }
  id_ = H5I_INVALID_HID;
}

// ---------------------------------------------------------------- Object

std::string Object::path() const {
  const ssize_t length = H5Iget_name(id(), nullptr, 0);
  if (length <= 0) return "?";
  std::string name(static_cast<std::size_t>(length), '\0');
  H5Iget_name(id(), name.data(), name.size() + 1);
  return name;
}

std::string Object::file_name() const {
  const ssize_t length = H5Fget_name(id(), nullptr, 0);
  if (length <= 0) return "?";
  std::string name(static_cast<std::size_t>(length), '\0');
  H5Fget_name(id(), name.data(), name.size() + 1);
  return name;
}

std::string Object::context(const std::string& doing) const {
  return fmt::format("{} in '{}' at '{}'", doing, file_name(), path());
}

bool Object::has_attribute(const std::string& name) const {
  const htri_t exists = H5Aexists(id(), name.c_str());
  if (exists < 0) fail(context(fmt::format("could not check for attribute '{}'", name)));
  return exists > 0;
}

namespace {

void write_attribute(hid_t id, const std::string& name, hid_t type, const void* value, const std::string& context) {
  const htri_t exists = H5Aexists(id, name.c_str());
  if (exists < 0) fail(context);
  if (exists > 0 && H5Adelete(id, name.c_str()) < 0) fail(context);
  Handle space = scalar_space();
  Handle attribute(H5Acreate2(id, name.c_str(), type, space.id(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attribute.valid()) fail(context);
  if (H5Awrite(attribute.id(), type, value) < 0) fail(context);
}

Handle open_attribute(hid_t id, const std::string& name, const std::string& context) {
  Handle attribute(H5Aopen(id, name.c_str(), H5P_DEFAULT));
  if (!attribute.valid()) fail(context);
  return attribute;
}

}  // namespace

void Object::set_attribute(const std::string& name, const std::string& value) {
  silence_library();
  Handle type(H5Tcopy(H5T_C_S1));
  const std::string where = context(fmt::format("could not write string attribute '{}'", name));
  if (!type.valid() || H5Tset_size(type.id(), H5T_VARIABLE) < 0 || H5Tset_cset(type.id(), H5T_CSET_UTF8) < 0) {
    fail(where);
  }
  const char* text = value.c_str();
  write_attribute(id(), name, type.id(), static_cast<const void*>(&text), where);
}

void Object::set_attribute(const std::string& name, double value) {
  write_attribute(id(), name, H5T_NATIVE_DOUBLE, &value,
                  context(fmt::format("could not write attribute '{}' = {}", name, value)));
}

void Object::set_attribute(const std::string& name, std::int64_t value) {
  write_attribute(id(), name, H5T_NATIVE_INT64, &value,
                  context(fmt::format("could not write attribute '{}' = {}", name, value)));
}

std::string Object::string_attribute(const std::string& name) const {
  const std::string where = context(fmt::format("could not read string attribute '{}'", name));
  Handle attribute = open_attribute(id(), name, where);
  Handle stored(H5Aget_type(attribute.id()));
  if (!stored.valid()) fail(where);
  if (H5Tget_class(stored.id()) != H5T_STRING) {
    throw LibraryError(fmt::format("HDF5: {}: the attribute is not a string", where));
  }
  const htri_t variable = H5Tis_variable_str(stored.id());
  if (variable < 0) fail(where);
  Handle memory(H5Tcopy(H5T_C_S1));
  if (!memory.valid()) fail(where);
  if (variable > 0) {
    if (H5Tset_size(memory.id(), H5T_VARIABLE) < 0 || H5Tset_cset(memory.id(), H5Tget_cset(stored.id())) < 0) {
      fail(where);
    }
    char* text = nullptr;
    if (H5Aread(attribute.id(), memory.id(), static_cast<void*>(&text)) < 0) fail(where);
    std::string value = text ? text : "";
    H5free_memory(text);
    return value;
  }
  const std::size_t size = H5Tget_size(stored.id());
  std::string value(size, '\0');
  if (H5Tset_size(memory.id(), size) < 0 || H5Aread(attribute.id(), stored.id(), value.data()) < 0) fail(where);
  value.resize(std::min(value.find('\0'), value.size()));
  return value;
}

double Object::double_attribute(const std::string& name) const {
  const std::string where = context(fmt::format("could not read attribute '{}' as a double", name));
  Handle attribute = open_attribute(id(), name, where);
  double value = 0;
  if (H5Aread(attribute.id(), H5T_NATIVE_DOUBLE, &value) < 0) fail(where);
  return value;
}

std::int64_t Object::int_attribute(const std::string& name) const {
  const std::string where = context(fmt::format("could not read attribute '{}' as an integer", name));
  Handle attribute = open_attribute(id(), name, where);
  std::int64_t value = 0;
  if (H5Aread(attribute.id(), H5T_NATIVE_INT64, &value) < 0) fail(where);
  return value;
}

// ---------------------------------------------------------------- Dataset

std::uint64_t Dataset::size() const {
  Handle space(H5Dget_space(id()));
  hsize_t dims = 0;
  if (!space.valid() || H5Sget_simple_extent_dims(space.id(), &dims, nullptr) != 1) {
    fail(context("could not query the size of the dataset"));
  }
  return dims;
}

template <Element T>
void Dataset::check_type(const char* doing) const {
  if (type_of<T>() != type_) {
    throw LibraryError(fmt::format("HDF5: {}: the dataset holds {} but the program asked for {}", context(doing),
                                   type_name(type_), type_name(type_of<T>())));
  }
}

template <Element T>
void Dataset::append(std::span<const T> values) {
  if (values.empty()) return;
  check_type<T>("could not append to the dataset");
  const hsize_t old_size = size();
  const hsize_t count = values.size();
  const hsize_t new_size = old_size + count;
  auto where = [&] { return context(fmt::format("could not append {} values at offset {}", count, old_size)); };
  if (H5Dset_extent(id(), &new_size) < 0) fail(where());
  Handle file_space(H5Dget_space(id()));
  if (!file_space.valid() ||
      H5Sselect_hyperslab(file_space.id(), H5S_SELECT_SET, &old_size, nullptr, &count, nullptr) < 0) {
    fail(where());
  }
  Handle memory_space(H5Screate_simple(1, &count, nullptr));
  if (!memory_space.valid() ||
      H5Dwrite(id(), memory_type(type_), memory_space.id(), file_space.id(), H5P_DEFAULT, values.data()) < 0) {
    fail(where());
  }
}

template <Element T>
void Dataset::read(std::uint64_t offset, std::span<T> out) const {
  check_type<T>("could not read the dataset");
  if (out.empty()) return;
  const hsize_t start = offset;
  const hsize_t count = out.size();
  const std::uint64_t stored = size();
  if (offset > stored || count > stored - offset) {
    throw FileError(
        fmt::format("HDF5: {}: the dataset holds only {} values. Fix: the file is truncated or its "
                    "index is inconsistent",
                    context(fmt::format("could not read values [{}, {})", offset, offset + count)), stored));
  }
  auto where = [&] { return context(fmt::format("could not read values [{}, {})", offset, offset + count)); };
  Handle file_space(H5Dget_space(id()));
  if (!file_space.valid() ||
      H5Sselect_hyperslab(file_space.id(), H5S_SELECT_SET, &start, nullptr, &count, nullptr) < 0) {
    fail(where());
  }
  Handle memory_space(H5Screate_simple(1, &count, nullptr));
  if (!memory_space.valid() ||
      H5Dread(id(), memory_type(type_), memory_space.id(), file_space.id(), H5P_DEFAULT, out.data()) < 0) {
    fail(where());
  }
}

template <Element T>
std::vector<T> Dataset::read_all() const {
  std::vector<T> values(size());
  read<T>(0, values);
  return values;
}

void Dataset::flush() {
  if (H5Dflush(id()) < 0) fail(context("could not flush the dataset"));
}

void Dataset::refresh() {
  if (H5Drefresh(id()) < 0) fail(context("could not refresh the dataset"));
}

#define SABO_HDF5_INSTANTIATE(T)                                     \
  template void Dataset::append<T>(std::span<const T>);              \
  template void Dataset::read<T>(std::uint64_t, std::span<T>) const; \
  template std::vector<T> Dataset::read_all<T>() const;
SABO_HDF5_INSTANTIATE(double)
SABO_HDF5_INSTANTIATE(std::uint64_t)
SABO_HDF5_INSTANTIATE(std::uint32_t)
SABO_HDF5_INSTANTIATE(std::uint8_t)
#undef SABO_HDF5_INSTANTIATE

// ---------------------------------------------------------------- Group

bool Group::exists(const std::string& name) const {
  const htri_t exists = H5Lexists(id(), name.c_str(), H5P_DEFAULT);
  if (exists < 0) fail(context(fmt::format("could not check for '{}'", name)));
  return exists > 0;
}

std::vector<std::string> Group::children() const {
  std::vector<std::string> names;
  hsize_t index = 0;
  const herr_t status = H5Literate(
      id(), H5_INDEX_NAME, H5_ITER_INC, &index,
      [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
        static_cast<std::vector<std::string>*>(data)->emplace_back(name);
        return 0;
      },
      &names);
  if (status < 0) fail(context("could not list the group's members"));
  std::sort(names.begin(), names.end());
  return names;
}

Group Group::create_group(const std::string& name) {
  Handle group(H5Gcreate2(id(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (!group.valid()) fail(context(fmt::format("could not create group '{}'", name)));
  return Group(std::move(group));
}

Group Group::group(const std::string& name) const {
  Handle group(H5Gopen2(id(), name.c_str(), H5P_DEFAULT));
  if (!group.valid()) fail(context(fmt::format("could not open group '{}'", name)));
  return Group(std::move(group));
}

Dataset Group::create_dataset(const std::string& name, Type type, std::uint64_t chunk_elements) {
  auto where = [&] {
    return context(
        fmt::format("could not create {} dataset '{}' with chunks of {}", type_name(type), name, chunk_elements));
  };
  const hsize_t initial = 0;
  const hsize_t maximum = H5S_UNLIMITED;
  const hsize_t chunk = std::max<std::uint64_t>(chunk_elements, 1);
  Handle space(H5Screate_simple(1, &initial, &maximum));
  Handle properties(H5Pcreate(H5P_DATASET_CREATE));
  if (!space.valid() || !properties.valid() || H5Pset_chunk(properties.id(), 1, &chunk) < 0) fail(where());
  Handle dataset(
      H5Dcreate2(id(), name.c_str(), file_type(type), space.id(), H5P_DEFAULT, properties.id(), H5P_DEFAULT));
  if (!dataset.valid()) fail(where());
  return Dataset(std::move(dataset), type);
}

Dataset Group::dataset(const std::string& name) const {
  const std::string where = context(fmt::format("could not open dataset '{}'", name));
  Handle dataset(H5Dopen2(id(), name.c_str(), H5P_DEFAULT));
  if (!dataset.valid()) fail(where);
  Handle stored(H5Dget_type(dataset.id()));
  if (!stored.valid()) fail(where);
  const Type type = classify(stored.id(), where);
  Handle space(H5Dget_space(dataset.id()));
  if (!space.valid()) fail(where);
  if (H5Sget_simple_extent_ndims(space.id()) != 1) {
    throw LibraryError(fmt::format("HDF5: {}: the dataset is not one-dimensional", where));
  }
  return Dataset(std::move(dataset), type);
}

// ---------------------------------------------------------------- File

File File::create(const std::filesystem::path& path, bool swmr) {
  silence_library();
  const std::string where = fmt::format("could not create file '{}'", string_of_path(path));
  Handle access(H5Pcreate(H5P_FILE_ACCESS));
  if (!access.valid()) fail(where);
  if (swmr && H5Pset_libver_bounds(access.id(), H5F_LIBVER_LATEST, H5F_LIBVER_LATEST) < 0) fail(where);
  Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, access.id()));
  if (!file.valid()) fail(where);
  return File(std::move(file), path);
}

File File::open(const std::filesystem::path& path, Access access) {
  silence_library();
  const char* mode = access == Access::read_write  ? "reading and writing"
                     : access == Access::swmr_read ? "reading (SWMR)"
                                                   : "reading";
  const std::string where = fmt::format("could not open file '{}' for {}", string_of_path(path), mode);
  if (!std::filesystem::exists(path)) {
    throw FileError(fmt::format("HDF5: {}: no such file. Fix: check the path", where));
  }
  unsigned flags = H5F_ACC_RDONLY;
  if (access == Access::read_write) flags = H5F_ACC_RDWR;
  if (access == Access::swmr_read) flags = H5F_ACC_RDONLY | H5F_ACC_SWMR_READ;
  Handle file_access(H5Pcreate(H5P_FILE_ACCESS));
  if (!file_access.valid()) fail(where);
  // A SWMR reader retries a metadata read whose checksum fails, in case the
  // writer is midway; HDF5's default of 100 tries with growing sleeps can
  // stall for minutes on a damaged file.
  if (access == Access::swmr_read && H5Pset_metadata_read_attempts(file_access.id(), kSwmrReadAttempts) < 0) {
    fail(where);
  }
  Handle file(H5Fopen(path.c_str(), flags, file_access.id()));
  if (!file.valid()) fail(where);
  return File(std::move(file), path);
}

void File::start_swmr_write() {
  if (H5Fstart_swmr_write(id()) < 0) fail(context("could not start SWMR writing"));
}

void File::flush() {
  if (H5Fflush(id(), H5F_SCOPE_LOCAL) < 0) fail(context("could not flush the file"));
}

void File::close() {
  handle_.reset();
}

void clear_status_flags(const std::filesystem::path& path) {
  silence_library();
  const std::string where = fmt::format("could not clear the status flags of '{}'", string_of_path(path));
  Handle access(H5Pcreate(H5P_FILE_ACCESS));
  if (!access.valid()) fail(where);
  // The property h5clear sets; it exists in the file-access class of every
  // HDF5 >= 1.10 but has no dedicated setter.
  hbool_t clear = true;
  if (H5Pset(access.id(), "clear_status_flags", &clear) < 0) fail(where);
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDWR, access.id()));
  if (!file.valid()) fail(where);
  // A killed SWMR writer leaves data past the end-of-allocation address the
  // superblock stores; closing would truncate the file there. Extend the
  // EOA to the end of the file first (h5clear's --increment).
  if (H5Fincrement_filesize(file.id(), 0) < 0) fail(where);
}

}  // namespace sabo::io::hdf5
