// Scenarios for benchmarks: a shipped scenario with a denser pattern over the same projected
// extent, or a bigger sensor over the same field of view.
#pragma once

#include <filesystem>
#include <string>

#include "sim/cell/build_cell.hpp"
#include "servo/pattern/pattern_file.hpp"
#include "sim/scenario/scenario.hpp"

namespace bench {

inline sim::Scenario scaled_scenario(const std::string& name, int pattern_size, double image_scale) {
  sim::Scenario s = sim::load_scenario(std::string(CELL_SOURCE_DIR) + "/sim/scenarios/" + name + ".yaml");
  if (pattern_size != 20) {
    pattern::GenerationOptions p;
    p.rows = p.cols = pattern_size;
    const auto path = std::filesystem::temp_directory_path() / ("bench_pattern_" + std::to_string(pattern_size) + ".txt");
    pattern::write_marray(path, *pattern::generate_marray(p).array);
    s.projector.pattern = path;
    s.projector.spot_pitch_px *= 20.0 / pattern_size;
    s.projector.spot_radius_px *= 20.0 / pattern_size;
  }
  if (image_scale != 1.0) {
    auto& k = s.camera.intrinsics;
    k.width = static_cast<int>(k.width * image_scale);
    k.height = static_cast<int>(k.height * image_scale);
    k.fx *= image_scale;
    k.fy *= image_scale;
    k.cx = 0.5 * (k.width - 1);
    k.cy = 0.5 * (k.height - 1);
  }
  return s;
}

}  // namespace bench
