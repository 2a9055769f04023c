// The servo's states as cell_msgs/ServoStatus carries them, one enum for the servo's state
// machine (which sets them) and the cell's (which acts on CONVERGED and STOPPED). Plain C++,
// no DDS; dds/topics.cpp checks it against the generated constants, as it does SimCommand.
#pragma once

#include <cstdint>

namespace cell_dds {

enum class ServoState : std::uint8_t { kIdle = 0, kTeaching = 1, kServoing = 2, kConverged = 3, kLost = 4, kStopped = 5 };

// the state as cell_msgs/ServoStatus.state carries it
constexpr std::uint8_t to_wire(ServoState s) { return static_cast<std::uint8_t>(s); }

}  // namespace cell_dds
