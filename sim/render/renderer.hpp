// The camera's image of the cell: what a colour camera on the end-effector would see of the
// projected pattern. A pure function of the cell, the camera pose and a noise seed.
//
// Per pixel: the ray through the (distorted) lens meets the nearest surface (z-buffer);
// the surface point is projected into the projector (projective texturing, as the projector
// is an inverse camera) and lit if the projector sees it (shadow map); the spot disc it falls
// in gives colour x albedo x incidence cosine x inverse-square falloff, blurred by the
// projector's defocus at that depth; dim ambient light shows the scene; the sensor adds
// channel crosstalk, exposure, read and shot noise, and 8-bit quantisation.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "sim/render/cell.hpp"
#include "sim/render/texturing.hpp"

namespace sim {

// Where the arm's links are in one frame (ArmRobot::world_T_links); null or empty: no arm.
using LinkPoses = std::vector<Eigen::Isometry3d>;

// The scene of one frame: the cell's static parts, and the arm's links where they are
// (their triangles, the spots they catch, their shadow in the projector's depth map).
struct FrameScene {
  const SceneTriangles* triangles = nullptr;
  const std::vector<SpotHit>* spot_hits = nullptr;
  const DepthBuffer* projector_depth = nullptr;      // the static scene's, from the projector
  const DepthBuffer* arm_projector_depth = nullptr;  // the arm's alone (null: not in the beam)
  bool arm_in_beam = false;
};
struct ArmFrameBuffers {
  SceneTriangles triangles;
  std::vector<SpotHit> spot_hits;
  // the arm seen from the projector, over a buffer the size of the static one; only the
  // region the arm covered last frame is cleared (copying the static buffer each frame cost
  // more than the rest of the arm's rendering)
  DepthBuffer arm_projector_depth;
  int dirty_u0 = 0, dirty_v0 = 0, dirty_u1 = -1, dirty_v1 = -1;
  bool scalar = false;  // rasterise without the vector unit (see rasterize)
};
// The arm's triangles are added when `with_triangles` (rendering), the spots' hits on it when
// `with_hits` (the ground truth).
// `light`: the frame's (light_at).
FrameScene pose_scene(const Cell& cell, const Light& light, const LinkPoses* links, ArmFrameBuffers& buffers,
                      bool with_triangles, bool with_hits);

// Buffers reused from frame to frame (pass the same one to avoid reallocating).
struct RenderScratch {
  ArmFrameBuffers arm;
  std::vector<ScreenTriangle> screen;  // the frame's triangles on the camera's image plane
  std::vector<std::vector<std::int32_t>> band_screen;  // per band of rows: the ones its z-buffer rows meet
  std::vector<float> triangles;  // each triangle's vectors for this pose (shading.hpp)
  std::vector<float> tint;       // each triangle's colour (Frame::tint), when a surface is coloured
  TextureFrame texture;          // each textured triangle's map (Frame::texture_map), when one is
  std::vector<float> arm_beam_depth;  // the arm's projector depth over Light::beam
  // true: the scalar path even where the CPU has AVX2 (tests hold the two to the same bits)
  bool scalar = false;
  // false: the AVX2 path even where the CPU has AVX-512 (the same bits again)
  bool avx512 = true;
  // false: the projector's depth looked up for every lit point, also where Light::never_shadowed
  // says no shadow can fall (the same bits: tests hold the two to each other)
  bool skip_unshadowed = true;
  // false: every pixel's surface point projected into the projector, also where outside_beam
  // says it lies outside the beam (the same bits: tests hold the two to each other)
  bool skip_outside_beam = true;
  std::vector<std::uint8_t> outside;  // outside_beam's flags for this frame
  Light light;  // a projector on the camera: its light at this frame's pose (light_at)
  // 0: the rows are shared out over OpenCV's thread pool (as many threads as cv::setNumThreads
  // allows); 1: all on the calling thread (a campaign's runs, one thread each)
  int threads = 0;
};

// RGB8 image (channel order R, G, B), camera resolution. `noise_seed` fixes every random
// draw of the frame: the same seed gives a byte-identical image.
// `sensor`, when given, replaces the scenario camera's exposure, ambient, noise and crosstalk
// (its intrinsics must be the scenario's): studies over noise levels use it.
// `links`: the arm's link poses in this frame (drawn, lit, casting shadows).
// `cast`: what the projector shows. kWhite is the reference frame a cell takes beside a
// pattern frame (servo/vision/reference.hpp): white wherever a spot's light can reach (the beam
// window: the pattern's extent widened by a blurred spot's reach), so each pixel
// gives its surface's albedo per channel as the spots light it.
enum class Cast { kPattern, kWhite };
cv::Mat render_image(const Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t noise_seed,
                     RenderScratch* scratch = nullptr, const CameraSpec* sensor = nullptr,
                     const LinkPoses* links = nullptr, Cast cast = Cast::kPattern);

// Per static triangle of the cell (Cell::triangles), 1 where no pixel the camera at
// world_T_camera gives it can see a point the projector's beam window reaches (Light::beam): such
// a pixel takes the ambient light alone. Conservative: 0 where that is not certain.
void outside_beam(const Cell& cell, const Light& light, const Eigen::Isometry3d& world_T_camera,
                  std::vector<std::uint8_t>& out);

// Ground truth for one spot (pattern row, col).
struct SpotTruth {
  int row = 0, col = 0;
  bool visible = false;            // lit, facing the camera, unoccluded, inside the image
  bool hidden_by_arm = false;      // lit and facing the camera, but an arm link is in the way
  bool on_arm = false;             // it lands on an arm link (the arm is in the projector's beam)
  int object = -1;                 // what its centre hit lands on: an object of the cell, or (after
                                   // them) an arm link; -1 when it lights nothing
  Eigen::Vector2d uv{0, 0};        // distorted image position of the centre hit (pixels)
  double depth_m = 0;              // Z of the centre hit in the camera frame
  Eigen::Vector3d point_w{0, 0, 0};
  std::vector<Eigen::Vector2d> footprint_px;  // projected rim hits on the same object
  // The projector's defocus blur where the spot lands (sigma, projector pixels), and whether
  // that blur leaves it a spot: far outside the focus range neighbouring spots wash into one
  // another (the light between two of them stays above 40 % of their peak), and no decoder
  // can tell them apart however well it sees.
  double blur_px = 0;
  bool resolved = false;  // visible, and not washed out
  // Where any of the spot's light lands in the image, seen or not: the centre and the rim
  // hits on every object. A spot split by a depth edge, or whose centre is hidden, still
  // shows part of its light: a decoder naming that part names the right spot.
  std::vector<Eigen::Vector2d> light_px;
};

// Whether a spot blurred by `blur_px` (projector pixels) still stands apart from its neighbours.
bool spot_resolved(double blur_px, const ProjectorSpec& spec);

// One entry per pattern spot, row-major. Visibility from a Bullet ray from the camera to
// the spot's centre hit.
std::vector<SpotTruth> compute_truth(const Cell& cell, const Eigen::Isometry3d& world_T_camera,
                                     const LinkPoses* links = nullptr);

// Mixes a frame index into a scenario seed (splitmix64), for per-frame noise seeds.
std::uint64_t frame_seed(std::uint64_t scenario_seed, std::uint64_t frame);

// The noise seed of the white reference frame taken beside the pattern frame of `pattern_seed`
// (Cast::kWhite): a draw of its own, fixed by the pattern frame's.
std::uint64_t white_frame_seed(std::uint64_t pattern_seed);

}  // namespace sim
