// `cellsim`: the robot-cell simulator's command line. `render` renders one frame offline.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "servo/pattern/window_table.hpp"
#include "sim/app/decode_sweep.hpp"
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

int run_decode_sweep(const std::string& scenario_file, cellsim::SweepOptions o) {
  const auto cell = sim::build_cell(sim::load_scenario(scenario_file));
  if (!o.out_dir.empty()) std::filesystem::create_directories(o.out_dir);
  const auto t0 = std::chrono::steady_clock::now();
  const cellsim::SweepSummary s = cellsim::run_decode_sweep(*cell, o);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%s: %d poses (noise sigma", cell->scenario.name.c_str(), o.poses);
  for (double n : o.noise_sigmas) std::printf(" %.1f", n);
  std::printf(") in %.1f s\n", secs);
  std::printf("  decoded %d of %d visible (mean rate %.1f %%, worst pose %.1f %%), wrong ids %d, mislocated %d\n",
              s.total_decoded, s.total_visible, 100 * s.mean_rate, 100 * s.min_rate, s.total_wrong,
              s.total_mislocated);
  std::printf("  decode time median %.2f ms, p99 %.2f ms\n", s.median_ms, s.p99_ms);
  if (!o.out_dir.empty()) std::printf("  per-pose table: %s\n", (o.out_dir / "sweep.csv").c_str());
  return s.total_wrong == 0 ? 0 : 3;
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
  cellsim::SweepOptions sweep;
  std::string sweep_dir;
  bool tolerant = false;
  auto* ds = app.add_subcommand("decode-sweep", "decoder accuracy against the ground truth over random poses");
  ds->add_option("scenario", scenario, "scenario YAML file")->required();
  ds->add_option("--poses", sweep.poses, "random poses")->capture_default_str()->check(CLI::PositiveNumber);
  ds->add_option("--seed", sweep.seed, "seed of the pose draw and the noise")->capture_default_str();
  ds->add_option("--noise", sweep.noise_sigmas, "sensor noise sigmas to cycle through (8-bit units)");
  ds->add_option("--min-votes", sweep.decoder.min_votes, "windows that must name a spot")->capture_default_str();
  ds->add_option("--min-island", sweep.decoder.min_island, "smallest island of decoded spots kept (0: off)")
      ->capture_default_str();
  ds->add_flag("--tolerant", tolerant, "error-tolerant window reading");
  ds->add_option("--threads", sweep.threads, "worker threads")->capture_default_str();
  ds->add_option("-o,--output", sweep_dir, "folder for sweep.csv and overlays of poses with wrong ids");
  CLI11_PARSE(app, argc, argv);
  try {
    if (*render) return run_render(scenario, pose, out, truth, frame);
    if (*ds) {
      sweep.decoder.tolerance.enabled = tolerant;
      sweep.out_dir = sweep_dir;
      return run_decode_sweep(scenario, sweep);
    }
  } catch (const std::exception& e) {
    std::cerr << "cellsim: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
