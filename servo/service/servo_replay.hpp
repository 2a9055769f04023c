// `servo replay FILE.mcap`: a recorded run (cellsim serve --record) fed through the servo's
// state machine, message by message in the recording's order: camera_info, the sim status
// and camera pose of each frame, the commands, the images, with the recording's log times
// as the clock. The twists it would have sent are compared with the recorded ones, stamp by
// stamp: an unchanged servo reproduces them bit for bit; another model, law or decoder
// shows what it would have commanded on exactly those frames.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

#include "servo/pipeline/servo_pipeline.hpp"

namespace servo {

// Where the servo's commands come from. The simulator's rt/sim/accepted by default: the
// commands it obeyed, when they took effect. A command published once on rt/sim/control then
// reaches the run whichever reader a client matched first, as there is one (cellsim).
// rt/sim/control itself for a servo beside another simulator or a real robot's driver.
enum class CommandSource { kSimulator, kClients };

struct ReplayOptions {
  std::filesystem::path recording;
  std::filesystem::path pattern;
  ServoConfig config;
  std::filesystem::path reference;  // s* to start from (the run's --reference); empty: taught from the recording
  double lost_ms = 500;
  bool autostart = false;
  CommandSource commands = CommandSource::kSimulator;  // the recorded run's (a recording made
                                                      // before rt/sim/accepted existed: kClients)
  std::filesystem::path output;  // replay.csv (and replay.png); empty: nothing written
  bool plot = true;
};

struct ReplayResult {
  long images = 0;              // recorded images fed to the servo
  bool white_frames = false;    // the recording holds white reference frames (cellsim serve --white-frame)
  long compared = 0;            // recorded twists with a replayed twist of the same stamp
  long differing = 0;           // of those, how many differ in any bit
  double max_difference = 0;    // largest |replayed - recorded| over all components (m/s, rad/s)
  std::optional<double> first_differing_s;  // the stamp of the first that differs (s)
  long recorded_only = 0;       // recorded twists the replay did not answer
  long past_cut = 0;            // of a cut recording: twists whose image lies past its end
  long replayed_only = 0;       // replayed twists the recording does not hold (its writer was not matched yet)
  // LOST notices (no image for --lost-ms: a zero twist at the last image's stamp), sent by the
  // live servo's clock and by the replay's from the log times: counted, never compared (they
  // answer no image, and a loaded machine times them otherwise)
  long lost_recorded = 0, lost_replayed = 0;
  // the recording ends before its footer (its recorder was killed, or the disk filled): where,
  // in one line; what its complete chunks hold was replayed
  std::optional<std::string> truncated;
  // the recording says it stopped before the run ended (the size limit, a full disk): why,
  // printable, at most 300 characters; what it holds was replayed
  std::optional<std::string> stopped;
};

// Throws std::runtime_error (one line naming the file) for a recording that cannot be read
// or a message that does not decode as its topic's type. A truncated recording is replayed
// as far as its complete chunks go, and ReplayResult::truncated says so.
ReplayResult run_replay(const ReplayOptions& options);

}  // namespace servo
