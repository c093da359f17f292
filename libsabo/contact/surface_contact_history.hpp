#pragma once
// The carried state of a contact::SurfaceContact (its tangential springs, normal offsets, rolling springs,
// merged features and largest radius seen) in and out of an HDF5 group, for checkpoints: the coupler's
// particle-surface pairs and the fem_solver's structure contact store it alike.
#include "libsabo/contact/surface_contact.hpp"
#include "libsabo/io/hdf5.hpp"

namespace sabo::contact {

// Attribute max_radius_seen and the datasets spring_* and merged_* of `group`.
void write_history(io::hdf5::Group& group, const SurfaceContact::History& history);
// Throws FileError naming the group when the arrays disagree in length or a feature kind is unknown
// (and sabo::LibraryError when a dataset is missing).
[[nodiscard]] SurfaceContact::History read_history(const io::hdf5::Group& group);

}  // namespace sabo::contact
