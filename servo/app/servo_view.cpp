#include "servo/app/servo_view.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "cell_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/cli_flags.hpp"
#include "dds/topics.hpp"
#include "sensor_msgsPubSubTypes.h"
#include "common/output_image.hpp"
#include "servo/node/servo_state_machine.hpp"

namespace servo {
namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

using StampKey = std::pair<int32_t, uint32_t>;
StampKey key(const builtin_interfaces::msg::dds_::Time_& t) { return {t.sec(), t.nanosec()}; }

// The frame with its decoded ids drawn on it, and a caption (BGR, for OpenCV's window and files).
cv::Mat annotated(sensor_msgs::msg::dds_::Image_& img, const std::optional<cell_msgs::msg::dds_::DecodedSpots_>& ids) {
  cv::Mat rgb(static_cast<int>(img.height()), static_cast<int>(img.width()), CV_8UC3, img.data().data(), img.step());
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  if (ids)
    for (const auto& s : ids->spots()) {
      // untrusted positions: only those on the image are drawn (a cast of 1e300 is undefined)
      if (!(s.u() >= 0 && s.u() < bgr.cols && s.v() >= 0 && s.v() < bgr.rows)) continue;
      cv::circle(bgr, {static_cast<int>(s.u() + 0.5), static_cast<int>(s.v() + 0.5)}, 5, cv::Scalar(255, 255, 255), 1,
                 cv::LINE_AA);
      cv::putText(bgr, std::to_string(s.row()) + "," + std::to_string(s.col()),
                  {static_cast<int>(s.u()) + 4, static_cast<int>(s.v()) - 3}, cv::FONT_HERSHEY_PLAIN, 0.6,
                  cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
    }
  char caption[128];
  std::snprintf(caption, sizeof caption, "t = %.2f s, %zu decoded", cell_dds::seconds(img.header().stamp()),
                ids ? ids->spots().size() : 0);
  cv::putText(bgr, caption, {8, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  return bgr;
}

}  // namespace

// Nothing has come yet: said every 5 s, so that a viewer with no cell does not look hung.
void say_waiting(const std::string& topic, int domain, std::chrono::steady_clock::time_point& last_said) {
  if (std::chrono::steady_clock::now() - last_said <= std::chrono::seconds(5)) return;
  std::printf("servo view: waiting for images on %s (domain %d): is a cellsim serving there? (Ctrl-C ends)\n",
              topic.c_str(), domain);
  std::fflush(stdout);
  last_said = std::chrono::steady_clock::now();
}

int run_viewer(const ViewOptions& o) {
  // SIGHUP: a closed terminal or ssh session stops it as cleanly as Ctrl-C
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, on_signal);
  const bool window = o.output.empty() && std::getenv("DISPLAY") != nullptr;
  if (!window && o.output.empty()) throw std::runtime_error("no display: give --output DIR for a PNG sequence");
  if (!o.output.empty()) common::make_output_folder(o.output);

  std::mutex m;
  std::condition_variable cv;
  std::optional<sensor_msgs::msg::dds_::Image_> image;
  long received = 0, dropped = 0;  // images that came; those the next replaced before they were drawn
  std::map<StampKey, cell_msgs::msg::dds_::DecodedSpots_> spots;  // by stamp, a few kept
  const auto topic = [&](const char* t) { return cell_dds::namespaced(o.ns, t); };
  auto p = cell_dds::make_participant(cell_dds::participant_options(o, "servo_view", "viewer"));
  using cell_dds::Stream;
  cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType> images(
      *p, topic(cell_dds::kImageTopic), cell_dds::reader_qos(Stream::kFrame), [&](sensor_msgs::msg::dds_::Image_&& i) {
        std::lock_guard<std::mutex> l(m);
        ++received;
        dropped += image.has_value();
        image = std::move(i);
        cv.notify_all();
      });
  cell_dds::Reader<cell_msgs::msg::dds_::DecodedSpots_PubSubType> decoded(
      *p, topic(cell_dds::kSpotsTopic), cell_dds::reader_qos(Stream::kFrame), [&](cell_msgs::msg::dds_::DecodedSpots_&& s) {
        std::lock_guard<std::mutex> l(m);
        spots[key(s.header().stamp())] = std::move(s);
        while (spots.size() > 8) spots.erase(spots.begin());
        cv.notify_all();
      });
  std::printf("servo view: ready (%s, domain %d)\n", window ? "window" : o.output.c_str(), o.domain_id);
  std::fflush(stdout);

  long shown = 0, seen = 0, rejected = 0;
  auto last_said = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(m);
  while (!g_stop && (o.frames == 0 || shown < o.frames)) {
    // an image and its decoded spots (the servo answers each image), or the image alone after 100 ms
    if (!cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return image.has_value(); })) {
      if (window) cv::waitKey(1);
      if (received == 0) say_waiting(topic(cell_dds::kImageTopic), o.domain_id, last_said);
      continue;
    }
    const auto stamp = key(image->header().stamp());
    cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return spots.count(stamp) > 0; });
    sensor_msgs::msg::dds_::Image_ img = std::move(*image);
    image.reset();
    std::optional<cell_msgs::msg::dds_::DecodedSpots_> ids;
    if (auto it = spots.find(stamp); it != spots.end()) ids = it->second;
    lock.unlock();
    // the same checks as the servo's (64-bit sizes, limits); camera_info is not needed to draw
    const ImageView view{{img.header().stamp().sec(), img.header().stamp().nanosec()}, img.encoding(), img.width(),
                         img.height(), img.step(), img.is_bigendian(), img.data().data(), img.data().size()};
    const std::string bad = ServoStateMachine::reject_reason(
        view, CameraInfoMsg{img.width(), img.height(), {}, {}});
    if (!bad.empty()) {
      if (++rejected <= 5) std::fprintf(stderr, "servo view: %s: %s\n", topic(cell_dds::kImageTopic).c_str(), bad.c_str());
      lock.lock();
      continue;
    }
    if (++seen % o.every == 0) {
      const cv::Mat bgr = annotated(img, ids);
      if (window) {
        cv::imshow("servo view", bgr);
        if (cv::waitKey(1) == 27) g_stop = true;
      } else {
        char name[64];
        std::snprintf(name, sizeof name, "frame_%06ld.png", shown);
        common::write_output_image(o.output / name, bgr);
      }
      ++shown;
    }
    lock.lock();
  }
  std::printf("servo view: %ld frames %s; %ld images received, %ld dropped (a newer one came before they were "
              "drawn), %ld refused, %ld skipped by --every\n",
              shown, window ? "shown" : ("written to " + o.output.string()).c_str(), received, dropped, rejected,
              seen - shown);
  return 0;
}

}  // namespace servo
