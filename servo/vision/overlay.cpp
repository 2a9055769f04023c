#include "servo/vision/overlay.hpp"

#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

namespace vision {

namespace {

// A label's place beside its spot: the first of four corners around the ring where it overlaps
// no label placed before; none when all four do (the ring stays, the id is in the JSON).
std::optional<cv::Rect> free_place(const cv::Point& centre, const cv::Size& text, int ring,
                                   const std::vector<cv::Rect>& taken, const cv::Size& image) {
  const cv::Point corners[4] = {{centre.x + ring, centre.y - ring - text.height},
                                {centre.x + ring, centre.y + ring},
                                {centre.x - ring - text.width, centre.y - ring - text.height},
                                {centre.x - ring - text.width, centre.y + ring}};
  for (const cv::Point& c : corners) {
    const cv::Rect r(c, text + cv::Size(2, 2));
    if (r.x < 0 || r.y < 0 || r.br().x > image.width || r.br().y > image.height) continue;
    bool clear = true;
    for (const cv::Rect& t : taken) clear = clear && (r & t).area() == 0;
    if (clear) return r;
  }
  return std::nullopt;
}

}  // namespace

cv::Mat draw_overlay(const cv::Mat& rgb, const DecodeResult& result) {
  cv::Mat base;
  if (rgb.type() == CV_8UC3) base = rgb;
  else cv::cvtColor(rgb, base, rgb.channels() == 1 ? cv::COLOR_GRAY2RGB : cv::COLOR_RGBA2RGB);
  // drawn at twice the image's size: the labels of a 20 x 20 pattern's spots, 10-20 px apart,
  // cannot be read at the image's own
  constexpr int kScale = 2, kShift = 4, kRing = 5 * kScale;
  cv::Mat out;
  cv::resize(base, out, base.size() * kScale, 0, 0, cv::INTER_NEAREST);
  const auto at = [](double u, double v) {
    return cv::Point(static_cast<int>((u + 0.5) * kScale * 16), static_cast<int>((v + 0.5) * kScale * 16));
  };
  for (const Spot& s : result.detected) cv::circle(out, at(s.u, s.v), kRing * 16, cv::Scalar(110, 110, 110), 1, cv::LINE_AA, kShift);
  std::vector<cv::Rect> taken;
  for (const DecodedSpot& d : result.decoded) {
    // orange: named, but off its epipolar line (a spill, a split spot) or clipped, kept from the law
    const cv::Scalar ring = d.apart() ? kOffLine : cv::Scalar(255, 255, 255);
    cv::circle(out, at(d.u, d.v), kRing * 16, ring, 1, cv::LINE_AA, kShift);
    const std::string label = std::to_string(d.row) + "," + std::to_string(d.col);
    int baseline = 0;
    const cv::Size text = cv::getTextSize(label, cv::FONT_HERSHEY_PLAIN, 0.9, 1, &baseline);
    const cv::Point centre(static_cast<int>((d.u + 0.5) * kScale), static_cast<int>((d.v + 0.5) * kScale));
    const std::optional<cv::Rect> place = free_place(centre, text, kRing, taken, out.size());
    if (!place) continue;
    taken.push_back(*place);
    // white on a dark outline: readable on a bright surface as on the dark wall
    const cv::Point origin(place->x + 1, place->y + text.height + 1);
    cv::putText(out, label, origin, cv::FONT_HERSHEY_PLAIN, 0.9, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(out, label, origin, cv::FONT_HERSHEY_PLAIN, 0.9, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return out;
}

}  // namespace vision
