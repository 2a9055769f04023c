// `servo`: the visual-servoing controller's command line. `decode` decodes one image.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "servo/pattern/pattern_file.hpp"
#include "servo/vision/overlay.hpp"
#include "servo/vision/spot_decoder.hpp"
#include "servo/app/servo_service.hpp"
#include "servo/app/servo_view.hpp"
#include "dds/participant.hpp"

namespace {

cv::Mat read_rgb(const std::string& path) {
  // IMREAD_COLOR turns grey and binary images into 3 equal channels: they have no chroma,
  // so they decode to zero spots instead of failing
  cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
  if (bgr.empty()) throw std::runtime_error(path + ": cannot read image (missing, empty or not an image)");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

int run_decode(const std::string& image, const std::string& pattern_file, const std::string& json_out,
               const std::string& overlay_out, bool tolerant, int min_votes) {
  const pattern::MArray marray = pattern::load_pattern(pattern_file, {3, 3});
  vision::DecoderOptions options;
  options.tolerance.enabled = tolerant;
  options.min_votes = min_votes;
  const vision::SpotDecoder decoder(pattern::WindowTable(marray, {3, 3}), options);
  const cv::Mat rgb = read_rgb(image);
  const auto t0 = std::chrono::steady_clock::now();
  const vision::DecodeResult r = decoder.decode(rgb);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!json_out.empty()) {
    nlohmann::json j;
    j["spots"] = nlohmann::json::array();
    for (const auto& d : r.decoded) j["spots"].push_back({{"row", d.row}, {"col", d.col}, {"u", d.u}, {"v", d.v}});
    j["detected"] = r.detected.size();
    j["decoded"] = r.decoded.size();
    j["time_ms"] = ms;
    std::ofstream f(json_out);
    if (!f) throw std::runtime_error(json_out + ": cannot write");
    f << j.dump(1) << "\n";
  }
  if (!overlay_out.empty()) {
    cv::Mat bgr;
    cv::cvtColor(vision::draw_overlay(rgb, r), bgr, cv::COLOR_RGB2BGR);
    if (!cv::imwrite(overlay_out, bgr)) throw std::runtime_error(overlay_out + ": cannot write overlay");
  }
  std::printf("%s: %zu spots detected, %zu decoded in %.2f ms\n", image.c_str(), r.detected.size(), r.decoded.size(), ms);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"servo: structured-light visual-servoing controller"};
  app.require_subcommand(1);
  std::string image, pattern_file, json_out, overlay_out;
  bool tolerant = false;
  int min_votes = vision::DecoderOptions{}.min_votes;
  auto* decode = app.add_subcommand("decode", "segment and decode the coded spots of one image");
  decode->add_option("image", image, "image file (PNG, JPEG, ...)")->required();
  decode->add_option("--pattern", pattern_file, "pattern file")->required();
  decode->add_option("--json", json_out, "decoded spots as JSON");
  decode->add_option("--overlay", overlay_out, "image with the decoded ids drawn on it");
  decode->add_flag("--tolerant", tolerant, "error-tolerant window reading (beyond the paper)");
  decode->add_option("--min-votes", min_votes, "windows that must name a spot (1: the paper)")
      ->check(CLI::Range(1, 9))->capture_default_str();
  servo::ServiceOptions svc;
  std::string config_file, model, reference, projector_file;
  double z_hat = 0, gain = 0;
  int domain = -1;
  auto* run = app.add_subcommand("run", "run the controller as a DDS service");
  run->add_option("--pattern", pattern_file, "pattern file")->required();
  run->add_option("--config", config_file, "servo configuration (YAML)");
  run->add_option("--model", model, "interaction matrix: desired-constant-depth | desired | current | mean");
  run->add_option("--z-hat", z_hat, "depth of desired-constant-depth (m)");
  run->add_option("--gain", gain, "constant gain");
  run->add_option("--domain", domain, "DDS domain id (default: $ROS_DOMAIN_ID or 0)");
  run->add_option("--lost-ms", svc.lost_ms, "no image for this long: zero twist, state LOST")->capture_default_str();
  run->add_option("--reference", reference, "s* file: loaded when it exists, written after teaching");
  run->add_option("--projector", projector_file,
                  "projector calibration (YAML, from `cellsim calibration`): depths by triangulation for the "
                  "desired, current and mean models");
  run->add_flag("--autostart", svc.autostart, "servo as soon as a reference exists");

  servo::ViewOptions view;
  std::string view_out;
  auto* vw = app.add_subcommand("view", "live view of the camera with the decoded ids (window, or PNGs headless)");
  vw->add_option("--domain", domain, "DDS domain id (default: $ROS_DOMAIN_ID or 0)");
  vw->add_option("-o,--output", view_out, "write a PNG sequence here instead of opening a window");
  vw->add_option("--frames", view.frames, "stop after this many frames")->capture_default_str();
  vw->add_option("--every", view.every, "keep one frame in N")->capture_default_str()->check(CLI::PositiveNumber);

  CLI11_PARSE(app, argc, argv);
  // The decoder's per-frame OpenCV operations are too small to gain from OpenCV's thread
  // pool: measured 2.1 ms per VGA frame with it, 1.5 ms without (docs/performance.md).
  cv::setNumThreads(1);
  try {
    if (*vw) {
      view.domain_id = domain >= 0 ? domain : cell_dds::domain_id_from_env(0);
      view.output = view_out;
      return servo::run_viewer(view);
    }
    if (*run) {
      svc.pattern = pattern_file;
      if (!config_file.empty()) servo::load_servo_config(config_file, svc.config);
      if (!model.empty()) svc.config.law.model = control::parse_interaction_model(model);
      if (z_hat > 0) svc.config.law.z_hat_m = z_hat;
      if (gain > 0) svc.config.law.gain = {gain, gain, 0};
      svc.domain_id = domain >= 0 ? domain : cell_dds::domain_id_from_env(0);
      svc.reference = reference;
      if (!projector_file.empty()) svc.config.projector = servo::load_projector_calibration(projector_file);
      return servo::run_servo_service(svc);
    }
    if (*decode) return run_decode(image, pattern_file, json_out, overlay_out, tolerant, min_votes);
  } catch (const std::exception& e) {
    std::cerr << "servo: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
