// The closed loop in one process: the two services' own state machines (sim::CellStateMachine
// of `cellsim serve`, servo::ServoStateMachine of `servo run`) wired by plain messages passed
// by value. No DDS, no threads, no clocks: time is the frames' simulated time. Every stop is
// the cell's decision (sim::SessionEnd), as in the two-process run, so the in-process trace is
// the lockstep trace of the services by construction.
//
// What a frame order becomes on the way, as the wire carries it: the image rendered with the
// frame's seed, the sim status, the reported camera pose through a quaternion (as in
// geometry_msgs/Pose), the stamp of the frame; the servo's reply becomes a twist and a status.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "servo/node/servo_state_machine.hpp"
#include "sim/session/cell_state_machine.hpp"
#include "sim/session/white_frame_pose.hpp"
#include "sim/render/renderer.hpp"

namespace loop {

// Where the law's points come from. decoded: the servo decodes the rendered image (what a cell
// does). ideal: the simulator's true image positions of every visible spot, washed out by the
// projector's defocus or not. resolved: those of the visible spots the defocus leaves apart
// (sim::SpotTruth::resolved), what a perfect decoder could name. decoded ids: the spots the
// decoder names in the rendered image, each put at its id's true image position (an id the
// simulator sees nowhere is dropped): which spots from the decoder, where from the truth. A
// loop that fails with decoded features and with decoded ids but converges with resolved ones
// fails on which spots the decoder names, not on where it puts them; one that fails with
// resolved features too fails on what the camera can see.
enum class FeatureSource { kDecoded, kIdeal, kDecodedIds, kResolved };

// Whether the source's points are the simulator's truth alone (no image is rendered for them).
inline bool from_truth_alone(FeatureSource s) { return s == FeatureSource::kIdeal || s == FeatureSource::kResolved; }

// Refuses (std::invalid_argument) an injection the source would never see (outliers or losses
// into the truth) or would undo (outliers into decoded ids, each put back at its own id's
// position), rather than run as if it had been made.
void check_injections(FeatureSource source, double outlier_fraction, double loss_fraction);

struct LoopSetup {
  sim::Latency latency;               // the run's delays (the scenario's unless an experiment chose others)
  std::unique_ptr<sim::Robot> robot;  // what carries the camera (its belief set)
  servo::ServoConfig servo;           // the servo's configuration; its camera goes out as camera_info
  std::uint64_t noise_seed = 0;       // frame k's image noise: sim::frame_seed(noise_seed, k)
  FeatureSource source = FeatureSource::kDecoded;
  // outlier injection (issue 19): at every frame the ids of this fraction of the decoded spots
  // are swapped among them before the servo steps on them
  double outlier_fraction = 0;
  // decoding losses (issue 44): at every frame this fraction of the decoded spots is dropped
  // (seeded) before the servo steps, as spots a harder scene would not have decoded
  double loss_fraction = 0;
  // beside each pattern frame the camera takes the white reference frame at the same pose (its
  // own noise draw), and the servo decodes their ratio (servo/vision/reference.hpp); so too
  // when the servo's configuration asks for it (ServoConfig::white_frame)
  bool white_frame = false;
  // A real camera takes the white frame apart from the pattern frame, so while it moves the two
  // are not taken at one pose: the white frame is taken this share of a frame period before its
  // pattern frame, on the way the camera came (0: at the same pose; 1: where the frame before was)
  double white_frame_lead = 0;
  long max_steps = 400;  // the cell's iteration cap
  int render_threads = 0;  // sim::RenderScratch::threads: 0 OpenCV's pool, 1 this thread
};

// One frame of the loop: what the cell ordered, what the servo answered.
struct LoopExchange {
  sim::FrameOrder frame;
  servo::ServoReply reply;
  cv::Mat image;                            // the frame's rendered image (decoded source)
  int swapped = 0;                          // ids the injection swapped in this frame
  std::vector<std::pair<int, int>> wrong;   // the ids the swapped spots carried
};

// What crosses the wire in the two-process run, for a recorder (cellsim experiment --record):
// called in the order the services publish, with the loop's simulated time.
class LoopTap {
 public:
  virtual ~LoopTap() = default;
  // the camera_info the servo was given (latched, before anything else)
  virtual void on_start(const servo::CameraInfoMsg& info, const sim::CellStateMachine& cell) = 0;
  virtual void on_command(const sim::CommandMsg& c, double now_s) = 0;
  // a command the cell obeyed, as the service says it on rt/sim/accepted
  virtual void on_accepted(const sim::CommandMsg& c, double now_s) = 0;
  // a frame as cellsim publishes it: status, pose, robot, the white frame (null without one),
  // the image (null for the ideal source), clock
  virtual void on_frame(const sim::FrameOrder& f, const sim::CellStateMachine& cell, const cv::Mat* white,
                        const cv::Mat* rgb, double now_s) = 0;
  // the servo's answer to it (status, twist, spots), when it answered
  virtual void on_reply(const servo::ServoReply& r, double now_s) = 0;
};

class InMemoryLoop {
 public:
  InMemoryLoop(const sim::Cell& cell, LoopSetup setup);

  // Every message from now on goes to `tap` too (none when null); it is told the camera_info.
  void set_tap(LoopTap* tap);

  // A command on rt/sim/control: the cell hears it; the servo learns it when the cell obeys it
  // (at the next round or observe, before the frames, as over rt/sim/accepted). False when the
  // cell refused it.
  bool command(const sim::CommandMsg& c);
  // One round: the cell advances; every frame it orders is rendered, answered by the servo,
  // and the answer delivered back (status, then twist). The exchanges are appended, the
  // frames moved into them.
  sim::CellOutput round(std::vector<LoopExchange>& exchanges);

  // The same round in two halves, for a controller outside the loop (experiment::ServoEnv): the
  // frames are rendered and the servo's replies computed, but nothing is delivered back...
  sim::CellOutput observe(std::vector<LoopExchange>& exchanges);
  // ...until the caller answers a frame with its own twist (the servo's status goes with it).
  void answer(const LoopExchange& x, const control::Vector6d& twist);

  const sim::CellStateMachine& cell() const { return cell_; }
  const servo::ServoStateMachine& servo() const { return servo_; }

 private:
  void accepted(const sim::CellOutput& out);
  LoopExchange exchange(sim::FrameOrder order);  // rendered and answered by the servo
  // the spots the servo's pipeline locates in `rgb`, with the losses, outliers or true
  // positions the run asks for applied (x.swapped, x.wrong filled), for ServoStateMachine::on_spots
  std::vector<servo::ImageSpot> located(LoopExchange& x, const cv::Mat& rgb, const cv::Mat& white,
                                        const Eigen::Isometry3d& reported, int* detected);

  const sim::Cell& world_;
  std::uint64_t noise_seed_;
  FeatureSource source_;
  double outlier_fraction_;
  double loss_fraction_;
  bool white_frame_;
  sim::WhiteFramePose white_pose_;
  vision::DecodeScratch decode_scratch_;  // the decoder's room where the loop locates the spots itself
  sim::CellStateMachine cell_;
  servo::ServoStateMachine servo_;
  sim::RenderScratch scratch_;
  servo::CameraInfoMsg camera_info_;
  LoopTap* tap_ = nullptr;
  double now_s_ = 0;
};

// The decoded-ids source: each of `spots` moved to its id's true image position in `truth`, an id
// no visible spot of `truth` carries dropped (a wrong id, a spill of a hidden spot). The rest
// of each spot (its off-line mark: whether the law takes it) stays the decoder's. Returns how
// many were dropped.
int place_at_truth(std::vector<servo::ImageSpot>& spots, const std::vector<sim::SpotTruth>& truth);

// The outlier injection: the ids of `fraction` of `spots` (at least 2 when fraction > 0)
// shifted along a seeded cycle, so each chosen spot carries another's id. Returns how many.
// `wrong`, when given, receives the ids the chosen spots carry now.
int inject_outliers(std::vector<servo::ImageSpot>& spots, double fraction, std::uint64_t seed,
                    std::vector<std::pair<int, int>>* wrong = nullptr);

// The loss injection: `fraction` of `spots` (rounded) dropped, chosen by `seed`, the others
// kept in their order. Returns how many were dropped.
int drop_spots(std::vector<servo::ImageSpot>& spots, double fraction, std::uint64_t seed);

}  // namespace loop
