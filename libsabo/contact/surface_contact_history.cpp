#include "libsabo/contact/surface_contact_history.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <span>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"

namespace sabo::contact {

namespace {

template <io::hdf5::Element T>
void write_array(io::hdf5::Group& group, const std::string& name, const std::vector<T>& values) {
  const std::uint64_t chunk = std::clamp<std::uint64_t>(values.size(), 1, 1U << 16);
  auto dataset = group.create_dataset<T>(name, chunk);
  dataset.append(std::span<const T>(values));
}

template <io::hdf5::Element T>
std::vector<T> read_array(const io::hdf5::Group& group, const std::string& name) {
  return group.dataset(name).read_all<T>();
}

}  // namespace

void write_history(io::hdf5::Group& group, const SurfaceContact::History& history) {
  std::vector<std::uint64_t> particle, nodes, merged_particle, merged_nodes;
  std::vector<std::uint8_t> kind, merged_kind;
  std::vector<double> displacement, normal, offset, overlap, rolling;
  for (const auto& e : history.springs) {
    particle.push_back(e.particle);
    kind.push_back(static_cast<std::uint8_t>(e.key.kind));
    nodes.insert(nodes.end(), e.key.node.begin(), e.key.node.end());
    for (int c = 0; c < 3; ++c) {
      displacement.push_back(e.displacement[c]), normal.push_back(e.normal[c]), rolling.push_back(e.rolling_torque[c]);
    }
    offset.push_back(e.normal_offset);
    overlap.push_back(e.spring_overlap);
  }
  for (const auto& e : history.merged) {
    merged_particle.push_back(e.particle);
    merged_kind.push_back(static_cast<std::uint8_t>(e.key.kind));
    merged_nodes.insert(merged_nodes.end(), e.key.node.begin(), e.key.node.end());
  }
  group.set_attribute("max_radius_seen", history.max_radius_seen);
  write_array(group, "spring_particle", particle);
  write_array(group, "spring_feature", kind);
  write_array(group, "spring_nodes", nodes);
  write_array(group, "spring_displacement", displacement);
  write_array(group, "spring_normal", normal);
  write_array(group, "spring_normal_offset", offset);
  write_array(group, "spring_overlap", overlap);
  write_array(group, "spring_rolling_torque", rolling);
  write_array(group, "merged_particle", merged_particle);
  write_array(group, "merged_feature", merged_kind);
  write_array(group, "merged_nodes", merged_nodes);
}

SurfaceContact::History read_history(const io::hdf5::Group& group) {
  SurfaceContact::History history;
  history.max_radius_seen = group.double_attribute("max_radius_seen");
  const auto particle = read_array<std::uint64_t>(group, "spring_particle");
  const auto kind = read_array<std::uint8_t>(group, "spring_feature");
  const auto nodes = read_array<std::uint64_t>(group, "spring_nodes");
  const auto displacement = read_array<double>(group, "spring_displacement");
  const auto normal = read_array<double>(group, "spring_normal");
  const auto offset = read_array<double>(group, "spring_normal_offset");
  const auto overlap = read_array<double>(group, "spring_overlap");
  const auto rolling = read_array<double>(group, "spring_rolling_torque");
  const std::size_t n = particle.size();
  if (kind.size() != n || nodes.size() != 3 * n || displacement.size() != 3 * n || normal.size() != 3 * n ||
      offset.size() != n || overlap.size() != n || rolling.size() != 3 * n) {
    throw FileError(fmt::format("{}: the spring arrays differ in length ({} springs)", group.path(), n));
  }
  const auto feature = [&](std::uint8_t k) {
    if (k > static_cast<std::uint8_t>(Feature::vertex)) {
      throw FileError(fmt::format("{}: feature kind {} is not a face, edge or vertex", group.path(), k));
    }
    return static_cast<Feature>(k);
  };
  for (std::size_t i = 0; i < n; ++i) {
    SurfaceContact::HistoryEntry e;
    e.particle = particle[i];
    e.key.kind = feature(kind[i]);
    e.key.node = {nodes[3 * i], nodes[3 * i + 1], nodes[3 * i + 2]};
    e.displacement = Vec3(displacement[3 * i], displacement[3 * i + 1], displacement[3 * i + 2]);
    e.normal = Vec3(normal[3 * i], normal[3 * i + 1], normal[3 * i + 2]);
    e.normal_offset = offset[i];
    e.spring_overlap = overlap[i];
    e.rolling_torque = Vec3(rolling[3 * i], rolling[3 * i + 1], rolling[3 * i + 2]);
    history.springs.push_back(e);
  }
  const auto merged_particle = read_array<std::uint64_t>(group, "merged_particle");
  const auto merged_kind = read_array<std::uint8_t>(group, "merged_feature");
  const auto merged_nodes = read_array<std::uint64_t>(group, "merged_nodes");
  if (merged_kind.size() != merged_particle.size() || merged_nodes.size() != 3 * merged_particle.size()) {
    throw FileError(fmt::format("{}: the merged-feature arrays differ in length", group.path()));
  }
  for (std::size_t i = 0; i < merged_particle.size(); ++i) {
    history.merged.push_back(
        {merged_particle[i],
         {feature(merged_kind[i]), {merged_nodes[3 * i], merged_nodes[3 * i + 1], merged_nodes[3 * i + 2]}}});
  }
  return history;
}

}  // namespace sabo::contact
