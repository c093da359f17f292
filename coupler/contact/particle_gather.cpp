#include "coupler/contact/particle_gather.hpp"

namespace sabo::coupler {

namespace {
template <class T>
std::span<const T> span_of(const google::protobuf::RepeatedField<T>& field) {
  return {field.data(), static_cast<std::size_t>(field.size())};
}
}  // namespace

void ParticleGather::gather(const sabo::v1::ParticleTable& table, const sabo::v1::StepState& state) {
  const auto n = static_cast<std::size_t>(state.index_size());
  id_.resize(n);
  radius_.resize(n);
  mass_.resize(n);
  body_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto i = static_cast<int>(state.index(static_cast<int>(k)));
    id_[k] = table.id(i);
    radius_[k] = table.radius(i);
    mass_[k] = table.mass(i);
    body_[k] = table.body(i);
  }
  view_.id = id_;
  view_.radius = radius_;
  view_.mass = mass_;
  view_.body = body_;
  view_.position = span_of(state.position());
  view_.velocity = span_of(state.velocity());
  view_.angular_velocity = span_of(state.angular_velocity());
}

}  // namespace sabo::coupler
