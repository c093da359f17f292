#pragma once
// Conversions from received messages to the contact kernels' inputs.
#include <vector>

#include "libsabo/contact/surface_contact.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::coupler {

// Gathers the static attributes (id, radius, mass, body) of the particles a
// StepState lists, next to the state's own arrays, into one contact::ParticleView.
// Buffers are kept between steps.
class ParticleGather {
 public:
  void gather(const sabo::v1::ParticleTable& table, const sabo::v1::StepState& state);
  [[nodiscard]] const contact::ParticleView& view() const { return view_; }

 private:
  std::vector<std::uint64_t> id_;
  std::vector<double> radius_, mass_;
  std::vector<std::uint32_t> body_;
  contact::ParticleView view_;
};

}  // namespace sabo::coupler
