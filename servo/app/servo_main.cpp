// `servo`: the visual-servoing controller's command line. `decode` decodes one image.
#include <CLI/CLI.hpp>
#include <functional>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <optional>
#include <set>
#include <sstream>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/cli_help.hpp"
#include "common/output_image.hpp"
#include "dds/cli_flags.hpp"
#include "common/cli_numbers.hpp"
#include "common/plot_script.hpp"
#include "common/strict_yaml.hpp"
#include "common/regular_file.hpp"
#include "servo/pattern/pattern_file.hpp"
#include "servo/vision/overlay.hpp"
#include "servo/vision/spot_decoder.hpp"
#include "servo/service/servo_replay.hpp"
#include "servo/service/servo_service.hpp"
#include "servo/node/servo_state_machine.hpp"
#include "servo/app/servo_view.hpp"
#include "dds/participant.hpp"
#include "dds/topics.hpp"

namespace {

// Width and height from an image file's header, for the formats whose header says them
// plainly (PNG, JPEG, BMP, PNM); nullopt when the header does not tell.
std::optional<std::pair<std::uint64_t, std::uint64_t>> header_size(const std::string& head) {
  const auto u8 = [&](std::size_t i) { return static_cast<std::uint64_t>(static_cast<unsigned char>(head[i])); };
  const auto be32 = [&](std::size_t i) { return u8(i) << 24 | u8(i + 1) << 16 | u8(i + 2) << 8 | u8(i + 3); };
  if (head.size() >= 24 && head.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) return std::make_pair(be32(16), be32(20));
  if (head.size() >= 26 && head.compare(0, 2, "BM") == 0) {
    const auto le32 = [&](std::size_t i) { return u8(i) | u8(i + 1) << 8 | u8(i + 2) << 16 | u8(i + 3) << 24; };
    const std::int64_t h = static_cast<std::int32_t>(le32(22));
    return std::make_pair(le32(18), static_cast<std::uint64_t>(h < 0 ? -h : h));
  }
  if (head.size() >= 4 && u8(0) == 0xFF && u8(1) == 0xD8) {
    // walk the JPEG markers to the first frame header (SOF0..SOF15 but DHT, JPG, DAC)
    for (std::size_t i = 2; i + 9 < head.size();) {
      if (u8(i) != 0xFF) return std::nullopt;
      const std::uint64_t marker = u8(i + 1);
      const std::uint64_t len = u8(i + 2) << 8 | u8(i + 3);
      if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC)
        return std::make_pair(u8(i + 7) << 8 | u8(i + 8), u8(i + 5) << 8 | u8(i + 6));
      i += 2 + len;
    }
    return std::nullopt;
  }
  if (head.size() >= 3 && head[0] == 'P' && head[1] >= '1' && head[1] <= '6') {
    std::istringstream in(head.substr(2));
    std::string w, h;
    in >> w >> h;
    if (w.size() > 12 || h.size() > 12 || w.find_first_not_of("0123456789") != std::string::npos || w.empty() ||
        h.empty() || h.find_first_not_of("0123456789") != std::string::npos)
      return std::nullopt;
    return std::make_pair(std::stoull(w), std::stoull(h));
  }
  return std::nullopt;
}

// an uncompressed image of the largest size the servo takes, with room for its header
constexpr std::uintmax_t kMaxImageFileBytes = 3 * static_cast<std::uintmax_t>(servo::kMaxImagePixels) + (1u << 20);

cv::Mat read_rgb(const std::string& path) {
  // read once, as a regular file (a FIFO or a link to /proc/kmsg must not hang the decoder)
  const std::string bytes = common::read_regular_file(path, kMaxImageFileBytes, "image");
  const std::string head = bytes.substr(0, 64 * 1024);
  // a 1 MB PNG can decode to 20000 x 20000 (1.2 GB): the header is checked before decoding
  if (const auto wh = header_size(head)) {
    const auto [w, h] = *wh;
    if (w == 0 || h == 0 || w > servo::kMaxImageSide || h > servo::kMaxImageSide || w * h > servo::kMaxImagePixels)
      throw std::runtime_error(path + ": image of " + std::to_string(w) + " x " + std::to_string(h) +
                               " px, beyond the limit of " + std::to_string(servo::kMaxImageSide) + " per side and " +
                               std::to_string(servo::kMaxImagePixels) + " pixels");
  }
  // the codecs print their own complaints (libpng error: ...) on stderr: our one line says it
  cv::Mat bgr;
  {
    std::fflush(stderr);
    const int saved = dup(STDERR_FILENO);
    const int devnull = open("/dev/null", O_WRONLY);
    if (saved >= 0 && devnull >= 0) dup2(devnull, STDERR_FILENO);
    try {
      // IMREAD_COLOR turns grey and binary images into 3 equal channels: they have no chroma,
      // so they decode to zero spots instead of failing
      const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
      if (!bytes.empty()) bgr = cv::imdecode(raw, cv::IMREAD_COLOR);
    } catch (const cv::Exception&) {
      bgr.release();
    }
    std::fflush(stderr);
    if (saved >= 0) {
      dup2(saved, STDERR_FILENO);
      close(saved);
    }
    if (devnull >= 0) close(devnull);
  }
  if (bgr.empty()) throw std::runtime_error(path + ": cannot read image (empty, corrupt, too large or not an image)");
  if (static_cast<std::uint64_t>(bgr.cols) * bgr.rows > servo::kMaxImagePixels || bgr.cols > int(servo::kMaxImageSide) ||
      bgr.rows > int(servo::kMaxImageSide))
    throw std::runtime_error(path + ": image of " + std::to_string(bgr.cols) + " x " + std::to_string(bgr.rows) +
                             " px, beyond the limit");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

// The images named: files, and the image files of folders (sorted), at most 100 000.
std::vector<std::filesystem::path> image_list(const std::vector<std::string>& args) {
  static const std::set<std::string> kinds = {".png", ".jpg", ".jpeg", ".bmp", ".ppm", ".pnm", ".pgm"};
  std::vector<std::filesystem::path> out;
  for (const auto& a : args) {
    std::error_code ec;
    if (std::filesystem::is_directory(a, ec)) {
      std::vector<std::filesystem::path> in_dir;
      for (const auto& e : std::filesystem::directory_iterator(a, ec)) {
        std::string ext = e.path().extension().string();
        for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        if (e.is_regular_file(ec) && kinds.count(ext)) in_dir.push_back(e.path());
      }
      if (in_dir.empty()) throw std::runtime_error(a + ": no image files (png, jpg, bmp, ppm, pgm) in this folder");
      std::sort(in_dir.begin(), in_dir.end());
      out.insert(out.end(), in_dir.begin(), in_dir.end());
    } else {
      out.emplace_back(a);
    }
    if (out.size() > 100000) throw std::runtime_error("more than 100 000 images");
  }
  return out;
}

// What the epipolar check needs besides the image: the projector's calibration, the camera's
// intrinsics, and the camera's pose for each image (one for all, or each image's sidecar JSON).
struct EpipolarInputs {
  std::optional<calibration::ProjectorModel> projector;
  calibration::CameraIntrinsics camera;
  bool camera_given = false;  // --camera: without the projector, the frame's own lines are fitted
  std::optional<Eigen::Isometry3d> fixed_pose;
};

void check_finite(const std::string& what, const std::vector<double>& v, double limit) {
  for (double x : v)
    if (!(std::abs(x) <= limit)) throw std::runtime_error(what + ": values must be finite and within +-" + std::to_string(limit));
}

Eigen::Isometry3d pose_from(const std::string& what, const std::vector<double>& p, const std::vector<double>& q_xyzw) {
  check_finite(what, p, 100);
  check_finite(what, q_xyzw, 1.001);
  const Eigen::Quaterniond q(q_xyzw[3], q_xyzw[0], q_xyzw[1], q_xyzw[2]);
  if (std::abs(q.norm() - 1.0) > 1e-3) throw std::runtime_error(what + ": the orientation must be a unit quaternion [x, y, z, w]");
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
  t.linear() = q.normalized().toRotationMatrix();
  return t;
}

// The camera pose of `image` from its sidecar `<stem>.json` (what `cellsim render --truth`
// writes): {"camera_pose": {"position_m": [x, y, z], "orientation_xyzw": [x, y, z, w]}}.
Eigen::Isometry3d sidecar_pose(const std::filesystem::path& image) {
  std::filesystem::path file = image;
  file.replace_extension(".json");
  const std::string name = file.string();
  std::error_code ec;
  if (!std::filesystem::exists(file, ec))
    throw std::runtime_error(image.string() + ": no camera pose (--camera-pose, or " + name + " with camera_pose)");
  const nlohmann::json j = nlohmann::json::parse(common::read_regular_file(file, 16u << 20, "camera pose file"), nullptr, false);
  try {
    if (j.is_discarded()) throw std::runtime_error("not JSON");
    const auto& c = j.at("camera_pose");
    const auto p = c.at("position_m").get<std::vector<double>>();
    const auto q = c.at("orientation_xyzw").get<std::vector<double>>();
    if (p.size() != 3 || q.size() != 4) throw std::runtime_error("position_m needs 3 numbers, orientation_xyzw 4");
    return pose_from(name + ": camera_pose", p, q);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(name + ": camera_pose {position_m: [x, y, z], orientation_xyzw: [x, y, z, w]} expected");
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    throw std::runtime_error(what.rfind(name, 0) == 0 ? what : name + ": " + what);
  }
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// What a decode that names nothing, or an image the intrinsics were not made for, most likely
// means, said on stderr (issue 43: "380 spots detected, 0 decoded", exit 0, and no hint)
void warn_if_suspect(const std::string& image, const cv::Mat& rgb, const vision::DecodeResult& r,
                     const EpipolarInputs& epipolar) {
  if (epipolar.projector) {
    const double cx = epipolar.camera.cx, cy = epipolar.camera.cy;
    if (std::abs(cx - 0.5 * rgb.cols) > 0.25 * rgb.cols || std::abs(cy - 0.5 * rgb.rows) > 0.25 * rgb.rows)
      std::fprintf(stderr,
                   "servo: warning: %s is %d x %d but --camera puts the principal point at (%.1f, %.1f): are these "
                   "intrinsics this image's?\n",
                   common::printable(image, 200).c_str(), rgb.cols, rgb.rows, cx, cy);
  }
  if (r.decoded.empty() && r.detected.size() >= 9)
    std::fprintf(stderr,
                 "servo: warning: %s: %zu spots detected, none named: is --pattern the pattern the projector casts%s?\n",
                 common::printable(image, 200).c_str(), r.detected.size(),
                 epipolar.projector ? ", and --camera and the camera pose this image's" : "");
}

// One image's decode as JSON: its ids, and every segmented blob, in the order the decoder
// numbers them, with its links (E, S, W, N: the blob each one reaches, -1 for none): why a
// spot was or was not named.
void write_decode_json(const std::string& json_file, const std::string& image, const vision::DecodeResult& r, double ms) {
  nlohmann::json j;
  j["image"] = image;
  j["spots"] = nlohmann::json::array();
  for (const auto& d : r.decoded)
    j["spots"].push_back(
        {{"row", d.row}, {"col", d.col}, {"u", d.u}, {"v", d.v}, {"by", static_cast<int>(d.by)}, {"off_line", d.off_line},
         {"clipped", d.clipped}});
  j["detected"] = r.detected.size();
  j["blobs"] = nlohmann::json::array();
  for (std::size_t b = 0; b < r.detected.size(); ++b) {
    const vision::Spot& s = r.detected[b];
    const auto& next = b < r.graph.next.size() ? r.graph.next[b] : std::array<int, 4>{-1, -1, -1, -1};
    j["blobs"].push_back({{"u", s.u}, {"v", s.v}, {"colour", s.colour}, {"area_px", s.area_px},
                          {"strength", s.strength}, {"truncated", s.truncated}, {"sliver", s.sliver},
                          {"links", {next[0], next[1], next[2], next[3]}}});
  }
  j["decoded"] = r.decoded.size();
  j["time_ms"] = ms;
  common::write_output_file(json_file, j.dump(1) + "\n", "decode result");
}

// Decodes every image with one warm decoder: each image's time_ms is a warm decode (the
// first image is decoded once before its timed run); prints one line per image and, for
// several, the median and maximum per-frame time (the first image excluded). A bad image is
// one line and the others still go; the exit code says whether all went.
struct DecodeFiles {
  std::string json_out, json_dir, overlay_out;
  std::string white;  // the white reference frame of the one image (vision::normalise_by_white)
};

// The image decoded alone, or with its white reference frame (`white` not empty).
vision::DecodeResult decode_one(const vision::SpotDecoder& decoder, const cv::Mat& rgb, const cv::Mat& white,
                                const vision::EpipolarGeometry* g, const EpipolarInputs& epipolar,
                                vision::DecodeScratch& scratch) {
  return !g && epipolar.camera_given ? decoder.decode_uncalibrated(rgb, white, epipolar.camera, &scratch)
                                     : decoder.decode(rgb, white, g, &scratch);
}

// The white reference frame (none: empty) refused in one line naming both files when its size
// is not the image's.
void check_white(const std::string& white_file, const cv::Mat& white, const std::string& image, const cv::Mat& rgb) {
  if (white.empty() || white.size() == rgb.size()) return;
  throw std::runtime_error("--white " + common::printable(white_file, 200) + ": " + std::to_string(white.cols) + " x " +
                           std::to_string(white.rows) + " px, but " + common::printable(image, 200) + " is " +
                           std::to_string(rgb.cols) + " x " + std::to_string(rgb.rows));
}

int run_decode(const std::vector<std::string>& args, const std::string& pattern_file, const DecodeFiles& files,
               const vision::DecoderOptions& options, const EpipolarInputs& epipolar) {
  const std::string &json_out = files.json_out, &json_dir = files.json_dir, &overlay_out = files.overlay_out;
  const pattern::MArray marray = servo::load_decodable_pattern(pattern_file);
  if (epipolar.projector) calibration::check_projector_against_pattern(*epipolar.projector, marray, pattern_file);
  const vision::SpotDecoder decoder(pattern::WindowTable(marray, {3, 3}), options);
  const std::vector<std::filesystem::path> images = image_list(args);
  if (images.size() > 1 && (!json_out.empty() || !overlay_out.empty() || !files.white.empty()))
    throw std::runtime_error("--json, --overlay and --white take one image; for several, --json-dir DIR");
  const cv::Mat white = files.white.empty() ? cv::Mat() : read_rgb(files.white);
  if (!json_dir.empty()) common::make_output_folder(json_dir);
  std::vector<double> times;
  std::set<std::string> written;
  bool warm = false;
  vision::DecodeScratch scratch;  // the decoder's room, reused from image to image
  int failed = 0;
  for (std::size_t i = 0; i < images.size(); ++i) {
    const std::string image = images[i].string();
    cv::Mat rgb;
    try {
      rgb = read_rgb(image);
    } catch (const std::exception& e) {
      std::string what = e.what();
      for (char& ch : what)
        if (ch == '\n' || ch == '\r') ch = ' ';
      std::fprintf(stderr, "servo: %s\n", what.c_str());
      ++failed;
      continue;
    }
    check_white(files.white, white, image, rgb);
    std::optional<vision::EpipolarGeometry> geometry;
    if (epipolar.projector) {
      try {
        const Eigen::Isometry3d pose = epipolar.fixed_pose ? *epipolar.fixed_pose : sidecar_pose(images[i]);
        geometry.emplace(epipolar.camera, *epipolar.projector, pose, options.epipolar.tolerance_px);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "servo: %s\n", common::printable(e.what(), 300).c_str());
        ++failed;
        continue;
      }
    }
    const vision::EpipolarGeometry* g = geometry ? &*geometry : nullptr;
    if (!warm) {
      decode_one(decoder, rgb, white, g, epipolar, scratch);  // the first decode allocates; every time below is a warm one
      warm = true;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const vision::DecodeResult r = decode_one(decoder, rgb, white, g, epipolar, scratch);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    times.push_back(ms);
    std::string json_file = json_out;
    if (!json_dir.empty()) {
      std::string stem = images[i].stem().string();
      for (int k = 2; written.count(stem); ++k) stem = images[i].stem().string() + "_" + std::to_string(k);
      written.insert(stem);
      json_file = (std::filesystem::path(json_dir) / (stem + ".json")).string();
    }
    if (!json_file.empty()) write_decode_json(json_file, image, r, ms);
    if (!overlay_out.empty()) {
      cv::Mat bgr;
      cv::cvtColor(vision::draw_overlay(rgb, r), bgr, cv::COLOR_RGB2BGR);
      common::write_output_image(overlay_out, bgr);
    }
    std::printf("%s: %zu spots detected, %zu decoded in %.2f ms\n", image.c_str(), r.detected.size(), r.decoded.size(),
                ms);
    warn_if_suspect(image, rgb, r, epipolar);
  }
  if (times.size() > 1) {
    const std::vector<double> rest(times.begin() + 1, times.end());
    std::printf("decode: %zu images, warm decoder per frame (first image excluded): median %.2f ms, max %.2f ms\n",
                times.size(), median_of(rest), *std::max_element(rest.begin(), rest.end()));
  }
  if (failed > 0 && images.size() > 1) std::fprintf(stderr, "servo: %d of %zu images could not be read\n", failed, images.size());
  return failed == 0 ? 0 : 1;
}

}  // namespace

namespace {

// The camera's colour crosstalk (vision::SegmentationOptions::crosstalk), a calibration as the
// intrinsics are; `value` keeps its default when the flag is not given.
void add_crosstalk_option(CLI::App* c, double& value) {
  c->add_option("--crosstalk", value,
                "the camera's channel crosstalk, as calibrated: the fraction of each colour channel leaking into "
                "each other (default 0.06, the simulator's camera; in a servo config, crosstalk); with --projector the "
                "segmentation's chroma levels scale with it")
      ->check(common::finite_in(0, vision::kMaxCrosstalk));
}

// One struct per subcommand: its flags, and what it runs once they are parsed.
struct DecodeCommand {
  std::string pattern_file, projector;
  DecodeFiles files;
  std::vector<std::string> images;
  bool tolerant = false, fitted_lines = false;
  int min_votes = vision::DecoderOptions{}.min_votes;
  int segment_length = vision::EpipolarOptions{}.segment_length;
  double crosstalk = vision::kLevelsCrosstalk;
  std::vector<double> camera, pose;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("decode", "segment and decode the coded spots of images (files or folders)");
    c->add_option("images", images, "image files (PNG, JPEG, ...) or folders of them")->required();
    c->add_option("--pattern", pattern_file, "pattern file")->required();
    c->add_option("--json", files.json_out, "decoded spots as JSON (one image)");
    c->add_option("--json-dir", files.json_dir, "one JSON per image, named after it, with its warm decoding time_ms");
    c->add_option("--overlay", files.overlay_out, "image with the decoded ids drawn on it");
    c->add_option("--white", files.white,
                  "the white reference frame taken at the image's pose (the projector casting white; `cellsim render "
                  "--white`): the image is decoded as its ratio to it, the surface's albedo divided out (one image)");
    c->add_flag("--tolerant", tolerant, "error-tolerant window reading (beyond the paper)");
    c->add_option("--min-votes", min_votes, "windows that must name a spot (1: the paper)")
        ->check(CLI::Range(1, 9))
        ->capture_default_str();
    c->add_option("--segment-length", segment_length,
                  "with --projector: spots in a 1 x N row or column reading, decoder step 3b (under 3: off; the "
                  "lines no window reads: docs/decoding.md)")
        ->check(CLI::Range(0, 15))
        ->capture_default_str();
    c->add_option("--projector", projector,
                  "projector calibration (YAML, from `cellsim calibration`): check ids along the epipolar lines "
                  "and grow the identified lattice; needs --camera and a camera pose");
    c->add_option("--camera", camera,
                  "camera intrinsics: fx fy cx cy [k1 k2 p1 p2 k3]; without --projector, a spot off the epipolar "
                  "lines fitted to the frame's own spots is marked off_line (docs/decoding.md)")
        ->expected(4, 9);
    c->add_flag("--fitted-lines", fitted_lines,
                "with --camera, without --projector: decode again on the epipolar lines fitted to the first "
                "decoding's spots, as with a calibration (docs/decoding.md)");
    add_crosstalk_option(c, crosstalk);
    c->add_option("--camera-pose", pose,
                  "camera pose in the world for every image: x y z qx qy qz qw (default: each image's "
                  "<stem>.json camera_pose, as `cellsim render --truth` writes)")
        ->expected(7);
    return c;
  }
  int run() const {
    EpipolarInputs epi;
    if (!projector.empty()) {
      if (camera.size() != 4 && camera.size() != 9)
        throw std::runtime_error("--projector needs --camera fx fy cx cy [k1 k2 p1 p2 k3]");
      epi.projector = calibration::load_projector_calibration(projector);
    }
    if (!camera.empty()) {
      if (camera.size() != 4 && camera.size() != 9)
        throw std::runtime_error("--camera: 4 numbers (fx fy cx cy) or 9 (and k1 k2 p1 p2 k3)");
      check_finite("--camera", camera, 1e6);
      if (!(camera[0] > 0 && camera[1] > 0)) throw std::runtime_error("--camera: fx and fy must be > 0");
      epi.camera = {camera[0], camera[1], camera[2], camera[3]};
      epi.camera_given = true;
      for (std::size_t k = 4; k < camera.size(); ++k) {
        check_finite("--camera distortion", {camera[k]}, 10);
        epi.camera.distortion[k - 4] = camera[k];
      }
    }
    if (!pose.empty())
      epi.fixed_pose = pose_from("--camera-pose", {pose[0], pose[1], pose[2]}, {pose[3], pose[4], pose[5], pose[6]});
    vision::DecoderOptions options;
    options.tolerance.enabled = tolerant;
    options.min_votes = min_votes;
    options.epipolar.segment_length = segment_length;
    if (fitted_lines && (camera.empty() || !projector.empty()))
      throw std::runtime_error("--fitted-lines needs --camera and no --projector (the calibration's lines serve then)");
    options.epipolar.fitted_lines = fitted_lines;
    options.segmentation.crosstalk = crosstalk;
    return run_decode(images, pattern_file, files, options, epi);
  }
};

// The flags that set the servo's configuration, shared by `run` and `replay` (a replay with
// other flags shows what that configuration would have commanded).
struct ServoConfigFlags {
  std::string config_file, model, projector_file, robust, features;
  double z_hat = 0, gain = 0, divergence_ratio = -1;
  int points = -1;
  bool interior_points = false, fitted_lines = false, taught_points = false, white_frame = false;
  bool no_epipolar = false;
  double crosstalk = -1;
  void add(CLI::App* c) {
    c->add_option("--config", config_file, "servo configuration (YAML)");
    add_crosstalk_option(c, crosstalk);
    c->add_option("--model", model, "interaction matrix: desired-constant-depth | desired | current | mean");
    c->add_option("--z-hat", z_hat, "depth of desired-constant-depth (m)")->check(common::finite_in(0, 100));
    c->add_option("--gain", gain, "constant gain")->check(common::finite_in(1e-9, 1e3));
    c->add_option("--projector", projector_file,
                  "projector calibration (YAML, from `cellsim calibration`): depths by triangulation for the "
                  "desired, current and mean models, and decoding with the epipolar check");
    c->add_option("--robust", robust,
                  "tukey | huber | none: M-estimator weights on the points (v = -lambda (W L)^+ W (s - s*); config "
                  "key robust)");
    c->add_option("--divergence-ratio", divergence_ratio,
                  "stop (zero twist, STOPPED) when |e| rises above this x its first value after START (0: never)")
        ->check(CLI::Range(0.0, 1e6));
    c->add_option("--points", points,
                  "servo on this many points, chosen at teaching for the best-conditioned interaction matrix "
                  "(0: all)")
        ->check(CLI::Range(0, 4096));
    c->add_flag("--interior-points", interior_points,
                "servo on the interior of the matched spots: those whose four pattern neighbours are matched too, "
                "when they are at least half of them (config key interior_points)");
    c->add_flag("--taught-points", taught_points,
                "with --projector: hold each id to the point its spot lit at teaching; a spot away from it is no "
                "feature (config key taught_points; docs/decoding.md)");
    c->add_flag("--fitted-lines", fitted_lines,
                "without --projector: decode each frame again on the epipolar lines fitted to its first decoding's "
                "spots, as with a calibration (config key fitted_lines; docs/decoding.md)");
    c->add_flag("--no-epipolar", no_epipolar,
                "with --projector: triangulate only; decode without the epipolar check and the grown lattice");
    c->add_flag("--white-frame", white_frame,
                "decode each image as its ratio to the white reference frame of the same stamp (the projector "
                "casting white, on rt/camera/white/image_raw: `cellsim serve --white-frame`), the surface's albedo "
                "divided out; an image without one is rejected (config key white_frame; docs/decoding.md)");
    c->add_option("--visual-features", features,
                  "points (every decoded spot's x, y) | moments (the six image moments of the matched spots) | "
                  "surface (the plane of the triangulated spots and three moments: needs --projector) | plane (its "
                  "normal and distance alone, three degrees of freedom: the one for a projector on the camera); "
                  "config key visual_features")
        ->check(CLI::IsMember({"points", "moments", "surface", "plane"}));
  }
  void apply_to(servo::ServoConfig& config) const {
    if (!config_file.empty()) servo::load_servo_config(config_file, config);
    if (!model.empty()) config.law.model = control::parse_interaction_model(model);
    if (z_hat != 0) {
      common::require_within("--z-hat", z_hat, 1e-3, 100);
      config.law.z_hat_m = z_hat;
    }
    if (gain != 0) {
      common::require_within("--gain", gain, 1e-6, 100);
      config.law.gain = {gain, gain, 0};
    }
    if (!projector_file.empty()) config.projector = calibration::load_projector_calibration(projector_file);
    config.decoder.epipolar.enabled = !no_epipolar;
    if (crosstalk >= 0) config.decoder.segmentation.crosstalk = crosstalk;
    if (points >= 0) config.points = points;
    if (interior_points) config.interior_points = true;
    if (taught_points) config.taught_points = true;
    if (white_frame) config.white_frame = true;
    if (fitted_lines) config.decoder.epipolar.fitted_lines = true;
    if (divergence_ratio >= 0) config.divergence_ratio = divergence_ratio;
    if (!robust.empty()) config.law.robust = control::parse_robust_estimator(robust);
    if (!features.empty()) config.law.features = control::parse_visual_features(features);
  }
};

// --commands of `servo run` and `servo replay` (servo::CommandSource)
void add_commands_flag(CLI::App* c, servo::CommandSource& source) {
  c->add_option("--commands", source,
                "simulator: the commands cellsim obeyed (rt/sim/accepted); clients: rt/sim/control itself (a servo "
                "beside another simulator or a robot's driver; a recording made before rt/sim/accepted existed)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, servo::CommandSource>{
          {"simulator", servo::CommandSource::kSimulator}, {"clients", servo::CommandSource::kClients}}))
      ->default_str("simulator");
}

struct RunCommand {
  servo::ServiceOptions svc;
  std::string pattern_file, reference;
  ServoConfigFlags law;
  cell_dds::DdsFlags dds;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("run", "run the controller as a DDS service");
    c->add_option("--pattern", pattern_file, "pattern file")->required();
    law.add(c);
    dds.add_to(*c);
    c->add_option("--lost-ms", svc.lost_ms, "no image for this long: zero twist, state LOST")->capture_default_str();
    c->add_option("--reference", reference, "s* file: loaded when it exists, written after teaching");
    c->add_flag("--autostart", svc.autostart, "servo as soon as a reference exists");
    add_commands_flag(c, svc.commands);
    return c;
  }
  int run() {
    svc.pattern = pattern_file;
    common::require_within("--lost-ms", svc.lost_ms, 1, 60000);
    law.apply_to(svc.config);
    dds.apply_to(svc);
    svc.reference = reference;
    return servo::run_servo_service(svc);
  }
};

struct ReplayCommand {
  servo::ReplayOptions replay;
  ServoConfigFlags law;
  bool no_plot = false, expect_identical = false;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("replay",
                                 "feed a recorded run (cellsim serve --record) through the servo and compare the "
                                 "twists it would send with the recorded ones");
    c->add_option("recording", replay.recording, "MCAP file")->required();
    c->add_option("--pattern", replay.pattern, "pattern file (the one the recorded servo decoded)")->required();
    law.add(c);
    c->add_option("--reference", replay.reference,
                  "s* to start from (the recorded run's --reference, when it did not teach); default: taught from "
                  "the recording's teach frame");
    c->add_option("--lost-ms", replay.lost_ms, "as servo run --lost-ms")->capture_default_str();
    c->add_flag("--autostart", replay.autostart, "as servo run --autostart");
    add_commands_flag(c, replay.commands);
    c->add_option("-o,--output", replay.output, "folder for replay.csv and replay.png");
    c->add_flag("--no-plot", no_plot, "do not draw replay.png");
    c->add_flag("--expect-identical", expect_identical,
                "exit 1 unless every recorded twist is reproduced bit for bit (for CI)");
    return c;
  }
  int run() {
    common::require_within("--lost-ms", replay.lost_ms, 1, 60000);
    law.apply_to(replay.config);
    replay.plot = !no_plot;
    const servo::ReplayResult r = servo::run_replay(replay);
    if (r.truncated) std::printf("servo replay: %s; replayed what it holds\n", r.truncated->c_str());
    if (r.white_frames && !replay.config.white_frame)
      std::printf("servo replay: %s holds white reference frames; replayed without them (--white-frame takes them)\n",
                  replay.recording.c_str());
    if (r.stopped)
      std::printf("servo replay: %s: the recording stopped before the run ended (%s); replayed what it holds\n",
                  replay.recording.c_str(), r.stopped->c_str());
    std::printf("servo replay: %s: %ld images, %ld recorded twists compared", replay.recording.c_str(), r.images,
                r.compared);
    if (r.differing == 0)
      std::printf(": every one identical bit for bit");
    else
      std::printf(": %ld differ, max |difference| %.6g (m/s, rad/s), the first at t = %.3f s", r.differing,
                  r.max_difference, r.first_differing_s.value_or(0));
    std::printf("; %ld recorded twists not answered, %ld replayed twists not recorded", r.recorded_only, r.replayed_only);
    if (r.past_cut > 0) std::printf("; %ld recorded twists answer images past the cut", r.past_cut);
    if (r.lost_recorded + r.lost_replayed > 0)
      std::printf("; LOST notices (not compared): %ld recorded, %ld replayed", r.lost_recorded, r.lost_replayed);
    std::printf("\n");
    if (!replay.output.empty()) {
      std::printf("servo replay: trace %s\n", (replay.output / "replay.csv").c_str());
      if (replay.plot) common::run_plot_script("servo replay", "plot_replay.py", replay.output, replay.recording.filename().string());
    }
    std::fflush(stdout);
    const bool identical = r.differing == 0 && r.recorded_only == 0 && r.compared > 0;
    return expect_identical && !identical ? 1 : 0;
  }
};

struct ViewCommand {
  servo::ViewOptions view;
  std::string out;
  cell_dds::DdsFlags dds;
  CLI::App* add(CLI::App& app) {
    auto* c = app.add_subcommand("view", "live view of the camera with the decoded ids (window, or PNGs headless)");
    dds.add_to(*c);
    c->add_option("-o,--output", out, "write a PNG sequence here instead of opening a window");
    c->add_option("--frames", view.frames, "stop after this many frames")->capture_default_str();
    c->add_option("--every", view.every, "keep one frame in N")->capture_default_str()->check(CLI::PositiveNumber);
    return c;
  }
  int run() {
    dds.apply_to(view);
    view.output = out;
    return servo::run_viewer(view);
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"servo: structured-light visual-servoing controller"};
  common::plain_help(app);
  common::verbosity_flags(app);
  app.set_version_flag("--version", std::string("servo ") + CELL_VERSION);
  app.require_subcommand(1);
  DecodeCommand decode;
  RunCommand run;
  ReplayCommand replay;
  ViewCommand view;
  const common::Subcommands commands = {
      {decode.add(app), [&] { return decode.run(); }},
      {run.add(app), [&] { return run.run(); }},
      {replay.add(app), [&] { return replay.run(); }},
      {view.add(app), [&] { return view.run(); }},
  };
  // a backstop for the formats whose header read_rgb does not read: OpenCV refuses to
  // decode beyond this many pixels (read once, before the first decode)
  setenv("OPENCV_IO_MAX_IMAGE_PIXELS", std::to_string(servo::kMaxImagePixels).c_str(), 1);
  common::require_finite_numbers(app);
  if (const int rc = common::parse_command_line(app, argc, argv, "servo"); rc >= 0) return rc;
  // The decoder's per-frame OpenCV operations are too small to gain from OpenCV's thread
  // pool: measured 2.1 ms per VGA frame with it, 1.5 ms without (docs/performance.md).
  cv::setNumThreads(1);
  return common::run_subcommand(commands, "servo");
}
