#pragma once
// What traffic.h5's recorder (traffic.cpp) and reader (traffic_reader.cpp) agree on beyond docs/traffic.md's
// layout: the format's name and version attributes and the bits of a StepForces record's flags.
#include <cstdint>

namespace sabo::io::traffic_format {

// Version 3: hold exchanges (StepState.held, StepForces.holds in their own columns, StepForces.hold a flag).
// Version 2: StepForces.substeps in its own column (any whole number). Version 1 kept its log2 in bits 4-7 of
// the flags (powers of two only); the reader reads all three.
constexpr std::int64_t kFormatVersion = 3;
constexpr std::int64_t kOldestReadVersion = 1;
// The first version with the substeps column.
constexpr std::int64_t kSubstepsColumnVersion = 2;
// The first version with the hold columns.
constexpr std::int64_t kHoldColumnsVersion = 3;
constexpr const char* kFormatName = "sabo-traffic";

constexpr std::uint8_t kFlagCheckpoint = 1;
constexpr std::uint8_t kFlagOutput = 2;
constexpr std::uint8_t kFlagStop = 4;
constexpr std::uint8_t kFlagInterestAll = 8;
// Version 3 on (bits 4-7 held version 1's substeps): StepForces.hold.
constexpr std::uint8_t kFlagHold = 16;
// Version 1 only: bits 4-7 of the flags, log2 of StepForces.substeps (0: one step).
constexpr int kVersion1SubstepsShift = 4;
// The substeps and holds columns are bytes.
constexpr std::uint32_t kMaxRecordedSubsteps = 255;
constexpr std::uint32_t kMaxRecordedHolds = 255;

}  // namespace sabo::io::traffic_format
