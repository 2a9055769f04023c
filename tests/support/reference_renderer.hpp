// The renderer in its straightforward form, as it was before issue 22 made it fast: every
// spot shades every pixel of its box from scratch, over a whole-image radiance buffer, one
// thread. sim::render_image is held to it bit for bit (tests/unit/sim/render_test.cpp), and
// render_bench measures against it in the same run.
#pragma once

#include "sim/render/renderer.hpp"

namespace reference {

cv::Mat render_image(const sim::Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     const sim::CameraSpec* sensor = nullptr, const sim::LinkPoses* links = nullptr);

}  // namespace reference
