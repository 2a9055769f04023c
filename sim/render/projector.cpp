#include "sim/render/projector.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace sim {

Projector::Projector(const ProjectorSpec& spec, pattern::MArray pattern) : spec_(spec), pattern_(std::move(pattern)) {
  lit_.assign(pattern_.cells.size(), spec_.only_spots.empty());
  for (const auto& [r, c] : spec_.only_spots) {
    if (r < 0 || r >= pattern_.rows || c < 0 || c >= pattern_.cols)
      throw std::invalid_argument("projector: only_spots entry (" + std::to_string(r) + ", " + std::to_string(c) +
                                  ") is outside the " + std::to_string(pattern_.rows) + " x " +
                                  std::to_string(pattern_.cols) + " pattern");
    lit_[static_cast<std::size_t>(r) * pattern_.cols + c] = true;
  }
}

Eigen::Vector2d Projector::spot_pixel(int row, int col) const {
  const Intrinsics& k = spec_.intrinsics;
  return {k.cx + (col - 0.5 * (pattern_.cols - 1)) * spec_.spot_pitch_px,
          k.cy + (row - 0.5 * (pattern_.rows - 1)) * spec_.spot_pitch_px};
}

Eigen::Vector3d Projector::ray_w(const Eigen::Vector2d& px) const {
  const Intrinsics& k = spec_.intrinsics;
  const Eigen::Vector3d d_p((px.x() - k.cx) / k.fx, (px.y() - k.cy) / k.fy, 1.0);
  return (spec_.world_T_projector.linear() * d_p).normalized();
}

namespace {
constexpr double kRange = 50.0;  // metres: far beyond any cell
}

void Projector::recast(SpotHit& h, const MovingMeshes& meshes, const std::vector<Eigen::Isometry3d>& poses,
                       int object_offset) const {
  const Eigen::Vector3d origin = spec_.world_T_projector.translation();
  const auto cast = [&](const Eigen::Vector2d& px, std::optional<RayHit>& hit) {
    auto a = meshes.ray_test(poses, origin, origin + kRange * ray_w(px));
    if (!a || (hit && hit->fraction <= a->fraction)) return;
    a->object += object_offset;
    hit = a;
  };
  const Eigen::Vector2d centre = spot_pixel(h.row, h.col);
  cast(centre, h.centre);
  for (int i = 0; i < kRimSamples && i < static_cast<int>(h.rim.size()); ++i) {
    const double a = 2.0 * M_PI * i / kRimSamples;
    cast(centre + spec_.spot_radius_px * Eigen::Vector2d(std::cos(a), std::sin(a)), h.rim[static_cast<std::size_t>(i)]);
  }
}

std::vector<SpotHit> Projector::cast_spots(const World& world) const {
  const Eigen::Vector3d origin = spec_.world_T_projector.translation();
  std::vector<SpotHit> hits;
  for (int r = 0; r < pattern_.rows; ++r)
    for (int c = 0; c < pattern_.cols; ++c) {
      if (!is_lit(r, c)) continue;
      SpotHit h;
      h.row = r;
      h.col = c;
      h.symbol = pattern_.at(r, c);
      const Eigen::Vector2d centre = spot_pixel(r, c);
      h.centre = world.ray_test(origin, origin + kRange * ray_w(centre));
      h.rim.reserve(kRimSamples);
      for (int i = 0; i < kRimSamples; ++i) {
        const double a = 2.0 * M_PI * i / kRimSamples;
        const Eigen::Vector2d rim = centre + spec_.spot_radius_px * Eigen::Vector2d(std::cos(a), std::sin(a));
        h.rim.push_back(world.ray_test(origin, origin + kRange * ray_w(rim)));
      }
      hits.push_back(std::move(h));
    }
  return hits;
}

}  // namespace sim
