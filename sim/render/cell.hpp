// A robot cell built from a scenario: the world, the projector and what it lights, the
// camera's lens. Everything a frame depends on except the camera pose.
#pragma once

#include <algorithm>
#include <memory>
#include <optional>
#include <vector>

#include "sim/robot/robot.hpp"
#include "sim/render/camera_model.hpp"
#include "sim/render/projector.hpp"
#include "sim/render/rasterizer.hpp"
#include "sim/render/texturing.hpp"
#include "sim/scenario/scenario.hpp"
#include "sim/scene/world.hpp"

namespace sim {

// The projector pixels whose light the shading kernel takes: the depth buffer's window `w`
// (inclusive cells) less its margin, each cell's pixel from -0.5 to +0.5 about its centre
// (the kernel rounds a point's projector coordinates to the nearest cell).
inline Eigen::AlignedBox2d beam_pixels(const RasterClip& w, int margin) {
  return {Eigen::Vector2d(w.x0 - margin - 0.5, w.y0 - margin - 0.5), Eigen::Vector2d(w.x1 - margin + 0.5, w.y1 - margin + 0.5)};
}

// How far `box` lies beyond `window` along an axis (its largest gap; 0 or less: they overlap).
inline double gap_beyond(const Eigen::AlignedBox2d& box, const Eigen::AlignedBox2d& window) {
  return std::max({window.min().x() - box.max().x(), box.min().x() - window.max().x(), window.min().y() - box.max().y(),
                   box.min().y() - window.max().y()});
}

// What the projector lights from where it stands: its view of the static scene (its shadow
// map), the window of it its spots reach, and its spots' hits. A static projector's is the
// cell's, computed once; one riding on the camera (ProjectorSpec::on_camera) has one per frame
// (light_at).
struct Light {
  std::shared_ptr<const Projector> projector;  // at this light's pose
  DepthBuffer projector_depth;
  // The window of the projector's depth buffer (inclusive cells) its spots can light: the
  // pattern's extent widened by the farthest a blurred spot reaches. The renderer reads the
  // depth only there (a copy, `beam_depth`, small enough to stay in the core's cache).
  RasterClip beam;
  std::vector<float> beam_depth;
  // Per static triangle, 1 where its plane is never in the static scene's shadow: at every
  // cell of beam_depth, the nearest surface lies no more than 0.1 % before the plane, wherever
  // in the cell's +-0.51 px box a point of the plane falls. The shading kernel's test could not
  // darken a point of it, so the renderer skips that lookup (see never_shadowed_planes).
  std::vector<std::uint8_t> never_shadowed;
  // Per static triangle, how far its image on the projector's plane lies beyond the pixels
  // whose light the beam window holds (projector pixels, along an axis; 0: it reaches them, or
  // some of it is behind the projector). Only a triangle more than a pixel away can lie
  // outside the beam in a frame (renderer: outside_beam).
  std::vector<float> beam_gap;
  std::vector<SpotHit> spot_hits;
  double farthest_spot_m = 0;  // the farthest centre hit from the projector (bounds the blur)
  // where the camera stood when this light was made (a light on the camera: light_at reuses it
  // for the same pose); with_depth: the depth buffer and its tables are there, not only the hits
  std::optional<Eigen::Isometry3d> at;
  bool with_depth = false;
};

struct Cell {
  explicit Cell(ResolvedScenario s) : scenario(std::move(s)) {}
  const ResolvedScenario scenario;
  World world;
  SceneTriangles triangles;
  TexturePool textures;  // the objects' textures, for the shading kernel
  // the projector at the scenario's pose (on the camera: where it stands at the desired pose)
  std::shared_ptr<Projector> projector;
  std::unique_ptr<CameraModel> camera;
  // the static projector's light (on the camera: the light at the desired pose)
  Light light;
  int camera_margin_px = 0;  // how far beyond the ideal frame the distorted lens sees
  // for each camera pixel, the z-buffer cell its ray passes through (-1: none), in double
  // precision: the previous renderer's (tests/support/previous_renderer), kept as the baseline;
  // the renderer reads Lens::zcell
  std::vector<std::int32_t> pixel_to_zbuffer;
  // the rays laid out for the shading kernel (shading.hpp): rows padded to `stride` pixels (a
  // multiple of 16), x and y apart, NaN in the padding
  struct Lens {
    int stride = 0;
    std::vector<float> ray_x, ray_y;
    std::vector<int> zrow_lo, zrow_hi;  // per image row, the z-buffer rows its pixels look up (lo > hi: none)
    // per pixel (stride x height), the z-buffer cell its ray looks up, -1: none: column
    // floor(x fx + cx'), row floor(y fy + cy') in single precision, computed once; per 16
    // pixels of a row (stride / 16 x height), the least of their cells when all lie within 32
    // of it, else -1
    std::vector<std::int32_t> zcell, zrun;
  } lens;
  // each spot's pattern symbol, row-major; shading::kUnlitSymbol where the projector leaves it dark
  std::vector<std::int32_t> spot_symbol;
  // unit-variance Gaussian samples drawn once from the scenario seed; each frame reads them in
  // runs of 64 at seeded random offsets (one load per pixel value instead of a draw). 256 kB:
  // it stays in the core's cache
  std::vector<float> noise_pool;
  // the arm's link meshes in their link frames (none for the free-flying camera); a frame
  // places them with the robot's link poses (ArmRobot::world_T_links order)
  MovingMeshes arm_meshes;
  std::vector<std::string> object_names;
  // a projector on the camera: the plane its spots light from the desired pose, the goal the
  // camera is judged against (sim::goal_error); none for a static projector
  std::optional<GoalPlane> goal_plane;
};

// The renderer's own tables of a cell whose world, projector and camera are in place (what
// sim::build_cell, sim/cell, loads): the projector's view of the static scene and its beam
// window, the lens laid out for the shading kernel, the spots' symbols, the noise pool.
void prepare_rendering(Cell& cell);

// The light of a frame whose camera stands at world_T_camera: the cell's own for a static
// projector; for one on the camera, `scratch` made for that pose (kept while the pose is the
// same). `with_depth` false: the spots' hits alone (what the truth needs).
const Light& light_at(const Cell& cell, const Eigen::Isometry3d& world_T_camera, Light& scratch, bool with_depth);

}  // namespace sim
