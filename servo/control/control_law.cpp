#include "servo/control/control_law.hpp"

#include <algorithm>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace control {

namespace {
// one key per spot id (a pattern has at most 4096 columns; a neighbour's -1 keeps its own key)
long id_key(int row, int col) { return static_cast<long>(row) * 65536 + col; }
}  // namespace

std::vector<MatchedPoint> match_features(const std::vector<Feature>& current, const std::vector<Feature>& desired) {
  std::unordered_map<long, const Feature*> by_id;
  by_id.reserve(current.size());
  for (const Feature& f : current) by_id[id_key(f.row, f.col)] = &f;
  std::vector<MatchedPoint> out;
  out.reserve(desired.size());
  for (const Feature& d : desired) {
    const auto it = by_id.find(id_key(d.row, d.col));
    if (it == by_id.end()) continue;
    const Feature& c = *it->second;
    out.push_back({d.row, d.col, c.x, c.y, d.x, d.y, c.z, d.z, c.ray ? c.ray : d.ray});
  }
  return out;
}

std::vector<MatchedPoint> interior_points(const std::vector<MatchedPoint>& matched, double min_share, int min_count) {
  std::unordered_set<long> ids;
  ids.reserve(matched.size());
  for (const MatchedPoint& m : matched) ids.insert(id_key(m.row, m.col));
  std::vector<MatchedPoint> inside;
  for (const MatchedPoint& m : matched)
    if (ids.count(id_key(m.row + 1, m.col)) && ids.count(id_key(m.row - 1, m.col)) &&
        ids.count(id_key(m.row, m.col + 1)) && ids.count(id_key(m.row, m.col - 1)))
      inside.push_back(m);
  const bool enough = static_cast<double>(inside.size()) >= min_share * static_cast<double>(matched.size()) &&
                      inside.size() >= static_cast<std::size_t>(std::max(min_count, 1));
  return enough ? inside : matched;
}

double Gain::at(double e) const {
  if (!adaptive() || slope_zero <= 0) return lambda_inf;
  const double span = lambda_zero - lambda_inf;
  return span * std::exp(-slope_zero * e / span) + lambda_inf;
}

Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& A, double rel) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& sv = svd.singularValues();
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(sv.size());
  const double cut = sv.size() ? sv[0] * rel : 0;
  for (Eigen::Index i = 0; i < sv.size(); ++i)
    if (sv[i] > cut && sv[i] > 0) inv[i] = 1.0 / sv[i];
  return svd.matrixV() * inv.asDiagonal() * svd.matrixU().transpose();
}

Eigen::VectorXd pseudo_inverse_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, double rel, double* condition,
                                     Eigen::Index rank) {
  // A is tall (2k x 6): the SVD of A is read off the eigen-decomposition of the 6 x 6 A^T A
  // (A = U S V^T, A^T A = V S^2 V^T), so A^+ b = V S^-2 V^T A^T b, with singular values below
  // rel x the largest dropped. O(k) instead of an SVD of the 2k x 6 matrix.
  const Eigen::MatrixXd AtA = A.transpose() * A;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(AtA);
  const Eigen::VectorXd& ev = eig.eigenvalues();  // ascending
  const double top = ev.size() ? std::sqrt(std::max(ev[ev.size() - 1], 0.0)) : 0;
  if (condition) {
    // over the singular values asked that A has: a wide A (the plane's 3 x 6) has only as many as rows
    const Eigen::Index first = ev.size() - std::min({rank, A.rows(), ev.size()});
    const double bottom = ev.size() ? std::sqrt(std::max(ev[first], 0.0)) : 0;
    *condition = bottom > 0 ? top / bottom : std::numeric_limits<double>::infinity();
  }
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(ev.size());
  for (Eigen::Index i = 0; i < ev.size(); ++i) {
    const double sv = std::sqrt(std::max(ev[i], 0.0));
    if (sv > top * rel && sv > 0) inv[i] = 1.0 / ev[i];
  }
  const Eigen::MatrixXd& V = eig.eigenvectors();
  return V * inv.asDiagonal() * (V.transpose() * (A.transpose() * b));
}

std::string DivergenceWatch::check(double error_norm) {
  if (!(ratio_ > 0)) return "";
  if (!first_) first_ = error_norm;
  if (!(error_norm > ratio_ * *first_)) return "";
  char why[160];
  std::snprintf(why, sizeof why, "diverging: |e| = %.4g, above %g x its first value %.4g", error_norm, ratio_, *first_);
  return why;
}

std::string to_string(ControlStatus s) {
  switch (s) {
    case ControlStatus::kServoing: return "servoing";
    case ControlStatus::kConverged: return "converged";
    case ControlStatus::kTooFewPoints: return "too few points";
    case ControlStatus::kNoDepth: return "no depth";
  }
  return "?";
}

void check_options(const ControlLawOptions& p) {
  const auto bad = [](const std::string& what) { throw std::invalid_argument("control law: " + what); };
  if (!(p.z_hat_m > 0) || !std::isfinite(p.z_hat_m)) bad("z_hat must be a positive depth, got " + std::to_string(p.z_hat_m));
  if (!(p.gain.lambda_zero > 0) || !(p.gain.lambda_inf > 0) || !(p.gain.slope_zero >= 0))
    bad("gains must be positive (lambda0, lambda_inf) and the slope >= 0");
  if (!(p.max_linear_mps > 0) || !(p.max_angular_radps > 0)) bad("velocity limits must be positive");
  if (p.min_points < 3) bad("min_points must be at least 3 (6 degrees of freedom)");
  if (!(p.convergence_translation_m > 0) || !(p.convergence_rotation_rad > 0)) bad("convergence thresholds must be positive");
  if (p.robust_iterations < 1 || p.robust_iterations > 50) bad("robust iterations must be in 1..50");
  if (!(p.robust_min_scale > 0) || !std::isfinite(p.robust_min_scale)) bad("robust minimum scale must be positive");
  if (p.features != VisualFeatures::kPoints && p.robust != RobustEstimator::kNone)
    bad("robust weights are per point: they apply to the points, not to the " + to_string(p.features));
}

namespace {

// The depth each model uses for a point's current and desired rows; nullopt when the model
// needs a depth the point lacks.
struct Depths {
  std::optional<double> current, desired;
};

Depths model_depths(const MatchedPoint& p, const ControlLawOptions& params) {
  switch (params.model) {
    case InteractionModel::kDesiredConstantDepth: return {std::nullopt, params.z_hat_m};
    case InteractionModel::kDesired: return {std::nullopt, p.z_star};
    case InteractionModel::kCurrent: return {p.z, std::nullopt};
    case InteractionModel::kMean: return {p.z, p.z_star};
  }
  return {};
}

}  // namespace

RobustEstimator parse_robust_estimator(const std::string& name) {
  if (name == "none") return RobustEstimator::kNone;
  if (name == "tukey") return RobustEstimator::kTukey;
  if (name == "huber") return RobustEstimator::kHuber;
  throw std::invalid_argument("robust estimator '" + printable_name(name) + "': expected tukey, huber or none");
}

std::string to_string(RobustEstimator e) {
  switch (e) {
    case RobustEstimator::kNone: return "none";
    case RobustEstimator::kTukey: return "tukey";
    case RobustEstimator::kHuber: return "huber";
  }
  return "?";
}

namespace {
double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double upper = v[mid];
  if (v.size() % 2 == 1) return upper;
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
}
}  // namespace

std::vector<double> robust_weights(RobustEstimator e, const std::vector<double>& residuals, double min_scale) {
  std::vector<double> w(residuals.size(), 1.0);
  if (e == RobustEstimator::kNone || residuals.empty()) return w;
  const double med = median_of(residuals);
  std::vector<double> dev(residuals.size());
  for (std::size_t i = 0; i < residuals.size(); ++i) dev[i] = std::abs(residuals[i] - med);
  const double sigma = std::max(1.4826 * median_of(dev), min_scale);
  for (std::size_t i = 0; i < residuals.size(); ++i) {
    const double r = dev[i];
    if (e == RobustEstimator::kTukey) {
      const double c = 4.6851 * sigma;
      const double u = r / c;
      w[i] = r < c ? (1 - u * u) * (1 - u * u) : 0.0;
    } else {
      const double c = 1.345 * sigma;
      w[i] = r <= c ? 1.0 : c / r;
    }
  }
  return w;
}

namespace {

// The points whose depths the model has, with those depths.
struct UsablePoints {
  std::vector<const MatchedPoint*> points;
  std::vector<std::size_t> index;  // of each used point in `all`
  std::vector<Depths> depths;
};

UsablePoints usable_points(const std::vector<MatchedPoint>& all, const ControlLawOptions& params) {
  UsablePoints u;
  for (const MatchedPoint& p : all) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.x_star) || !std::isfinite(p.y_star))
      throw std::invalid_argument("control law: point (" + std::to_string(p.row) + ", " + std::to_string(p.col) +
                                  ") has non-finite coordinates");
    const Depths d = model_depths(p, params);
    // the surface is fitted to s's and s*'s triangulated points whatever the model
    // so are a riding spot's rows (its surface's plane)
    const bool surface =
        params.features == VisualFeatures::kSurface || params.features == VisualFeatures::kPlane || p.ray.has_value();
    const bool needs_current = params.model == InteractionModel::kCurrent || params.model == InteractionModel::kMean;
    const bool needs_desired = params.model != InteractionModel::kCurrent;
    if (surface && !(p.z && *p.z > 0 && p.z_star && *p.z_star > 0)) continue;
    if ((needs_current && !(d.current && *d.current > 0)) || (needs_desired && !(d.desired && *d.desired > 0))) continue;
    u.points.push_back(&p);
    u.index.push_back(static_cast<std::size_t>(&p - all.data()));
    u.depths.push_back(d);
  }
  return u;
}

// The matched points' coordinates, s and s*, with depths: the model's (the moments' rows take
// the depth the model gives each point, as stack_system's) or the triangulated ones (the
// surface is fitted to them whatever the model).
struct PointSets {
  Eigen::VectorXd s, s_star, z, z_star;
};
PointSets point_sets(const UsablePoints& u, bool triangulated) {
  const Eigen::Index k = static_cast<Eigen::Index>(u.points.size());
  PointSets p{Eigen::VectorXd(2 * k), Eigen::VectorXd(2 * k), Eigen::VectorXd(k), Eigen::VectorXd(k)};
  for (Eigen::Index i = 0; i < k; ++i) {
    const MatchedPoint& m = *u.points[i];
    p.s.segment<2>(2 * i) << m.x, m.y;
    p.s_star.segment<2>(2 * i) << m.x_star, m.y_star;
    p.z[i] = triangulated ? *m.z : u.depths[i].current.value_or(0);
    p.z_star[i] = triangulated ? *m.z_star : u.depths[i].desired.value_or(0);
  }
  return p;
}

// The planes riding spots' rows need (the surface's normal where they land, camera frame),
// fitted to the triangulated points of s and of s*; none when no spot rides on the camera.
// Throws std::invalid_argument when the points give no plane.
struct RidingPlanes {
  std::optional<Plane> now, goal;
};
RidingPlanes riding_planes(const UsablePoints& u) {
  if (std::none_of(u.points.begin(), u.points.end(), [](const MatchedPoint* p) { return p->ray.has_value(); })) return {};
  const PointSets t = point_sets(u, true);
  return {fit_plane(t.s, t.z), fit_plane(t.s_star, t.z_star)};
}

// A point's two rows at (x, y) with depth Z: eq. 7's, or a riding spot's on `plane`.
Matrix26 point_rows(const MatchedPoint& p, double x, double y, double Z, const std::optional<Plane>& plane) {
  return p.ray && plane ? riding_point_interaction_matrix(x, y, Z, *p.ray, plane->n) : point_interaction_matrix(x, y, Z);
}

// The stacked error s - s* and the model's interaction matrix L-hat; the depth each point's
// rows used goes to z_model.
void stack_system(const UsablePoints& u, const ControlLawOptions& params, const RidingPlanes& planes,
                  Eigen::VectorXd& error, Eigen::MatrixXd& L, std::vector<double>& z_model) {
  const Eigen::Index k = static_cast<Eigen::Index>(u.points.size());
  error.resize(2 * k);
  L = Eigen::MatrixXd::Zero(2 * k, 6);
  for (Eigen::Index i = 0; i < k; ++i) {
    const MatchedPoint& p = *u.points[i];
    error[2 * i] = p.x - p.x_star;
    error[2 * i + 1] = p.y - p.y_star;
    const Depths& d = u.depths[i];
    switch (params.model) {
      case InteractionModel::kDesiredConstantDepth:
      case InteractionModel::kDesired:
        L.block<2, 6>(2 * i, 0) = point_rows(p, p.x_star, p.y_star, *d.desired, planes.goal);
        z_model[u.index[i]] = *d.desired;
        break;
      case InteractionModel::kCurrent:
        L.block<2, 6>(2 * i, 0) = point_rows(p, p.x, p.y, *d.current, planes.now);
        z_model[u.index[i]] = *d.current;
        break;
      case InteractionModel::kMean:
        L.block<2, 6>(2 * i, 0) = 0.5 * (point_rows(p, p.x, p.y, *d.current, planes.now) +
                                         point_rows(p, p.x_star, p.y_star, *d.desired, planes.goal));
        z_model[u.index[i]] = *d.current;
        break;
    }
  }
}

// L where the model takes it: at s* for the desired models, at s for current, their mean
template <typename Now, typename AtGoal>
Eigen::MatrixXd by_model(InteractionModel model, Now&& now, AtGoal&& at_goal) {
  switch (model) {
    case InteractionModel::kDesiredConstantDepth:
    case InteractionModel::kDesired: return at_goal();
    case InteractionModel::kCurrent: return now();
    case InteractionModel::kMean: return 0.5 * (now() + at_goal());
  }
  return at_goal();
}

// The moments' system (image_moments.hpp): their error and interaction matrix.
void moment_system(const UsablePoints& u, const ControlLawOptions& params, const RidingPlanes& planes,
                   Eigen::VectorXd& error, Eigen::MatrixXd& L) {
  const PointSets p = point_sets(u, false);
  // each point's rows, at s and at s*, with the depths the model gives
  std::vector<Matrix26> now, at_goal;
  for (std::size_t i = 0; i < u.points.size(); ++i) {
    const MatchedPoint& m = *u.points[i];
    const auto k = static_cast<Eigen::Index>(i);
    now.push_back(point_rows(m, m.x, m.y, p.z[k], planes.now));
    at_goal.push_back(point_rows(m, m.x_star, m.y_star, p.z_star[k], planes.goal));
  }
  // a_n's value at the goal: the desired depths' mean where the model has them, else Z-hat
  const bool desired_depths = params.model != InteractionModel::kCurrent;
  const MomentScale scale{moment_area(p.s_star), desired_depths ? p.z_star.mean() : params.z_hat_m};
  error = moment_error(moment_features(p.s, scale), moment_features(p.s_star, scale));
  L = by_model(
      params.model, [&] { return moment_interaction_matrix(p.s, now, scale); },
      [&] { return moment_interaction_matrix(p.s_star, at_goal, scale); });
}

// The surface's system (surface_features.hpp): the planes of s's and s*'s triangulated points
// with three moments each.
void surface_system(const UsablePoints& u, const ControlLawOptions& params, Eigen::VectorXd& error, Eigen::MatrixXd& L) {
  const PointSets p = point_sets(u, true);
  const MomentScale scale{moment_area(p.s_star), p.z_star.mean()};
  error = surface_features(p.s, p.z, scale) - surface_features(p.s_star, p.z_star, scale);
  error[5] = std::remainder(error[5], 3.14159265358979323846);  // alpha, an orientation: modulo pi
  L = by_model(
      params.model, [&] { return surface_interaction_matrix(p.s, p.z, fit_plane(p.s, p.z), scale); },
      [&] { return surface_interaction_matrix(p.s_star, p.z_star, fit_plane(p.s_star, p.z_star), scale); });
}

// The plane-to-plane task's system (surface_features.hpp): the planes of s's and s*'s
// triangulated points, their normals and distances.
void plane_system(const UsablePoints& u, const ControlLawOptions& params, Eigen::VectorXd& error, Eigen::MatrixXd& L) {
  const PointSets p = point_sets(u, true);
  const Plane now = fit_plane(p.s, p.z), goal = fit_plane(p.s_star, p.z_star);
  error = plane_features(now) - plane_features(goal);
  L = by_model(
      params.model, [&] { return Eigen::MatrixXd(plane_interaction_matrix(now)); },
      [&] { return Eigen::MatrixXd(plane_interaction_matrix(goal)); });
}

// The robust task function by IRLS: weights from the residuals of the last estimate, e from
// the weighted system. Returns the points' last weights.
std::vector<double> robust_task(const Eigen::MatrixXd& L, const Eigen::VectorXd& error, const ControlLawOptions& params,
                                Vector6d& task, double* condition, Eigen::Index rank) {
  const Eigen::Index k = L.rows() / 2;
  std::vector<double> w(static_cast<std::size_t>(k), 1.0), residual(static_cast<std::size_t>(k));
  Eigen::MatrixXd WL = L;
  Eigen::VectorXd We = error;
  task = pseudo_inverse_solve(L, error, params.svd_relative_threshold);
  for (int it = 0; it < params.robust_iterations; ++it) {
    const Eigen::VectorXd r = error - L * task;
    for (Eigen::Index i = 0; i < k; ++i) residual[static_cast<std::size_t>(i)] = r.segment<2>(2 * i).norm();
    w = robust_weights(params.robust, residual, params.robust_min_scale);
    for (Eigen::Index i = 0; i < k; ++i) {
      WL.row(2 * i) = w[static_cast<std::size_t>(i)] * L.row(2 * i);
      WL.row(2 * i + 1) = w[static_cast<std::size_t>(i)] * L.row(2 * i + 1);
      We[2 * i] = w[static_cast<std::size_t>(i)] * error[2 * i];
      We[2 * i + 1] = w[static_cast<std::size_t>(i)] * error[2 * i + 1];
    }
    task = pseudo_inverse_solve(WL, We, params.svd_relative_threshold, condition, rank);
  }
  return w;
}

// The system of the features the options name: e = s - s* and L-hat, and the points' error's
// RMS. False, with the status and reason in `out`, when the points give no plane or no moments
// (all on one spot, all on a line: a few spots left at an edge): a safe stop, as too few points
// are, never a throw out of the servo's frame.
bool feature_system(const UsablePoints& u, const ControlLawOptions& params, Eigen::VectorXd& error, Eigen::MatrixXd& L,
                    ControlOutput& out) {
  try {
    const RidingPlanes planes = riding_planes(u);
    stack_system(u, params, planes, error, L, out.z_model);
    out.feature_rms = std::sqrt(error.squaredNorm() / static_cast<double>(error.size()));
    switch (params.features) {
      case VisualFeatures::kPoints: break;
      case VisualFeatures::kMoments: moment_system(u, params, planes, error, L); break;
      case VisualFeatures::kPlane: plane_system(u, params, error, L); break;
      case VisualFeatures::kSurface: surface_system(u, params, error, L); break;
    }
    return true;
  } catch (const std::invalid_argument& e) {
    out.status = ControlStatus::kTooFewPoints;
    out.reason = e.what();
    return false;
  }
}

}  // namespace

ControlOutput compute_control(const std::vector<MatchedPoint>& all, const ControlLawOptions& params) {
  check_options(params);
  ControlOutput out;
  out.z_model.assign(all.size(), std::numeric_limits<double>::quiet_NaN());
  const UsablePoints u = usable_points(all, params);
  out.points = static_cast<int>(u.points.size());
  if (out.points < params.min_points) {
    out.status = static_cast<int>(all.size()) >= params.min_points ? ControlStatus::kNoDepth : ControlStatus::kTooFewPoints;
    out.reason = std::to_string(out.points) + " usable points (" + std::to_string(all.size()) + " matched), " +
                 std::to_string(params.min_points) + " needed";
    return out;
  }
  const Eigen::Index k = out.points;
  Eigen::VectorXd error;
  Eigen::MatrixXd L;
  if (!feature_system(u, params, error, L, out)) return out;
  // spots cast from the camera see the plane's three degrees of freedom, no more
  const bool riding = std::any_of(u.points.begin(), u.points.end(), [](const MatchedPoint* p) { return p->ray.has_value(); });
  const Eigen::Index rank = riding ? 3 : 6;
  out.weights.assign(all.size(), std::numeric_limits<double>::quiet_NaN());
  if (params.features != VisualFeatures::kPoints || params.robust == RobustEstimator::kNone) {
    out.task = pseudo_inverse_solve(L, error, params.svd_relative_threshold, &out.condition, rank);
    for (Eigen::Index i = 0; i < k; ++i) out.weights[u.index[i]] = 1.0;
  } else {
    const std::vector<double> w = robust_task(L, error, params, out.task, &out.condition, rank);
    int kept = 0;
    for (Eigen::Index i = 0; i < k; ++i) {
      out.weights[u.index[i]] = w[static_cast<std::size_t>(i)];
      kept += w[static_cast<std::size_t>(i)] > 0;
    }
    if (kept < params.min_points) {
      out.status = ControlStatus::kTooFewPoints;
      out.reason = std::to_string(kept) + " points with a non-zero robust weight (" + std::to_string(k) + " used), " +
                   std::to_string(params.min_points) + " needed";
      out.task.setZero();
      return out;
    }
  }
  // a task that is not a number (moments of coordinates past what a double squares and cubes)
  // moves nothing: a safe stop that says so
  if (!out.task.allFinite()) {
    out.task.setZero();
    out.status = ControlStatus::kTooFewPoints;
    out.reason = "the " + to_string(params.features) + " gave a task function that is not finite";
    return out;
  }
  out.error_norm = out.task.norm();
  if (out.task.head<3>().norm() < params.convergence_translation_m &&
      out.task.tail<3>().norm() < params.convergence_rotation_rad) {
    out.status = ControlStatus::kConverged;
    char why[128];
    std::snprintf(why, sizeof why, "task function below %.2g m and %.2g rad", params.convergence_translation_m,
                  params.convergence_rotation_rad);
    out.reason = why;
    return out;  // zero twist: hold still
  }
  out.gain = params.gain.at(out.error_norm);
  Vector6d v = -out.gain * out.task;
  // saturate the whole screw by one factor, so its direction is kept
  const double lin = v.head<3>().norm(), ang = v.tail<3>().norm();
  const double scale = std::min({1.0, params.max_linear_mps / std::max(lin, 1e-300),
                                 params.max_angular_radps / std::max(ang, 1e-300)});
  out.saturated = scale < 1.0;
  out.twist = v * scale;
  return out;
}

std::vector<MatchedPoint> best_conditioned_subset(const std::vector<MatchedPoint>& points, std::size_t count,
                                                  const ControlLawOptions& params) {
  if (points.size() <= count) return points;
  const auto rows = [&](const MatchedPoint& p) {
    const Depths d = model_depths(p, params);
    const double z = d.desired.value_or(d.current.value_or(params.z_hat_m));
    return params.model == InteractionModel::kCurrent ? point_interaction_matrix(p.x, p.y, z)
                                                      : point_interaction_matrix(p.x_star, p.y_star, z);
  };
  const auto condition = [](const Eigen::MatrixXd& L) {
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(L);
    const auto& sv = svd.singularValues();
    return sv[sv.size() - 1] > 0 ? sv[0] / sv[sv.size() - 1] : 1e300;
  };
  std::vector<bool> used(points.size(), false);
  std::vector<MatchedPoint> chosen;
  Eigen::MatrixXd L(0, 6);
  // seed: the point farthest from the centroid of s*, then greedy minimal condition number
  double cx = 0, cy = 0;
  for (const auto& p : points) cx += p.x_star, cy += p.y_star;
  cx /= static_cast<double>(points.size()), cy /= static_cast<double>(points.size());
  std::size_t seed = 0;
  double far = -1;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double d = std::hypot(points[i].x_star - cx, points[i].y_star - cy);
    if (d > far) far = d, seed = i;
  }
  const auto add = [&](std::size_t i) {
    used[i] = true;
    chosen.push_back(points[i]);
    L.conservativeResize(L.rows() + 2, 6);
    L.bottomRows<2>() = rows(points[i]);
  };
  add(seed);
  while (chosen.size() < count) {
    double best = 1e301;
    std::size_t pick = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (used[i]) continue;
      Eigen::MatrixXd trial(L.rows() + 2, 6);
      trial << L, rows(points[i]);
      // below 3 points L has rank < 6: rank-deficient conditions compare the spread instead
      const double c = trial.rows() >= 6 ? condition(trial) : -trial.norm();
      if (c < best) best = c, pick = i;
    }
    add(pick);
  }
  return chosen;
}

}  // namespace control
