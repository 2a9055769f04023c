// One frame's light and sensor, pixel by pixel, in single precision: the part of rendering
// that runs over every pixel (render_image prepares this plain data from the cell and the pose).
//
// Per pixel, with d = (x, y, 1) the pixel's ray in the camera frame and t the triangle the
// z-buffer puts behind it:
//   s = G_t . d = 1 / z_c             (G_t: the triangle's camera-frame plane, n / offset)
//   h = M d + m s                     (X_p s: the point in the projector's frame, times s;
//                                      M, m: the camera-to-projector pose with the projector's
//                                      intrinsics folded in, the same for every pixel)
//   u_p = h_0 / h_2, v_p = h_1 / h_2, z_p = h_2 / s
//   the camera pixel seen on the projector's plane: k / h_2
//   returned light: K_t / |L|^3, L the point-to-projector vector (K_t: albedo x brightness x
//                   |n.(P - X)| x focus distance^2, constant on a plane)
// So a triangle is five numbers per frame (G_t, its ambient, K_t), prepared in double precision.
// The spots that can reach the point are found on the projector's regular grid, not by boxes
// in the image: a point of the projector's plane lies within reach of at most one spot when
// the spots are focused, a few when blurred.
//
// The same arithmetic, operation for operation, runs one pixel at a time, eight (AVX2) or
// sixteen (AVX-512): every path gives the same bytes (tests hold them to it).
#pragma once

#include <cstddef>
#include <cstdint>

namespace sim::shading {

// A triangle's prepared numbers: field k of triangle t at triangles[k * triangle_stride(n) + t],
// n triangles (field by field, each padded: the lanes of a tessellated surface read
// neighbouring planes' numbers with two loads and one permutation per field).
enum TriangleField {
  kG0, kG1, kG2,  // s = G . d = 1 / z_c
  kAmbient,       // ambient light it returns (ambient x albedo)
  kReturn,        // K above; -K where the plane is never in the static scene's shadow
  kTriangleFields
};
// a field's length for n triangles: 32 beyond the last, so that a run of 32 from any triangle
// can be loaded
constexpr std::size_t triangle_stride(std::size_t n) { return n + 32; }

// A textured triangle's prepared numbers (sim/render/texturing.hpp), laid out as the
// triangles' fields: its plane's G (1/z = G . r for the pixel's ray r), then the texture
// coordinates u = (A_u . r) / (G . r) + k_u and v likewise.
enum TextureField { kTexG0, kTexG1, kTexG2, kTexAu0, kTexAu1, kTexAu2, kTexKu, kTexAv0, kTexAv1, kTexAv2, kTexKv, kTextureFields };
constexpr int kSymbolLut = 16;       // colour tables' entries; kUnlitSymbol has colour 0
constexpr int kUnlitSymbol = 15;
constexpr int kNoiseChunk = 64;      // pixels per noise run
// a noise run's offset hashes (row, channel, chunk) with the seed: key times kNoiseKeyScale,
// then splitmix64's finaliser (its two multipliers)
constexpr std::uint64_t kNoiseKeyScale = 0x9E3779B97F4A7C15ull;
constexpr std::uint64_t kMix1 = 0xBF58476D1CE4E5B9ull, kMix2 = 0x94D049BB133111EBull;
constexpr int kMaxSpotsAway = 8;     // a point takes the light of spots at most this many pitches away
constexpr int kEdgeSegments = 32;
constexpr float kEdgeReach = 4.0f;   // 0.5 erfc(4 / sqrt 2) = 3e-5: nothing beyond

// The projector's depth (1 / z, 0 where nothing) over the window of its image that its spots
// can light: projector pixel (x, y) at (x + offset_x, y + offset_y) of the window. Beyond the
// window no spot's light reaches (Light::beam), so nothing there is lit.
struct DepthView {
  const float* inv_depth = nullptr;
  int width = 0, height = 0, offset_x = 0, offset_y = 0;
};

struct Frame {
  // the image
  int width = 0, height = 0;
  int stride = 0;                      // width rounded up to a multiple of 16
  const float* ray_x = nullptr;        // stride x height: the pixel's ray (x, y, 1), camera frame
  const float* ray_y = nullptr;        // (NaN in the padding)
  // the z-buffer cell each pixel's ray looks up, -1: none; per 16 pixels, the least of their
  // cells when all lie within 32 of it, else -1 (Cell::Lens::zcell, zrun)
  const std::int32_t* zcell = nullptr;
  const std::int32_t* zrun = nullptr;
  // the z-buffer: triangle per cell (-1: none), from cell `cell_base` of the whole buffer on
  // (a band of it), `cells` of them
  const std::int32_t* cell_triangle = nullptr;
  std::int64_t cell_base = 0;
  std::size_t cells = 0;
  const float* triangles = nullptr;    // kTriangleFields x triangle_stride(triangle_count)
  // a coloured surface's channels: 3 x triangle_stride(triangle_count), each channel's share of
  // the triangle's albedo (the ambient and K above carry its brightest channel's); null where
  // every surface is grey
  const float* tint = nullptr;
  // textured surfaces, null where none is: kTextureFields x triangle_stride(triangle_count);
  // texel: 3 x the same, each triangle's texture (its first texel in `texels`, -1: untextured;
  // its width; its height); texels: every texture's R, G and B planes, rows from the top
  const float* texture_map = nullptr;
  const std::int32_t* texel = nullptr;
  const float* texels = nullptr;
  std::size_t triangle_count = 0;
  // ids from here on: a plane's triangles outside the projector's beam this frame (their
  // numbers: the ambient light, G = 0); the kernel gives their pixels the ambient light alone
  std::int32_t outside_from = INT32_MAX;
  // the projector
  DepthView projector_depth, arm_depth;  // arm_depth.inv_depth null: no arm in the beam
  float focused_blur = 0, defocus_per_m = 0, focus_near = 0, focus_far = 0;
  float pixel_scale = 0;               // projector focal / camera focal
  float radius = 0;                    // spot radius, projector pixels
  float grid_x0 = 0, grid_y0 = 0, pitch = 0, inv_pitch = 0;  // spot (r, c) at (x0 + c p, y0 + r p)
  int rows = 0, cols = 0;
  const std::int32_t* spot_symbol = nullptr;  // rows x cols; kUnlitSymbol where not lit
  const float* colour_r = nullptr;     // kSymbolLut entries each
  const float* colour_g = nullptr;
  const float* colour_b = nullptr;
  // 0.5 erfc(x / sqrt 2), the blurred disc's edge profile, as kEdgeSegments cubics over
  // [-kEdgeReach, kEdgeReach): segment k's coefficients edge[j][k], p = c0 + t (c1 + t (c2 + t c3))
  const float* edge[4] = {};
  // true: the projector casts white over its beam window instead of its spots (the
  // reference frame a real cell takes between two pattern frames: the surface's albedo per
  // channel, lit as the spots are)
  bool white = false;
  float qx = 0, qy = 0, qz = 0;        // the projector's centre, camera frame
  float m[3][4] = {};                  // rows: (M_k0, M_k1, M_k2, m_k) above
  // the sensor
  float gain = 0, read_var = 0, shot = 0;
  bool noisy = false;
  const float* noise_pool = nullptr;   // unit Gaussian samples
  std::uint32_t noise_span = 1;        // offsets drawn in [0, noise_span)
  std::uint64_t noise_seed = 0;
};

// Rows [v0, v1) of the image into `image` (RGB8, `step` bytes per row). `scratch`: room for
// kRowArrays x stride floats, the caller's (one per thread).
constexpr int kRowArrays = 8;
void shade_rows_scalar(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch);
void shade_rows_avx2(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch);
void shade_rows_avx512(const Frame& f, int v0, int v1, std::uint8_t* image, std::size_t step, float* scratch);

}  // namespace sim::shading
