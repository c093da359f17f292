#include "sph_solver/fronts.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"

namespace sabo::sph {
namespace {

constexpr const char* kFrontsFile = "fronts.csv";
constexpr const char* kStationsFile = "front_stations.csv";

// NaN as JSON null (JSON has no NaN).
nlohmann::json number_or_null(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

}  // namespace

FrontReading read_front(const SphModel& model, const scene::Front& front) {
  const auto positions = model.positions();
  const auto velocities = model.velocities();
  const auto active = model.active();
  const auto offsets = model.wrap_offsets();  // the periodic wrapping undone: a front moves on
  const auto projection = [&](std::size_t i) {
    return front.project(offsets.empty() ? positions[i] : Vec3(positions[i] - offsets[i]));
  };
  const auto distance = [&](std::size_t i) { return projection(i).s; };
  std::vector<std::pair<double, std::uint32_t>> ranked;
  ranked.reserve(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (active.empty() || active[i] != 0) ranked.emplace_back(distance(i), static_cast<std::uint32_t>(i));
  }
  FrontReading reading;
  if (ranked.size() <= front.ahead) return reading;
  // The (ahead + 1)-th largest distance; ties broken by id, so that the same state gives the same particle.
  const auto nth = ranked.begin() + static_cast<std::ptrdiff_t>(front.ahead);
  std::nth_element(ranked.begin(), nth, ranked.end(), std::greater<>());
  reading.position = nth->first;
  reading.point = positions[nth->second];
  const double support = 2.0 * model.kernel().h;
  double speed_sum = 0;
  std::size_t count = 0;
  for (const auto& [s, i] : ranked) {
    if (s <= reading.position && s >= reading.position - support) {
      speed_sum += velocities[i].dot(projection(i).tangent);
      ++count;
    }
  }
  reading.flow_speed = count > 0 ? speed_sum / static_cast<double>(count) : 0.0;
  return reading;
}

FrontRecorder::FrontRecorder(const std::filesystem::path& run_dir, const scene::Scene& scene)
    : fronts_csv_(run_dir / kFrontsFile, "time,front,position,speed,flow_speed,x,y,z", "the fronts' positions"),
      stations_csv_(run_dir / kStationsFile, "time,front,station,at,depth", "the fronts' station depths"),
      fronts_(scene.fronts),
      depth_spacing_(0.25 * scene.sph.particle_spacing) {
  for (const scene::Front& front : fronts_) {
    const std::size_t stations = front.stations.size();
    tracks_.push_back(Track{SampleSchedule(front.interval > 0 ? front.interval : scene.run.output_interval),
                            {},
                            {},
                            {},
                            {},
                            std::vector<double>(stations, std::numeric_limits<double>::quiet_NaN()),
                            std::vector<double>(stations, 0.0),
                            std::vector<double>(stations, 0.0)});
  }
}

void FrontRecorder::sample(const SphModel& model, double time) {
  std::string front_rows, station_rows;
  for (std::size_t f = 0; f < fronts_.size(); ++f) {
    Track& track = tracks_[f];
    if (!track.schedule.due(time)) continue;
    const scene::Front& front = fronts_[f];
    const FrontReading reading = read_front(model, front);
    const bool have_previous = !track.time.empty() && std::isfinite(track.position.back());
    const double speed = have_previous && time > track.time.back()
                             ? (reading.position - track.position.back()) / (time - track.time.back())
                             : 0.0;
    for (std::size_t k = 0; k < front.stations.size(); ++k) {
      const double at = front.stations[k].at;
      if (std::isnan(track.arrival[k]) && reading.position >= at) {
        // Interpolated between the samples on either side of the passage.
        track.arrival[k] = have_previous && track.position.back() < at
                               ? track.time.back() + (time - track.time.back()) * (at - track.position.back()) /
                                                         (reading.position - track.position.back())
                               : time;
      }
      const Vec3 base = front.path_point(at);
      const double depth = surface_distance(model, base, base + front.depth_height * Vec3::UnitZ(), depth_spacing_);
      track.last_depth[k] = depth;
      track.max_depth[k] = std::max(track.max_depth[k], depth);
      station_rows += fmt::format("{:.9g},{},{},{:.9g},{:.9g}\n", time, front.name, front.stations[k].name, at, depth);
    }
    track.time.push_back(time);
    track.position.push_back(reading.position);
    track.speed.push_back(speed);
    track.flow_speed.push_back(reading.flow_speed);
    front_rows +=
        fmt::format("{:.9g},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n", time, front.name, reading.position, speed,
                    reading.flow_speed, reading.point.x(), reading.point.y(), reading.point.z());
  }
  if (!front_rows.empty()) fronts_csv_.append(front_rows);
  if (!station_rows.empty()) stations_csv_.append(station_rows);
}

nlohmann::json FrontRecorder::results() const {
  using nlohmann::json;
  json fronts = json::object();
  for (std::size_t f = 0; f < fronts_.size(); ++f) {
    const scene::Front& front = fronts_[f];
    const Track& track = tracks_[f];
    const std::string path = front.kind == scene::Front::Kind::channel   ? "channel " + front.channel
                             : front.kind == scene::Front::Kind::terrain ? "terrain " + front.structure
                                                                         : std::string("axis");
    json entry = {{"path", path}, {"samples", track.time.size()}};
    double farthest = -std::numeric_limits<double>::infinity(), fastest = 0, fastest_time = 0, fastest_flow = 0;
    for (std::size_t k = 0; k < track.time.size(); ++k) {
      if (std::isfinite(track.position[k])) farthest = std::max(farthest, track.position[k]);
      if (track.speed[k] > fastest) fastest = track.speed[k], fastest_time = track.time[k];
      fastest_flow = std::max(fastest_flow, track.flow_speed[k]);
    }
    entry["final_position"] = track.position.empty() ? json(nullptr) : number_or_null(track.position.back());
    entry["max_position"] = number_or_null(farthest);
    entry["max_speed"] = fastest;
    entry["max_speed_time"] = fastest_time;
    entry["max_flow_speed"] = fastest_flow;
    json position = json::array(), speed = json::array(), flow_speed = json::array();
    for (std::size_t k = 0; k < track.time.size(); ++k) {
      position.push_back(number_or_null(track.position[k]));
      speed.push_back(track.speed[k]);
      flow_speed.push_back(track.flow_speed[k]);
    }
    entry["history"] = {{"time", track.time}, {"position", position}, {"speed", speed}, {"flow_speed", flow_speed}};
    json stations = json::object();
    for (std::size_t k = 0; k < front.stations.size(); ++k) {
      stations[front.stations[k].name] = {{"at", front.stations[k].at},
                                          {"arrival_time", number_or_null(track.arrival[k])},
                                          {"max_depth", track.max_depth[k]},
                                          {"final_depth", track.last_depth[k]}};
    }
    entry["stations"] = stations;
    fronts[front.name] = entry;
  }
  return fronts;
}

void FrontRecorder::save(io::hdf5::Group& group) const {
  if (fronts_.empty()) return;
  io::hdf5::Group out = group.create_group("fronts");
  for (std::size_t f = 0; f < fronts_.size(); ++f) {
    const Track& track = tracks_[f];
    io::hdf5::Group g = out.create_group(std::to_string(f));
    g.set_attribute("next_sample", static_cast<std::int64_t>(track.schedule.next()));
    io::write_array(g, "time", track.time);
    io::write_array(g, "position", track.position);
    io::write_array(g, "speed", track.speed);
    io::write_array(g, "flow_speed", track.flow_speed);
    io::write_array(g, "arrival", track.arrival);
    io::write_array(g, "max_depth", track.max_depth);
    io::write_array(g, "last_depth", track.last_depth);
  }
  fronts_csv_.save(out, "fronts_started", "fronts_csv");
  stations_csv_.save(out, "stations_started", "stations_csv");
}

void FrontRecorder::load(const io::hdf5::Group& group) {
  if (fronts_.empty()) return;
  const auto mismatch = [&](const std::string& what) {
    return FileError(
        fmt::format("{}: {}, while the scene has {} fronts. Fix: restart from a checkpoint of this "
                    "scene, unchanged",
                    group.file_name(), what, fronts_.size()));
  };
  if (!group.exists("fronts")) throw mismatch("no state of the fronts");
  const io::hdf5::Group in = group.group("fronts");
  for (std::size_t f = 0; f < fronts_.size(); ++f) {
    if (!in.exists(std::to_string(f))) throw mismatch(fmt::format("no state of front {}", f));
    const io::hdf5::Group g = in.group(std::to_string(f));
    Track& track = tracks_[f];
    const std::size_t stations = fronts_[f].stations.size();
    track.schedule.set_next(static_cast<std::uint64_t>(g.int_attribute("next_sample")));
    track.time = io::read_array<double>(g, "time");
    track.position = io::read_array<double>(g, "position", track.time.size());
    track.speed = io::read_array<double>(g, "speed", track.time.size());
    track.flow_speed = io::read_array<double>(g, "flow_speed", track.time.size());
    track.arrival = io::read_array<double>(g, "arrival", stations);
    track.max_depth = io::read_array<double>(g, "max_depth", stations);
    track.last_depth = io::read_array<double>(g, "last_depth", stations);
  }
  fronts_csv_.load(in, "fronts_started", "fronts_csv");
  stations_csv_.load(in, "stations_started", "stations_csv");
}

}  // namespace sabo::sph
