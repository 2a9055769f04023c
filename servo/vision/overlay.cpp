#include "servo/vision/overlay.hpp"

#include <opencv2/imgproc.hpp>
#include <string>

namespace vision {

cv::Mat draw_overlay(const cv::Mat& rgb, const DecodeResult& result) {
  cv::Mat out;
  if (rgb.type() == CV_8UC3) out = rgb.clone();
  else cv::cvtColor(rgb, out, rgb.channels() == 1 ? cv::COLOR_GRAY2RGB : cv::COLOR_RGBA2RGB);
  constexpr int kShift = 4;  // sub-pixel drawing
  const auto at = [](double u, double v) { return cv::Point(static_cast<int>(u * 16 + 0.5), static_cast<int>(v * 16 + 0.5)); };
  for (const Spot& s : result.detected)
    cv::circle(out, at(s.u, s.v), 5 * 16, cv::Scalar(110, 110, 110), 1, cv::LINE_AA, kShift);
  for (const DecodedSpot& d : result.decoded) {
    cv::circle(out, at(d.u, d.v), 5 * 16, cv::Scalar(255, 255, 255), 1, cv::LINE_AA, kShift);
    cv::putText(out, std::to_string(d.row) + "," + std::to_string(d.col),
                cv::Point(static_cast<int>(d.u) + 4, static_cast<int>(d.v) - 3), cv::FONT_HERSHEY_PLAIN, 0.6,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return out;
}

}  // namespace vision
