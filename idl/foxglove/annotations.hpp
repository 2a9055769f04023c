// What the live view draws over the camera image: `/servo/annotations`, Foxglove's
// foxglove_msgs/ImageAnnotations. Each decoded spot ringed and labelled with its id, the
// desired points (the spots decoded in the teach frame, which /sim/status names) as hollow
// rings, and each matched spot's error vector to its desired point. Built from /servo/spots and
// /sim/status alone, as any client could: the bridge serves them live, `cellsim serve --record`
// records them beside the rest.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <utility>

#include "cell_msgs.h"
#include "foxglove_msgs.h"

namespace foxglove {

// its topic, namespaced as the cell's
inline constexpr const char* kAnnotationsTopic = "rt/servo/annotations";

class Annotations {
 public:
  using Drawn = foxglove_msgs::msg::dds_::ImageAnnotations_;
  using Sink = std::function<void(const Drawn&)>;
  // `sink` takes each frame's annotations; `wanted` (optional) says whether anyone would take
  // them (a viewer subscribes), so that nothing is drawn for nobody. Thread-safe.
  explicit Annotations(Sink sink, std::function<bool()> wanted = nullptr);

  void on_status(const cell_msgs::msg::dds_::SimStatus_& s);  // learns which frame is the teach frame
  void on_spots(const cell_msgs::msg::dds_::DecodedSpots_& x);  // draws this frame's annotations

 private:
  using Key = std::pair<std::int32_t, std::uint32_t>;
  static Key key(const builtin_interfaces::msg::dds_::Time_& t) { return {t.sec(), t.nanosec()}; }
  void learn(const cell_msgs::msg::dds_::DecodedSpots_& x);
  Drawn draw(const cell_msgs::msg::dds_::DecodedSpots_& x) const;

  Sink sink_;
  std::function<bool()> wanted_;
  std::mutex m_;
  Key teach_{-1, 0};
  std::map<std::pair<int, int>, std::pair<double, double>> desired_;  // id -> its pixel at the teach frame
  std::deque<cell_msgs::msg::dds_::DecodedSpots_> recent_;           // the last 16, for a status heard late
};

}  // namespace foxglove
