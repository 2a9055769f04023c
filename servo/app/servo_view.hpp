// `servo view`: the camera image with the decoded ids drawn on it, live. In an OpenCV window
// when a display is there, otherwise (or with --output) a PNG sequence.
#pragma once

#include "dds/participant.hpp"

#include <filesystem>

namespace servo {

struct ViewOptions {
  int domain_id = 0;
  cell_dds::Discovery discovery;
  cell_dds::Security security;  // ROS 2's ROS_SECURITY_* variables
  std::string ns;  // ROS 2 namespace of the cell's topics (--namespace); empty: none  // the range and static peers (ROS 2's variables, or the flags)
  std::filesystem::path output;  // PNG sequence here (headless); empty: a window if possible
  long frames = 0;               // stop after this many frames (0: until SIGINT / window closed)
  int every = 1;                 // keep one frame in `every`
};

int run_viewer(const ViewOptions& options);

}  // namespace servo
