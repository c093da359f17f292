#pragma once
// Whole arrays in and out of an HDF5 group: what the contact pairs' histories
// are made of in a checkpoint (the helpers live with the checkpoint files).
#include "libsabo/io/checkpoint.hpp"

namespace sabo::coupler {

using io::read_array;
using io::write_array;

}  // namespace sabo::coupler
