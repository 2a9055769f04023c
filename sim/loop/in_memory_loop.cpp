#include "sim/loop/in_memory_loop.hpp"

#include <algorithm>
#include <map>
#include <random>
#include <stdexcept>

namespace loop {

namespace {

sim::CellOptions lockstep_params(long max_steps, const sim::Latency& latency) {
  sim::CellOptions p;
  p.latency = latency;
  p.timing = sim::Timing::kLockstep;
  p.exit_on_converged = true;
  p.exit_on_stop = true;
  p.max_run_steps = max_steps;
  // nobody else publishes here: the servo's CONVERGED is taken as it is, also where the
  // scenario's calibration errors put the servo's goal away from the true one
  p.accept_translation_m = std::numeric_limits<double>::infinity();
  p.accept_rotation_deg = std::numeric_limits<double>::infinity();
  return p;
}

servo::CameraInfoMsg camera_info_of(const calibration::CameraIntrinsics& c, const sim::CameraSpec& size) {
  servo::CameraInfoMsg m;
  m.width = static_cast<std::uint32_t>(size.intrinsics.width);
  m.height = static_cast<std::uint32_t>(size.intrinsics.height);
  m.k = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
  m.d.assign(c.distortion.begin(), c.distortion.end());
  return m;
}

// geometry_msgs/Pose carries a quaternion; the servo rebuilds the rotation from it
Eigen::Isometry3d as_on_the_wire(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  const Eigen::Quaterniond received(q.w(), q.x(), q.y(), q.z());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() = T.translation();
  out.linear() = received.normalized().toRotationMatrix();
  return out;
}

}  // namespace

void check_injections(FeatureSource source, double outlier_fraction, double loss_fraction) {
  if (from_truth_alone(source) && (outlier_fraction > 0 || loss_fraction > 0))
    throw std::invalid_argument("outliers and losses are injected into decoded spots: they need decoded features");
  if (source == FeatureSource::kDecodedIds && outlier_fraction > 0)
    throw std::invalid_argument("outliers need decoded features: decoded ids put every id at its own true position");
}

InMemoryLoop::InMemoryLoop(const sim::Cell& cell, LoopSetup setup)
    : world_(cell),
      noise_seed_(setup.noise_seed),
      source_(setup.source),
      outlier_fraction_(setup.outlier_fraction),
      loss_fraction_(setup.loss_fraction),
      white_frame_(setup.white_frame || setup.servo.white_frame),
      white_pose_(setup.white_frame_lead),
      cell_(cell.scenario, lockstep_params(setup.max_steps, setup.latency), std::move(setup.robot), cell.goal_plane),
      servo_(std::make_unique<servo::ServoPipeline>(pattern::WindowTable(cell.projector->pattern(), {3, 3}), setup.servo),
             servo::ServoTiming{}) {
  scratch_.threads = setup.render_threads;
  check_injections(source_, outlier_fraction_, loss_fraction_);
  camera_info_ = camera_info_of(setup.servo.camera, cell.scenario.camera);
  const std::string why = servo_.on_camera_info(camera_info_);
  if (!why.empty()) throw std::invalid_argument(cell.scenario.file.string() + ": " + why);
}

void InMemoryLoop::set_tap(LoopTap* tap) {
  // a recording is replayed by decoding its images: the truth the servo stepped on is not in it
  if (tap && source_ == FeatureSource::kDecodedIds)
    throw std::invalid_argument("a run with decoded ids has no wire form to record (the servo steps on the truth)");
  tap_ = tap;
  if (tap_) tap_->on_start(camera_info_, cell_);
}

bool InMemoryLoop::command(const sim::CommandMsg& c) {
  if (tap_) tap_->on_command(c, now_s_);
  return cell_.on_command(c, now_s_);
}

// the commands the cell obeyed, to the servo before the frames they brought about (what the
// service says on rt/sim/accepted)
void InMemoryLoop::accepted(const sim::CellOutput& out) {
  for (const sim::CommandMsg& c : out.accepted) {
    if (tap_) tap_->on_accepted(c, now_s_);
    white_pose_.forget();
    servo_.on_command(c.command);
  }
}

LoopExchange InMemoryLoop::exchange(sim::FrameOrder order) {
  LoopExchange x;
  x.frame = std::move(order);
  const sim::FrameOrder& f = x.frame;
  const sim::FrameStamp fs = sim::frame_stamp(f.index, cell_.dt());
  const servo::Stamp stamp{static_cast<std::int32_t>(fs.sec), fs.nanosec};
  cv::Mat rgb, white;
  if (!from_truth_alone(source_)) {
    const std::uint64_t seed = sim::frame_seed(noise_seed_, f.index);
    rgb = sim::render_image(world_, f.scene_world_T_camera, seed, &scratch_, nullptr, &f.scene_world_T_links);
    if (white_frame_)
      white = sim::render_image(world_, white_pose_.at(f), sim::white_frame_seed(seed), &scratch_, nullptr,
                                &f.scene_world_T_links, sim::Cast::kWhite);
  }
  if (tap_) tap_->on_frame(f, cell_, white.empty() ? nullptr : &white, rgb.empty() ? nullptr : &rgb, now_s_);
  x.image = rgb;  // shared, not copied
  // the order the service publishes in: sim status and pose before the image
  servo_.on_sim_status({stamp, f.applies_twist, f.teach, cell_.running() && f.applies_twist});
  const Eigen::Isometry3d reported = as_on_the_wire(f.reported_world_T_camera);
  servo_.on_pose(stamp, reported);
  if (from_truth_alone(source_)) {
    std::vector<servo::ImageSpot> spots;
    for (const auto& t : sim::compute_truth(world_, f.scene_world_T_camera, &f.scene_world_T_links))
      if (source_ == FeatureSource::kResolved ? t.resolved : t.visible) spots.push_back({t.row, t.col, t.uv.x(), t.uv.y()});
    x.reply = servo_.on_spots(stamp, spots, 0, now_s_);
  } else if (source_ == FeatureSource::kDecodedIds || ((outlier_fraction_ > 0 || loss_fraction_ > 0) && !f.teach)) {
    int detected = 0;
    const std::vector<servo::ImageSpot> spots = located(x, rgb, white, reported, &detected);
    x.reply = servo_.on_spots(stamp, spots, detected, now_s_);
  } else {
    const auto view_of = [&](const cv::Mat& m) {
      return servo::ImageView{stamp,
                              "rgb8",
                              static_cast<std::uint32_t>(m.cols),
                              static_cast<std::uint32_t>(m.rows),
                              static_cast<std::uint32_t>(m.cols * 3),
                              0,
                              m.data,
                              m.total() * 3};
    };
    const servo::ImageView white_view = white.empty() ? servo::ImageView{} : view_of(white);
    x.reply = servo_.on_image(view_of(rgb), now_s_, white.empty() ? nullptr : &white_view);
  }
  return x;
}

void InMemoryLoop::answer(const LoopExchange& x, const control::Vector6d& twist) {
  // the servo's answer: status before twist, as the service publishes them
  const servo::ServoReply& r = x.reply;
  if (!r.answer) return;
  const sim::FrameStamp fs = sim::frame_stamp(x.frame.index, cell_.dt());
  if (tap_) {
    servo::ServoReply sent = r;
    sent.twist = twist;
    tap_->on_reply(sent, now_s_);
  }
  cell_.on_servo_status({fs.sec, fs.nanosec, static_cast<std::uint8_t>(r.state), r.error_norm, r.decoded, r.matched,
                         r.reason},
                        now_s_);
  cell_.on_twist({fs.sec, fs.nanosec, "camera_optical", twist}, now_s_);
}

sim::CellOutput InMemoryLoop::observe(std::vector<LoopExchange>& exchanges) {
  now_s_ += cell_.dt();
  sim::CellOutput out = cell_.poll(now_s_);
  accepted(out);
  // the frames are moved on into the exchanges (their link poses and joints are the large
  // part of an order); out.frames keeps their count, not their content
  for (auto& f : out.frames) exchanges.push_back(exchange(std::move(f)));
  return out;
}

std::vector<servo::ImageSpot> InMemoryLoop::located(LoopExchange& x, const cv::Mat& rgb, const cv::Mat& white,
                                                    const Eigen::Isometry3d& reported, int* detected) {
  const sim::FrameOrder& f = x.frame;
  // decoded as the servo would, then some spots dropped and some ids swapped before it steps
  // on them (not at teaching: the goal is taught from what the decoder names)
  std::vector<servo::ImageSpot> spots =
      servo_.pipeline().locate(rgb, reported, detected, white.empty() ? nullptr : &white, &decode_scratch_);
  if (loss_fraction_ > 0 && !f.teach)
    drop_spots(spots, loss_fraction_, sim::frame_seed(noise_seed_ ^ 0x6c6f7373ull, f.index + 1));
  if (outlier_fraction_ > 0 && !f.teach)
    x.swapped = inject_outliers(spots, outlier_fraction_, sim::frame_seed(noise_seed_ ^ 0x6f75746c69657273ull, f.index + 1),
                                &x.wrong);
  if (source_ == FeatureSource::kDecodedIds)
    place_at_truth(spots, sim::compute_truth(world_, f.scene_world_T_camera, &f.scene_world_T_links));
  return spots;
}

sim::CellOutput InMemoryLoop::round(std::vector<LoopExchange>& exchanges) {
  now_s_ += cell_.dt();
  sim::CellOutput out = cell_.poll(now_s_);
  accepted(out);
  for (auto& f : out.frames) {
    exchanges.push_back(exchange(std::move(f)));
    answer(exchanges.back(), exchanges.back().reply.twist);  // each frame answered before the next is seen
  }
  return out;
}

int drop_spots(std::vector<servo::ImageSpot>& spots, double fraction, std::uint64_t seed) {
  if (!(fraction > 0) || spots.empty()) return 0;
  const std::size_t n = std::min(spots.size(), static_cast<std::size_t>(std::lround(fraction * static_cast<double>(spots.size()))));
  std::mt19937_64 rng(seed);
  std::vector<char> drop(spots.size(), 0);
  for (std::size_t i = 0; i < n; ++i) drop[i] = 1;
  std::shuffle(drop.begin(), drop.end(), rng);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < spots.size(); ++i)
    if (!drop[i]) spots[kept++] = spots[i];
  spots.resize(kept);
  return static_cast<int>(n);
}

int place_at_truth(std::vector<servo::ImageSpot>& spots, const std::vector<sim::SpotTruth>& truth) {
  std::map<std::pair<int, int>, Eigen::Vector2d> at;
  for (const sim::SpotTruth& t : truth)
    if (t.visible) at.emplace(std::make_pair(t.row, t.col), t.uv);
  std::size_t kept = 0;
  for (const servo::ImageSpot& s : spots) {
    const auto it = at.find({s.row, s.col});
    if (it == at.end()) continue;
    servo::ImageSpot placed = s;
    placed.u = it->second.x();
    placed.v = it->second.y();
    spots[kept++] = placed;
  }
  const int dropped = static_cast<int>(spots.size() - kept);
  spots.resize(kept);
  return dropped;
}

int inject_outliers(std::vector<servo::ImageSpot>& spots, double fraction, std::uint64_t seed,
                    std::vector<std::pair<int, int>>* wrong) {
  if (!(fraction > 0) || spots.size() < 2) return 0;
  const std::size_t n = std::min(spots.size(), std::max<std::size_t>(2, static_cast<std::size_t>(std::lround(fraction * static_cast<double>(spots.size())))));
  std::mt19937_64 rng(seed);
  std::vector<std::size_t> pick(spots.size());
  for (std::size_t i = 0; i < pick.size(); ++i) pick[i] = i;
  for (std::size_t i = 0; i < n; ++i) std::swap(pick[i], pick[i + rng() % (pick.size() - i)]);
  // a cycle over the chosen spots: each takes the next one's id, so none keeps its own
  const int row0 = spots[pick[0]].row, col0 = spots[pick[0]].col;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    spots[pick[i]].row = spots[pick[i + 1]].row;
    spots[pick[i]].col = spots[pick[i + 1]].col;
  }
  spots[pick[n - 1]].row = row0;
  spots[pick[n - 1]].col = col0;
  if (wrong)
    for (std::size_t i = 0; i < n; ++i) wrong->emplace_back(spots[pick[i]].row, spots[pick[i]].col);
  return static_cast<int>(n);
}

}  // namespace loop
