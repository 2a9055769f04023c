// The commands on rt/sim/control (cell_msgs/SimControl's constants), one enum for both
// services' state machines (issue 20: sim::CellCommand and servo::Command were two names for
// it). Plain C++, no DDS: the pure state machines include it; topics.cpp checks it against the
// generated constants.
#pragma once

#include <cstdint>

namespace cell_dds {

enum class SimCommand : std::uint8_t { kLoadScenario = 0, kReset = 1, kTeach = 2, kStart = 3, kPause = 4, kStep = 5 };

}  // namespace cell_dds
