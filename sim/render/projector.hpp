// The projector as an inverse pinhole camera (paper §2): each spot of the pattern is a disc
// on its image plane; its light leaves the projector centre through that disc.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <optional>
#include <vector>

#include "servo/pattern/marray.hpp"
#include "sim/scenario/scenario.hpp"
#include "sim/scene/world.hpp"

namespace sim {

// Where one spot's light lands, from Bullet rays through its centre and its rim.
struct SpotHit {
  int row = 0, col = 0;
  int symbol = 0;                    // colour index in the pattern
  std::optional<RayHit> centre;      // the spot's centre ray; empty: it lights nothing
  std::vector<std::optional<RayHit>> rim;  // rays through the disc's rim, counter-clockwise
};

class Projector {
 public:
  static constexpr int kRimSamples = 16;

  Projector(const ProjectorSpec& spec, pattern::MArray pattern);

  // Spot centre on the projector's image plane (pixels); the pattern is centred.
  Eigen::Vector2d spot_pixel(int row, int col) const;
  // Unit ray direction, in the world, through a point of the projector's image plane.
  Eigen::Vector3d ray_w(const Eigen::Vector2d& pixel) const;
  bool is_lit(int row, int col) const { return lit_[static_cast<std::size_t>(row) * pattern_.cols + col]; }

  // Casts every lit spot's centre and rim rays into the world. The projector and the
  // objects are static, so callers cache this until the world changes.
  std::vector<SpotHit> cast_spots(const World& world) const;
  // Casts one spot's rays at moving meshes placed by `poses`; where they hit nearer than the
  // static hit, the hit becomes theirs (object = object_offset + mesh index).
  void recast(SpotHit& hit, const MovingMeshes& meshes, const std::vector<Eigen::Isometry3d>& poses,
              int object_offset) const;

  // Blur (sigma, projector pixels) of the projected image at depth z along the optical axis:
  // the residual blur inside the focus range, growing linearly outside it.
  double defocus_sigma_px(double z_p) const {  // inline: called per lit pixel
    const double outside = std::max({0.0, spec_.focus_near_m - z_p, z_p - spec_.focus_far_m});
    return spec_.focused_blur_px + spec_.defocus_px_per_m * outside;
  }

  const ProjectorSpec& spec() const { return spec_; }
  const pattern::MArray& pattern() const { return pattern_; }
  const Eigen::Isometry3d& world_T_projector() const { return spec_.world_T_projector; }
  Eigen::Isometry3d projector_T_world() const { return spec_.world_T_projector.inverse(); }

 private:
  ProjectorSpec spec_;
  pattern::MArray pattern_;
  std::vector<bool> lit_;
};

}  // namespace sim
