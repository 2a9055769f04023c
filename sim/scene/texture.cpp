#include "sim/scene/texture.hpp"

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/regular_file.hpp"
#include "sim/scene/triangle_mesh.hpp"

namespace sim {
namespace {

[[noreturn]] void fail(const std::filesystem::path& p, const std::string& what) {
  throw MeshError(p.string() + ": " + what);
}

std::uint32_t big_endian(const std::string& d, std::size_t at) {
  return (static_cast<std::uint32_t>(static_cast<unsigned char>(d[at])) << 24) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(d[at + 1])) << 16) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(d[at + 2])) << 8) |
         static_cast<std::uint32_t>(static_cast<unsigned char>(d[at + 3]));
}

}  // namespace

Texture load_texture(const std::filesystem::path& file) {
  std::string data;
  try {
    data = common::read_regular_file(file, kMaxTextureFileBytes, "texture");
  } catch (const common::FileError& e) {
    throw MeshError(e.what());
  }
  // the signature, then IHDR as the first chunk (the PNG standard's order): the size is known
  // before the decoder allocates anything
  static const char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (data.size() < 33 || data.compare(0, 8, kSignature, 8) != 0) fail(file, "not a PNG image (a texture must be PNG)");
  if (big_endian(data, 8) != 13 || data.compare(12, 4, "IHDR") != 0) fail(file, "PNG without its IHDR header first");
  const std::uint32_t w = big_endian(data, 16), h = big_endian(data, 20);
  if (w == 0 || h == 0 || w > kMaxTextureSide || h > kMaxTextureSide)
    fail(file, "texture of " + std::to_string(w) + " x " + std::to_string(h) + " pixels (each side 1.." +
                   std::to_string(kMaxTextureSide) + ")");
  const cv::Mat raw(1, static_cast<int>(data.size()), CV_8U, data.data());
  cv::Mat bgr;
  try {
    bgr = cv::imdecode(raw, cv::IMREAD_COLOR);
  } catch (const cv::Exception&) {
    bgr.release();
  }
  if (bgr.empty() || bgr.cols != static_cast<int>(w) || bgr.rows != static_cast<int>(h))
    fail(file, "cannot decode the PNG image");
  Texture t;
  t.width = bgr.cols;
  t.height = bgr.rows;
  t.file = file.string();
  const std::size_t plane = static_cast<std::size_t>(t.width) * static_cast<std::size_t>(t.height);
  t.rgb.resize(3 * plane);
  for (int y = 0; y < t.height; ++y) {
    const auto* px = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < t.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(t.width) + static_cast<std::size_t>(x);
      for (int c = 0; c < 3; ++c) t.rgb[static_cast<std::size_t>(c) * plane + i] = static_cast<float>(px[x][2 - c]) / 255.0f;
    }
  }
  return t;
}

void texel_at(const Texture& t, double u, double v, float out[3]) {
  const double fu = u - std::floor(u), fv = v - std::floor(v);
  const int x = std::min(t.width - 1, static_cast<int>(fu * t.width));
  const int y = std::min(t.height - 1, static_cast<int>((1.0 - fv) * t.height));
  const std::size_t plane = static_cast<std::size_t>(t.width) * static_cast<std::size_t>(t.height);
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(t.width) + static_cast<std::size_t>(x);
  for (int c = 0; c < 3; ++c) out[c] = t.rgb[static_cast<std::size_t>(c) * plane + i];
}

}  // namespace sim
