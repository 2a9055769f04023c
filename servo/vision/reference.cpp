#include "servo/vision/reference.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <opencv2/imgproc.hpp>

#include "servo/pattern/palette.hpp"

namespace vision {
namespace {

void check_rgb8(const cv::Mat& m, const char* which) {
  if (m.empty() || m.type() != CV_8UC3)
    throw std::invalid_argument(std::string("the ") + which + " frame is not an 8-bit RGB image");
}

void check_level(const ReferenceOptions& o) {
  if (o.full_level < 1 || o.full_level > 255) throw std::invalid_argument("reference: full_level must be in [1, 255]");
}

}  // namespace

void normalise_by_white(const cv::Mat& pattern_rgb, const cv::Mat& white_rgb, cv::Mat& out,
                        const ReferenceOptions& options, cv::Mat* white_mean) {
  check_rgb8(pattern_rgb, "pattern");
  check_rgb8(white_rgb, "white");
  check_level(options);
  if (pattern_rgb.size() != white_rgb.size())
    throw std::invalid_argument("the white frame is " + std::to_string(white_rgb.cols) + " x " +
                                std::to_string(white_rgb.rows) + " px, the pattern frame " +
                                std::to_string(pattern_rgb.cols) + " x " + std::to_string(pattern_rgb.rows));
  cv::Mat local;
  cv::Mat& mean = white_mean ? *white_mean : local;
  cv::blur(white_rgb, mean, {3, 3}, {-1, -1}, cv::BORDER_REPLICATE);
  // OpenCV's vector paths: the three whole-image passes cost a third of one written pixel by
  // pixel with a table of gains (the ham's frame: 2.0 ms more than the decoding alone)
  cv::max(mean, cv::Scalar::all(options.full_level), mean);
  cv::divide(pattern_rgb, mean, out, 255.0);
}

void strengths_as_shown(std::vector<Spot>& spots, const cv::Mat& white_rgb, const ReferenceOptions& options) {
  check_rgb8(white_rgb, "white");
  check_level(options);
  if (white_rgb.cols < 3 || white_rgb.rows < 3) return;  // no 3 x 3 to read: the ratio's strengths stand
  for (Spot& s : spots) {
    if (s.colour < 0 || s.colour >= static_cast<int>(pattern::kPalette.size())) continue;
    const pattern::Rgb c = pattern::symbol_colour(s.colour);
    const std::array<bool, 3> lit{c.r > 0, c.g > 0, c.b > 0};
    const int u0 = std::clamp(static_cast<int>(std::lround(s.u)), 1, white_rgb.cols - 2);
    const int v0 = std::clamp(static_cast<int>(std::lround(s.v)), 1, white_rgb.rows - 2);
    double sum = 0;
    int count = 0;
    for (int v = v0 - 1; v <= v0 + 1; ++v) {
      const std::uint8_t* row = white_rgb.ptr<std::uint8_t>(v);
      for (int u = u0 - 1; u <= u0 + 1; ++u)
        for (int ch = 0; ch < 3; ++ch)
          if (lit[static_cast<std::size_t>(ch)]) sum += row[3 * u + ch], ++count;
    }
    const double level = std::max(count > 0 ? sum / count : 0.0, static_cast<double>(options.full_level));
    s.strength = static_cast<float>(s.strength * level / 255.0);
  }
}

}  // namespace vision
