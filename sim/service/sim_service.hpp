// The `cellsim serve` service: the simulated cell on DDS. It publishes the camera's images,
// camera info, clock and ground truth, applies the servo's twists, and obeys rt/sim/control.
#pragma once

#include "dds/participant.hpp"

#include <filesystem>
#include <string>

namespace sim {

enum class TimingMode { kLockstep, kRealtime };

struct ServiceOptions {
  std::filesystem::path scenario;
  TimingMode mode = TimingMode::kLockstep;
  int domain_id = 0;
  cell_dds::Discovery discovery;
  cell_dds::Security security;  // ROS 2's ROS_SECURITY_* variables
  std::string ns;  // ROS 2 namespace of the cell's topics (--namespace); empty: none  // the range and static peers (ROS 2's variables, or the flags)
  double watchdog_ms = 100;     // no valid twist for this long: the robot stops
  double republish_ms = 1000;   // lockstep: frame k sent again when unanswered this long
  bool autorun = false;         // teach, go to the initial pose and start on its own
  long max_frames = 0;          // stop after this many frames (0: no limit)
  bool exit_on_converged = false;
  bool exit_on_stop = false;  // also on a servo that stopped itself or a robot stop (sim::SessionEnd)
  std::filesystem::path trace_dir;  // trace.csv of the run (lockstep: one row per step)
  // LOAD_SCENARIO (a remote peer's command) reads scenario files only from under this folder,
  // links resolved; empty: the folder of `scenario` (--scenarios DIR)
  std::filesystem::path scenarios_dir;
  // --record FILE.mcap: every message on the wire, as a ROS 2 bag (record/recorder.hpp)
  std::filesystem::path record;
  bool record_images = true;  // false: --record-no-images
  // --white-frame: beside each frame the white reference frame (the projector casting white,
  // its own noise draw), on rt/camera/white/image_raw with the frame's stamp, before its image
  bool white_frame = false;
  double white_frame_lead = 0;  // taken this share of a frame period before it (sim::WhiteFramePose)
  // --foxglove PORT: the run live in Foxglove on ws://127.0.0.1:PORT (foxglove/bridge.hpp; 0: a
  // free port, printed); -1: off
  int foxglove_port = -1;
  std::string foxglove_address = "127.0.0.1";  // foxglove::ServerOptions::address
};

// Runs until SIGINT/SIGTERM, max_frames or convergence (with exit_on_converged). Returns the
// process exit code; throws for a bad scenario or a DDS failure.
int run_sim_service(const ServiceOptions& options);

}  // namespace sim
