#pragma once
// What traffic.h5's recorder (traffic.cpp) and reader (traffic_reader.cpp) agree on beyond docs/traffic.md's
// layout: the format's name and version attributes and the bits of a StepForces record's flags.
#include <cstdint>

namespace sabo::io::traffic_format {

constexpr std::int64_t kFormatVersion = 1;
constexpr const char* kFormatName = "sabo-traffic";

constexpr std::uint8_t kFlagCheckpoint = 1;
constexpr std::uint8_t kFlagOutput = 2;
constexpr std::uint8_t kFlagStop = 4;
constexpr std::uint8_t kFlagInterestAll = 8;
// Bits 4-7: log2 of StepForces.substeps (multirate; 0: one step, as in recordings made before it).
constexpr int kSubstepsShift = 4;
constexpr std::uint32_t kMaxRecordedSubsteps = 1u << 15;

}  // namespace sabo::io::traffic_format
