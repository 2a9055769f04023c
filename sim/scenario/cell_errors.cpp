#include "sim/scenario/cell_errors.hpp"

#include <sstream>
#include <string_view>
#include <iomanip>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

namespace sim {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

struct ErrorField {
  const char* name;
  double CalibrationErrors::*member;
  double max;
};

constexpr ErrorField kErrorFields[] = {
    {"focal_pct", &CalibrationErrors::focal_pct, kMaxFocalErrorPct},
    {"principal_point_px", &CalibrationErrors::principal_point_px, kMaxPrincipalErrorPx},
    {"distortion_k1", &CalibrationErrors::distortion_k1, kMaxDistortionError},
    {"projector_position_mm", &CalibrationErrors::projector_position_mm, kMaxPositionErrorMm},
    {"projector_rotation_deg", &CalibrationErrors::projector_rotation_deg, kMaxRotationErrorDeg},
    {"hand_eye_position_mm", &CalibrationErrors::hand_eye_position_mm, kMaxPositionErrorMm},
    {"hand_eye_rotation_deg", &CalibrationErrors::hand_eye_rotation_deg, kMaxRotationErrorDeg},
    {"link_length_pct", &CalibrationErrors::link_length_pct, kMaxLinkLengthErrorPct},
    {"joint_offset_deg", &CalibrationErrors::joint_offset_deg, kMaxJointOffsetErrorDeg},
};

std::pair<std::string, double> split_assignment(const std::string& a, const char* what) {
  const std::size_t eq = a.find('=');
  if (a.size() > 200 || eq == std::string::npos)
    throw std::invalid_argument(std::string(what) + " '" + a.substr(0, 60) + "': expected NAME=VALUE");
  const std::string name = a.substr(0, eq), value = a.substr(eq + 1);
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size() || !std::isfinite(v))
    throw std::invalid_argument(std::string(what) + " " + name + ": '" + value.substr(0, 40) + "' is not a number");
  return {name, v};
}

double checked(const std::string& name, double v, double max, const char* what) {
  if (!(v >= 0 && v <= max)) {
    char range[96];
    std::snprintf(range, sizeof range, "%.6g is outside [0, %g]", v, max);
    throw std::invalid_argument(std::string(what) + " " + name + ": " + range);
  }
  return v;
}

// a direction drawn uniformly on the sphere
Eigen::Vector3d unit_vector(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  for (;;) {
    const Eigen::Vector3d v(n(rng), n(rng), n(rng));
    if (v.norm() > 1e-6) return v.normalized();
  }
}

double sign(std::mt19937_64& rng) { return (rng() & 1u) ? 1.0 : -1.0; }

Eigen::Isometry3d small_motion(std::mt19937_64& rng, double position_mm, double rotation_deg) {
  // both directions are drawn whatever the magnitudes, so one magnitude set to zero does not
  // change the direction the other gets
  const Eigen::Vector3d t = unit_vector(rng), axis = unit_vector(rng);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  if (rotation_deg > 0) m.linear() = Eigen::AngleAxisd(rotation_deg * kDeg, axis).toRotationMatrix();
  if (position_mm > 0) m.translation() = 1e-3 * position_mm * t;
  return m;
}

}  // namespace

bool CalibrationErrors::any() const {
  for (const ErrorField& f : kErrorFields)
    if (this->*f.member != 0) return true;
  return false;
}

DrawnErrors draw_errors(const CalibrationErrors& e, std::uint64_t seed, std::size_t chain_segments) {
  std::mt19937_64 rng(e.seed.value_or(seed));
  DrawnErrors d;
  // every draw is made whatever the magnitudes: each error's direction depends on the seed only
  const double sx = sign(rng), sy = sign(rng);
  d.fx_scale = 1 + sx * e.focal_pct / 100;
  d.fy_scale = 1 + sy * e.focal_pct / 100;
  const double angle = std::uniform_real_distribution<double>(0, 2 * 3.14159265358979323846)(rng);
  if (e.principal_point_px > 0) d.principal_shift_px = e.principal_point_px * Eigen::Vector2d(std::cos(angle), std::sin(angle));
  d.k1_shift = sign(rng) * e.distortion_k1;
  d.projector_delta = small_motion(rng, e.projector_position_mm, e.projector_rotation_deg);
  d.robot.camera_T_believed = small_motion(rng, e.hand_eye_position_mm, e.hand_eye_rotation_deg);
  if (e.link_length_pct > 0 || e.joint_offset_deg > 0) {
    d.robot.link_scale.resize(chain_segments);
    d.robot.joint_offset_rad.resize(chain_segments);
    for (std::size_t i = 0; i < chain_segments; ++i) {
      d.robot.link_scale[i] = 1 + sign(rng) * e.link_length_pct / 100;
      d.robot.joint_offset_rad[i] = sign(rng) * e.joint_offset_deg * kDeg;
    }
  }
  return d;
}

void set_error(CalibrationErrors& errors, const std::string& assignment) {
  const auto [name, v] = split_assignment(assignment, "error");
  set_error(errors, name, v);
}

void set_error(CalibrationErrors& errors, const std::string& name, double v) {
  if (name == "seed") {
    if (!(v >= 0 && v <= 9.007199254740992e15 && v == std::floor(v)))
      throw std::invalid_argument("error seed: expected a non-negative integer");
    errors.seed = static_cast<std::uint64_t>(v);
    return;
  }
  for (const ErrorField& f : kErrorFields)
    if (name == f.name) {
      errors.*f.member = checked(name, v, f.max, "error");
      return;
    }
  std::string known;
  for (const auto& n : error_names()) {
    if (!known.empty()) known += ", ";
    known += n;
  }
  throw std::invalid_argument("error '" + name.substr(0, 60) + "': unknown (known: " + known + ", seed)");
}

void set_latency(Latency& latency, const std::string& assignment) {
  const auto [name, v] = split_assignment(assignment, "latency");
  set_latency(latency, name, v);
}

void set_latency(Latency& latency, const std::string& name, double v) {
  const auto frames = [&] {
    if (v != std::floor(v)) throw std::invalid_argument("latency " + name + ": a whole number of frames");
    return static_cast<int>(checked(name, v, kMaxDelayFrames, "latency"));
  };
  if (name == "acquisition_frames") {
    latency.acquisition_frames = frames();
  } else if (name == "processing_frames") {
    latency.processing_frames = frames();
  } else if (name == "actuation_s") {
    latency.actuation_s = checked(name, v, kMaxActuationDelayS, "latency");
  } else {
    throw std::invalid_argument("latency '" + name.substr(0, 60) +
                                "': unknown (known: acquisition_frames, processing_frames, actuation_s)");
  }
}

std::vector<std::string> error_names() {
  std::vector<std::string> n;
  for (const ErrorField& f : kErrorFields) n.push_back(f.name);
  return n;
}

std::vector<std::pair<std::string, double>> error_values(const CalibrationErrors& errors) {
  std::vector<std::pair<std::string, double>> v;
  for (const ErrorField& f : kErrorFields) v.emplace_back(f.name, errors.*f.member);
  return v;
}

std::vector<std::string> latency_names() { return {"acquisition_frames", "processing_frames", "actuation_s"}; }

std::string describe(const CalibrationErrors& e, const Latency& l) {
  std::ostringstream d;
  d << std::setprecision(6);
  bool first = true;
  const auto put = [&](std::string_view name, double v) {
    if (v == 0) return;
    if (!first) d << ' ';
    first = false;
    d << name << '=' << v;
  };
  for (const auto& [name, v] : error_values(e)) put(name, v);
  if (e.any() && e.seed) put("error_seed", static_cast<double>(*e.seed));
  put("acquisition_frames", l.acquisition_frames);
  put("processing_frames", l.processing_frames);
  put("actuation_s", l.actuation_s);
  return first ? "none" : d.str();
}

}  // namespace sim
