#pragma once
// Whole arrays in and out of an HDF5 group: what the contact pairs' histories
// are made of in a checkpoint.
#include <algorithm>
#include <span>
#include <string>
#include <vector>

#include "libsabo/io/hdf5.hpp"

namespace sabo::coupler {

template <io::hdf5::Element T>
void write_array(io::hdf5::Group& group, const std::string& name, std::span<const T> values) {
  const std::uint64_t chunk = std::clamp<std::uint64_t>(values.size(), 1, 1U << 16);
  auto dataset = group.create_dataset<T>(name, chunk);
  dataset.append(values);
}

template <io::hdf5::Element T>
void write_array(io::hdf5::Group& group, const std::string& name, const std::vector<T>& values) {
  write_array(group, name, std::span<const T>(values));
}

// Throws sabo::LibraryError naming the file and the dataset when it is missing or of another type.
template <io::hdf5::Element T>
[[nodiscard]] std::vector<T> read_array(const io::hdf5::Group& group, const std::string& name) {
  return group.dataset(name).read_all<T>();
}

}  // namespace sabo::coupler
