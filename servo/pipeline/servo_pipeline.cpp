#include "servo/pipeline/servo_pipeline.hpp"

#include <stdexcept>

#include <algorithm>

namespace servo {

ServoPipeline::ServoPipeline(pattern::WindowTable table, ServoConfig config)
    : decoder_(std::move(table), config.decoder), config_(std::move(config)) {
  control::check_options(config_.law);  // a malformed law is refused at start, not at the first frame
  const control::VisualFeatures f = config_.law.features;
  const bool triangulated = f == control::VisualFeatures::kSurface || f == control::VisualFeatures::kPlane;
  if (triangulated && !config_.projector)
    throw std::invalid_argument("visual features '" + control::to_string(f) +
                                "' need the spots' depths: give the projector's calibration (--projector)");
  // the taught points are triangulated, and fixed in the world only for a static projector
  if (config_.taught_points && !config_.projector)
    throw std::invalid_argument("taught points need the projector's calibration to triangulate them: give --projector");
  if (config_.taught_points && config_.projector->on_camera)
    throw std::invalid_argument("taught points: the projector rides on the camera (mount: camera), so the points its "
                                "spots light move with it; there is nothing to hold them to");
  // spots cast from the camera show the surface and nothing more: the surface's three moments
  // would servo the degrees of freedom they cannot see (points and moments take the riding
  // spots' own rows, interaction_matrix.hpp)
  if (config_.projector && config_.projector->on_camera && f == control::VisualFeatures::kSurface)
    throw std::invalid_argument("the projector rides on the camera (mount: camera): its spots show the surface alone, "
                                "not the motion along it that the surface's moments servo; use --visual-features "
                                "plane, points or moments");
}

namespace {
// Where the camera stands for the projector's geometry: the robot's pose, or none needed when
// the projector rides on the camera (its pose is the camera's).
std::optional<Eigen::Isometry3d> geometry_pose(const std::optional<calibration::ProjectorModel>& projector,
                                               const std::optional<Eigen::Isometry3d>& wTc) {
  if (projector && projector->on_camera) return wTc.value_or(Eigen::Isometry3d::Identity());
  return wTc;
}
}  // namespace

std::vector<ImageSpot> ServoPipeline::locate(const cv::Mat& rgb, const std::optional<Eigen::Isometry3d>& wTc,
                                             int* detected, const cv::Mat* white,
                                             vision::DecodeScratch* scratch) const {
  std::optional<vision::EpipolarGeometry> geometry;
  const std::optional<Eigen::Isometry3d> at = geometry_pose(config_.projector, wTc);
  if (at && config_.projector && config_.decoder.epipolar.enabled)
    geometry.emplace(config_.camera, *config_.projector, *at, config_.decoder.epipolar.tolerance_px);
  // without the calibration the frame's own lines, fitted to its spots, tell the spills
  const cv::Mat none;
  const cv::Mat& reference = white ? *white : none;
  const vision::DecodeResult r = geometry ? decoder_.decode(rgb, reference, &*geometry, scratch)
                                          : decoder_.decode_uncalibrated(rgb, reference, config_.camera, scratch);
  if (detected) *detected = static_cast<int>(r.detected.size());
  std::vector<ImageSpot> out;
  out.reserve(r.decoded.size());
  for (const auto& d : r.decoded) out.push_back(image_spot(d));
  return out;
}

std::vector<control::Feature> ServoPipeline::features(const std::vector<ImageSpot>& spots,
                                                      const std::optional<Eigen::Isometry3d>& wTc) const {
  std::vector<control::Feature> out;
  out.reserve(spots.size());
  const std::optional<Eigen::Isometry3d> at = geometry_pose(config_.projector, wTc);
  for (const ImageSpot& s : spots) {
    if (s.apart()) continue;
    const Eigen::Vector2d xy = calibration::normalise(config_.camera, {s.u, s.v});
    control::Feature f{s.row, s.col, xy.x(), xy.y(), std::nullopt, std::nullopt};
    if (at && config_.projector) f.z = control::triangulate_depth(xy, s.row, s.col, *config_.projector, *at);
    // a spot of a projector on the camera: its ray, fixed in the camera frame, for its rows of L
    if (config_.projector && config_.projector->on_camera)
      f.ray = config_.projector->on_camera->linear() * config_.projector->spot_ray(s.row, s.col);
    out.push_back(f);
  }
  return out;
}

int ServoPipeline::teach(const std::vector<ImageSpot>& spots, const std::optional<Eigen::Isometry3d>& wTc) {
  reference_ = features(spots, wTc);
  selected_.clear();
  taught_.clear();
  if (config_.taught_points && wTc) taught_ = taught_points(reference_, *wTc);  // (a static projector: checked at start)
  if (config_.points > 0 && reference_.size() > static_cast<std::size_t>(config_.points)) {
    // s = s* at the desired pose: the subset is chosen on the matrix the law will start from
    // near convergence, and kept, so the features do not change from one iteration to the next
    const auto at_goal = control::match_features(reference_, reference_);
    for (const auto& p : control::best_conditioned_subset(at_goal, static_cast<std::size_t>(config_.points), config_.law))
      selected_.emplace_back(p.row, p.col);
    std::sort(selected_.begin(), selected_.end());
  }
  return static_cast<int>(reference_.size());
}

TaughtCheck ServoPipeline::hold_to_taught(const std::vector<control::Feature>& f,
                                          const std::optional<Eigen::Isometry3d>& wTc) const {
  if (taught_.empty() || !wTc) return {std::vector<char>(f.size(), 0), 0, 0, 0};
  return check_taught(f, taught_, *wTc, config_.camera.fx, config_.camera.fy, config_.decoder.epipolar.grown_limit);
}

StepResult ServoPipeline::step(const std::vector<ImageSpot>& spots, const std::optional<Eigen::Isometry3d>& wTc) const {
  StepResult r;
  r.decoded = static_cast<int>(spots.size());
  r.features = features(spots, wTc);
  const TaughtCheck held = hold_to_taught(r.features, wTc);
  if (held.kept_out > 0) {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < r.features.size(); ++i)
      if (!held.off[i]) r.features[kept++] = r.features[i];
    r.features.resize(kept);
    r.held_by_taught = held.kept_out;
  }
  r.matched = control::match_features(r.features, reference_);
  if (config_.interior_points)
    r.matched = control::interior_points(r.matched, config_.interior_min_share, config_.law.min_points);
  if (config_.points > 0 && r.matched.size() > static_cast<std::size_t>(config_.points)) {
    std::vector<control::MatchedPoint> kept;
    for (const auto& m : r.matched)
      if (std::binary_search(selected_.begin(), selected_.end(), std::pair{m.row, m.col})) kept.push_back(m);
    // some chosen points are hidden or lost: choose again among those seen, this iteration
    if (kept.size() < static_cast<std::size_t>(config_.points))
      kept = control::best_conditioned_subset(r.matched, static_cast<std::size_t>(config_.points), config_.law);
    r.matched = std::move(kept);
  }
  r.control = control::compute_control(r.matched, config_.law);
  return r;
}

}  // namespace servo
