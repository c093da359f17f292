#pragma once
// A thin RAII wrapper over the HDF5 C API, in the style of HighFive: files,
// groups, 1-D extendible chunked datasets of a few element types, and scalar
// attributes. Every failing call throws sabo::LibraryError whose text names
// what we tried, on which file and object, and HDF5's own error stack.
// HDF5's automatic error printing is turned off by the first call into this
// wrapper.
//
// Crash safety: a File created with `swmr = true` uses the latest file format;
// after every dataset and attribute exists, start_swmr_write() switches it to
// single-writer/multiple-reader mode, in which HDF5 keeps the file consistent
// on disk at every moment as long as datasets only grow and are written (HDF5
// 1.10 does not refuse other changes then, but they void the guarantee). A
// file whose writer was killed opens with File::open(path, Access::swmr_read)
// (h5py: `h5py.File(path, "r", swmr=True)`), or with any reader after
// clear_status_flags(path) (what `h5clear -s --increment=0` does).
#include <hdf5.h>

#include <concepts>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace sabo::io::hdf5 {

// Owning reference to an HDF5 identifier; copies share it (H5Iinc_ref).
class Handle {
 public:
  Handle() = default;
  explicit Handle(hid_t id) : id_(id) {}  // takes ownership of one reference
  Handle(const Handle& other);
  Handle(Handle&& other) noexcept;
  Handle& operator=(const Handle& other);
  Handle& operator=(Handle&& other) noexcept;
  ~Handle();

  [[nodiscard]] hid_t id() const { return id_; }
  [[nodiscard]] bool valid() const { return id_ > 0; }
  void reset();  // drops this reference

 private:
  hid_t id_ = H5I_INVALID_HID;
};

// Element types a Dataset can hold; file storage is little endian.
enum class Type { float64, uint64, uint32, uint8 };
[[nodiscard]] const char* type_name(Type type);

template <class T>
concept Element = std::same_as<T, double> || std::same_as<T, std::uint64_t> || std::same_as<T, std::uint32_t> ||
    std::same_as<T, std::uint8_t>;

template <Element T>
constexpr Type type_of() {
  if constexpr (std::same_as<T, double>) return Type::float64;
  if constexpr (std::same_as<T, std::uint64_t>) return Type::uint64;
  if constexpr (std::same_as<T, std::uint32_t>) return Type::uint32;
  return Type::uint8;
}

// Something that has attributes and a path in a file: a file, group or dataset.
class Object {
 public:
  [[nodiscard]] hid_t id() const { return handle_.id(); }
  [[nodiscard]] bool valid() const { return handle_.valid(); }
  [[nodiscard]] std::string path() const;       // path inside the file, e.g. "/dem_solver/state/position"
  [[nodiscard]] std::string file_name() const;  // the file's name on disk

  [[nodiscard]] bool has_attribute(const std::string& name) const;
  // Replaces an existing attribute of the same name. Strings are stored as
  // variable-length UTF-8, integers as int64.
  void set_attribute(const std::string& name, const std::string& value);
  void set_attribute(const std::string& name, const char* value) { set_attribute(name, std::string(value)); }
  void set_attribute(const std::string& name, double value);
  void set_attribute(const std::string& name, std::int64_t value);
  void set_attribute(const std::string& name, int value) { set_attribute(name, std::int64_t{value}); }
  [[nodiscard]] std::string string_attribute(const std::string& name) const;
  [[nodiscard]] double double_attribute(const std::string& name) const;
  [[nodiscard]] std::int64_t int_attribute(const std::string& name) const;

 protected:
  Object() = default;
  explicit Object(Handle handle) : handle_(std::move(handle)) {}
  // "while <doing> on '<file>' at '<path>'": context for error messages.
  [[nodiscard]] std::string context(const std::string& doing) const;
  Handle handle_;
};

// A 1-D dataset that grows at its end.
class Dataset : public Object {
 public:
  Dataset() = default;
  [[nodiscard]] Type type() const { return type_; }
  [[nodiscard]] std::uint64_t size() const;  // elements

  // Appends values at the end (grows the dataset). No-op for an empty span.
  template <Element T>
  void append(std::span<const T> values);
  // Reads `out.size()` elements starting at `offset`; throws if out of range.
  template <Element T>
  void read(std::uint64_t offset, std::span<T> out) const;
  template <Element T>
  [[nodiscard]] std::vector<T> read_all() const;

  void flush();    // writes this dataset's data and metadata to the file (H5Dflush)
  void refresh();  // SWMR readers: sees what the writer has flushed since (H5Drefresh)

 private:
  friend class Group;
  Dataset(Handle handle, Type type) : Object(std::move(handle)), type_(type) {}
  template <Element T>
  void check_type(const char* doing) const;
  Type type_ = Type::float64;
};

class Group : public Object {
 public:
  Group() = default;
  [[nodiscard]] bool exists(const std::string& name) const;  // a direct child (link) of this name
  [[nodiscard]] std::vector<std::string> children() const;   // names of direct children, sorted
  Group create_group(const std::string& name);
  [[nodiscard]] Group group(const std::string& name) const;
  // An empty, extendible, chunked 1-D dataset; `chunk_elements` is the size of
  // one chunk of file storage (also the unit HDF5 writes at every flush).
  Dataset create_dataset(const std::string& name, Type type, std::uint64_t chunk_elements);
  template <Element T>
  Dataset create_dataset(const std::string& name, std::uint64_t chunk_elements) {
    return create_dataset(name, type_of<T>(), chunk_elements);
  }
  [[nodiscard]] Dataset dataset(const std::string& name) const;

 protected:
  explicit Group(Handle handle) : Object(std::move(handle)) {}
};

enum class Access { read_only, read_write, swmr_read };

class File : public Group {
 public:
  File() = default;
  // Creates (truncates) `path`. swmr: latest file format, ready for
  // start_swmr_write().
  static File create(const std::filesystem::path& path, bool swmr = false);
  static File open(const std::filesystem::path& path, Access access = Access::read_only);

  // Switches to single-writer/multiple-reader mode: afterwards datasets may
  // only grow and be written. Every object must exist before.
  void start_swmr_write();
  void flush();  // the whole file (H5Fflush)
  // Releases this handle; the file closes when its last open object is gone.
  void close();
  [[nodiscard]] const std::filesystem::path& disk_path() const { return path_; }

 private:
  File(Handle handle, std::filesystem::path path) : Group(std::move(handle)), path_(std::move(path)) {}
  std::filesystem::path path_;
};

// Clears the "file is open for writing" flags that a killed writer leaves in a
// latest-format file, so that any reader opens it, and extends the end of
// allocation over data the writer wrote after its last superblock update
// (what `h5clear -s --increment=0` does).
void clear_status_flags(const std::filesystem::path& path);

// HDF5's current error stack as text, outermost call first; clears it.
[[nodiscard]] std::string take_error_stack();

}  // namespace sabo::io::hdf5
