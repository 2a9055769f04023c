// `cellsim`: the robot-cell simulator's command line. `render` renders one frame offline.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sim/geometry/se3.hpp"
#include "sim/render/renderer.hpp"

namespace {

nlohmann::json pose_json(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  return {{"position_m", {T.translation().x(), T.translation().y(), T.translation().z()}},
          {"orientation_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
}

void write_png_rgb(const std::string& path, const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  if (!cv::imwrite(path, bgr)) throw std::runtime_error(path + ": cannot write image");
}

int run_render(const std::string& scenario_file, const std::string& pose_spec, const std::string& out_png,
               const std::string& truth_file, std::uint64_t frame) {
  const sim::Scenario scenario = sim::load_scenario(scenario_file);
  const Eigen::Isometry3d wTc = sim::resolve_pose(scenario, pose_spec);
  const auto cell = sim::build_cell(scenario);
  const cv::Mat image = sim::render_image(*cell, wTc, sim::frame_seed(scenario.seed, frame));
  write_png_rgb(out_png, image);
  const auto truth = sim::compute_truth(*cell, wTc);
  int visible = 0;
  for (const auto& t : truth) visible += t.visible;
  if (!truth_file.empty()) {
    nlohmann::json j;
    j["scenario"] = scenario.name;
    j["camera_pose"] = pose_json(wTc);
    j["camera_pose"]["frame_id"] = "world";
    j["spots"] = nlohmann::json::array();
    for (const auto& t : truth) {
      nlohmann::json s{{"row", t.row}, {"col", t.col}, {"visible", t.visible}};
      if (t.visible) {
        s["u"] = t.uv.x();
        s["v"] = t.uv.y();
        s["depth_m"] = t.depth_m;
      }
      j["spots"].push_back(s);
    }
    std::ofstream f(truth_file);
    if (!f) throw std::runtime_error(truth_file + ": cannot write truth");
    f << j.dump(1) << "\n";
  }
  std::printf("%s: %s pose, %d of %zu spots visible -> %s\n", scenario.name.c_str(), pose_spec.c_str(), visible,
              truth.size(), out_png.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cellsim: simulator of a camera-projector robot cell"};
  app.require_subcommand(1);
  std::string scenario, pose = "desired", out, truth;
  std::uint64_t frame = 0;
  auto* render = app.add_subcommand("render", "render one camera frame of a scenario");
  render->add_option("scenario", scenario, "scenario YAML file")->required();
  render->add_option("--pose", pose,
                     "desired | initial | \"x y z rx ry rz\": offset from the desired pose, cm and deg "
                     "(translation along the desired camera axes, then rotations about X, Y, Z)")
      ->capture_default_str();
  render->add_option("-o,--output", out, "PNG image to write")->required();
  render->add_option("--truth", truth, "ground-truth JSON to write");
  render->add_option("--frame", frame, "frame index (selects the noise draw)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    if (*render) return run_render(scenario, pose, out, truth, frame);
  } catch (const std::exception& e) {
    std::cerr << "cellsim: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
