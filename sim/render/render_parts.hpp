// The parts of a frame's rendering that the renderer and its reference (tests/support, the
// straightforward per-spot form it is held to, bit for bit) share: where each spot can
// light, the blurred edge of a spot, the spot colours the sensor sees, and the sensor.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

#include "sim/render/cell.hpp"
#include "sim/render/renderer.hpp"

namespace sim::render_parts {

// The image region each spot can light, one box per object its light lands on, in the
// order of `hits`.
void spot_boxes(const Cell& cell, const std::vector<SpotHit>& hits, const Eigen::Isometry3d& c_T_w,
                std::vector<SpotBox>& out);

// 0.5 erfc(x / sqrt 2): the fraction of a Gaussian-blurred edge's light at signed distance x
// (in sigmas) outside it, from a table.
float edge_fraction(double x);

// Spot colours after the sensor's channel crosstalk, per pattern symbol.
std::array<Eigen::Vector3f, 10> spot_colours(const CameraSpec& camera);

// The sensor, one image row: exposure, read and shot noise, 8-bit quantisation of `n`
// linear values (R, G, B interleaved) into `out`. The noise is a run of the cell's pool at an
// offset drawn from the seed and the row, so a row's bytes depend on nothing else.
struct Sensor {
  Sensor(const Cell& cell, const CameraSpec& camera, std::uint64_t noise_seed);
  void expose_row(int v, const float* radiance, std::uint8_t* out, std::size_t n) const;
  const float* row_noise(int v) const;  // the pool's run for row v

  float gain, read_var, shot;
  bool noisy;
  bool scalar = false;  // without the vector unit (tests hold the two to the same bytes)
  bool avx512 = true;   // false: AVX2 at most, where the CPU has AVX-512 (the same bytes again)
  const float* pool;
  std::size_t pool_span;
  std::uint64_t seed;
};

}  // namespace sim::render_parts
