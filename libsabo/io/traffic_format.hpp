#pragma once
// What traffic.h5's recorder (traffic.cpp) and reader (traffic_reader.cpp) agree on beyond docs/traffic.md's
// layout: the format's name and version attributes and the bits of a StepForces record's flags.
#include <cstdint>

namespace sabo::io::traffic_format {

// Version 2: StepForces.substeps in its own column (any whole number). Version 1 kept its log2 in bits 4-7 of
// the flags (powers of two only); the reader reads both.
constexpr std::int64_t kFormatVersion = 2;
constexpr std::int64_t kOldestReadVersion = 1;
// The first version with the substeps column.
constexpr std::int64_t kSubstepsColumnVersion = 2;
constexpr const char* kFormatName = "sabo-traffic";

constexpr std::uint8_t kFlagCheckpoint = 1;
constexpr std::uint8_t kFlagOutput = 2;
constexpr std::uint8_t kFlagStop = 4;
constexpr std::uint8_t kFlagInterestAll = 8;
// Version 1 only: bits 4-7 of the flags, log2 of StepForces.substeps (0: one step).
constexpr int kVersion1SubstepsShift = 4;
// The substeps column is a byte.
constexpr std::uint32_t kMaxRecordedSubsteps = 255;

}  // namespace sabo::io::traffic_format
