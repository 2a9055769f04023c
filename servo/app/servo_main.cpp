// `servo`: the visual-servoing controller's command line. `decode` decodes one image.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "servo/pattern/pattern_file.hpp"
#include "servo/vision/overlay.hpp"
#include "servo/vision/spot_decoder.hpp"

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
  CLI11_PARSE(app, argc, argv);
  try {
    if (*decode) return run_decode(image, pattern_file, json_out, overlay_out, tolerant, min_votes);
  } catch (const std::exception& e) {
    std::cerr << "servo: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
