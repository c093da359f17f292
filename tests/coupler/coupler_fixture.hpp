#pragma once
// The coupler run in-process against solvers the test scripts: a scratch
// folder, an ipc endpoint in it, a scene without bodies (the tests add theirs)
// and the coupler's event stream captured.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "coupler/coupler.hpp"

namespace sabo::testing {

struct CouplerFixture : ::testing::Test {
  std::filesystem::path dir;
  std::string endpoint;
  scene::Scene scene;
  std::FILE* events_file = nullptr;
  coupler::ConnectionLimits connection_limits;  // the coupler's, for peers that do not register

  void SetUp() override {
    dir = std::filesystem::temp_directory_path() / ("sabo-coupler-" + std::to_string(::getpid()) + "-" +
                                                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    endpoint = "ipc://" + (dir / "c.sock").string();
    scene.file = dir / "scene.toml";
    std::ofstream(scene.file) << "# test scene\n";
    scene.recording.enabled = false;
    events_file = std::tmpfile();
  }
  void TearDown() override {
    std::fclose(events_file);
    std::filesystem::remove_all(dir);
  }

  std::future<int> start_coupler() {
    return std::async(std::launch::async, [this] {
      coupler::EventStream events(events_file);
      coupler::CouplerOptions options;
      options.endpoint = endpoint;
      options.out_dir = dir;
      options.registration_timeout = std::chrono::milliseconds(3000);
      options.connections = connection_limits;
      coupler::Coupler c(scene, options, events);
      return c.run();
    });
  }

  std::vector<nlohmann::json> events() const {
    std::fflush(events_file);
    std::rewind(events_file);
    std::vector<nlohmann::json> out;
    char line[4096];
    while (std::fgets(line, sizeof line, events_file) != nullptr) out.push_back(nlohmann::json::parse(line));
    return out;
  }

  // The run's first error event (printed), or an empty object when there is none.
  nlohmann::json first_error() const {
    for (const auto& event : events()) {
      if (event["event"] != "error") continue;
      std::cout << "error event: " << event.dump() << "\n";
      return event;
    }
    return nlohmann::json::object();
  }
};

}  // namespace sabo::testing
