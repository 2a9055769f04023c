// The renderer as it was before issue 22 redefined its images in single precision: double
// precision, every spot shading every pixel of its box in the image from scratch, an 8 MB
// noise pool read in runs of a row. Kept, frozen, as what the renderer is measured against in
// the same run (render_bench) and compared with (tests/unit/sim/render_test.cpp: the same
// frames within a stated tolerance, the same spots decoded).
#pragma once

#include "sim/render/renderer.hpp"

namespace previous {

cv::Mat render_image(const sim::Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     const sim::CameraSpec* sensor = nullptr, const sim::LinkPoses* links = nullptr);

}  // namespace previous
