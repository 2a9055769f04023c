// Rendering cost: one VGA frame against casting one Bullet ray per pixel (what the z-buffer
// replaces), the projector's rays per second, and growth with pattern and image size.
#include <chrono>
#include <benchmark/benchmark.h>

#include <filesystem>
#include <map>
#include <memory>

#include "bench/bench_scenes.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/render/renderer.hpp"
#include "support/previous_renderer.hpp"

namespace {

std::unique_ptr<sim::Cell> make_cell(const std::string& name, int pattern_size = 20, double image_scale = 1.0) {
  return sim::build_cell(sim::resolve(bench::scaled_scenario(name, pattern_size, image_scale)));
}

void render(benchmark::State& state, const sim::Cell& cell) {
  sim::RenderScratch scratch;
  std::uint64_t frame = 0;
  for (auto _ : state) {
    cv::Mat img = sim::render_image(cell, cell.scenario.world_T_initial(), sim::frame_seed(1, frame++), &scratch);
    benchmark::DoNotOptimize(img.data);
  }
  state.counters["px/s"] = benchmark::Counter(static_cast<double>(cell.scenario.camera.intrinsics.width) *
                                                  cell.scenario.camera.intrinsics.height,
                                              benchmark::Counter::kIsIterationInvariantRate);
}

void BM_RenderVga(benchmark::State& state, const char* scenario) {
  static std::map<std::string, std::unique_ptr<sim::Cell>> cells;
  auto& cell = cells[scenario];
  if (!cell) cell = make_cell(scenario);
  render(state, *cell);
}

// The baseline: find each pixel's surface with one Bullet ray per pixel (geometry only, no
// shading), as a ray tracer would, instead of the z-buffer.
void BM_RenderVgaBaseline(benchmark::State& state) {
  static auto cell = make_cell("plane");
  const auto& k = cell->scenario.camera.intrinsics;
  const Eigen::Isometry3d wTc = cell->scenario.world_T_initial();
  const auto& rays = cell->camera->pixel_rays();
  for (auto _ : state) {
    int hits = 0;
    for (std::size_t i = 0; i < rays.size(); i += 2) {
      const Eigen::Vector3d d = wTc.linear() * Eigen::Vector3d(rays[i], rays[i + 1], 1.0);
      hits += cell->world.ray_test(wTc.translation(), wTc.translation() + 10.0 * d).has_value();
    }
    benchmark::DoNotOptimize(hits);
  }
  state.counters["px/s"] =
      benchmark::Counter(static_cast<double>(k.width) * k.height, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_ProjectorRays(benchmark::State& state) {
  static auto cell = make_cell("cylinder");
  std::size_t rays = 0;
  for (auto _ : state) {
    auto hits = cell->projector->cast_spots(cell->world);
    rays += hits.size() * (1 + sim::Projector::kRimSamples);
    benchmark::DoNotOptimize(hits.data());
  }
  state.counters["rays/s"] = benchmark::Counter(static_cast<double>(rays), benchmark::Counter::kIsRate);
}

void BM_Truth(benchmark::State& state) {
  static auto cell = make_cell("cylinder");
  for (auto _ : state) {
    auto truth = sim::compute_truth(*cell, cell->scenario.world_T_desired);
    benchmark::DoNotOptimize(truth.data());
  }
}

void BM_RenderPatternSize(benchmark::State& state) {
  static std::map<int, std::unique_ptr<sim::Cell>> cells;
  const int n = static_cast<int>(state.range(0));
  auto& cell = cells[n];
  if (!cell) cell = make_cell("cylinder", n);
  render(state, *cell);
}

void BM_RenderImageSize(benchmark::State& state) {
  static std::map<int, std::unique_ptr<sim::Cell>> cells;
  const int h = static_cast<int>(state.range(0));
  auto& cell = cells[h];
  if (!cell) cell = make_cell("cylinder", 20, h / 480.0);
  render(state, *cell);
}

}  // namespace

BENCHMARK(BM_RenderVgaBaseline)->Name("render_vga/baseline_bullet_ray_per_pixel")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderVga, plane, "plane")->Name("render_vga/plane")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderVga, cylinder, "cylinder")->Name("render_vga/cylinder")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ProjectorRays)->Name("projector/cast_400_spots_17_rays")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Truth)->Name("projector/truth_400_spots")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderPatternSize)->Name("render_pattern/baseline_20x20")->Arg(20)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderPatternSize)->Name("render_pattern/40x40")->Arg(40)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderPatternSize)->Name("render_pattern/64x64")->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderImageSize)->Name("render_image/baseline_vga")->Arg(480)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderImageSize)->Name("render_image/720p")->Arg(720)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RenderImageSize)->Name("render_image/1080p")->Arg(1080)->Unit(benchmark::kMillisecond);

namespace {

// The arm in the frame (issue 10): the same VGA frame rendered without and with the arm's
// links. "in_beam": the robot's camera at the initial pose of cylinder_occlusion, the arm in
// the projector's beam (its shadow on the cylinder, spots landing on it); "in_view": an
// observer camera that sees the arm and the cylinder.
struct ArmScene {
  std::unique_ptr<sim::Cell> cell;
  sim::LinkPoses links;
  Eigen::Isometry3d robot_camera, observer;
};

const ArmScene& arm_scene() {
  static const ArmScene scene = [] {
    ArmScene s;
    s.cell = sim::build_cell(sim::load_scenario(std::string(CELL_SOURCE_DIR) + "/sim/scenarios/cylinder_occlusion.yaml"));
    const auto robot = sim::make_robot(*s.cell);
    robot->reset(s.cell->scenario.world_T_initial());
    s.links = robot->world_T_links();
    s.robot_camera = robot->world_T_camera();
    s.observer = sim::look_at({0.9, -1.4, 1.0}, {0.5, 0.0, 0.45}, Eigen::Vector3d::UnitZ());
    return s;
  }();
  return scene;
}

void BM_ArmFrame(benchmark::State& state, bool observer, bool with_arm) {
  const ArmScene& s = arm_scene();
  sim::RenderScratch scratch;
  std::uint64_t frame = 0;
  for (auto _ : state) {
    cv::Mat img = sim::render_image(*s.cell, observer ? s.observer : s.robot_camera, sim::frame_seed(1, frame++), &scratch,
                                    nullptr, with_arm ? &s.links : nullptr);
    benchmark::DoNotOptimize(img.data);
  }
}

}  // namespace

BENCHMARK_CAPTURE(BM_ArmFrame, beam_base, false, false)->Name("render_arm_in_beam/baseline_no_arm")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ArmFrame, beam_arm, false, true)->Name("render_arm_in_beam/with_arm")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ArmFrame, view_base, true, false)->Name("render_arm_in_view/baseline_no_arm")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ArmFrame, view_arm, true, true)->Name("render_arm_in_view/with_arm")->Unit(benchmark::kMillisecond);

namespace {

// Issue 22: the renderer against the renderer before issue 22 (tests/support/previous_renderer:
// double precision, each spot's box shaded from scratch), on one core. The scenes: the
// plane and the cylinder at their initial poses (the robot's camera, the arm out of view), and
// the arm in the projector's beam with the back wall's blurred spots (a campaign's frames).
enum class Scene { kPlane, kCylinder, kBeam };
struct SceneFrame {
  const sim::Cell* cell;
  Eigen::Isometry3d camera;
  const sim::LinkPoses* links;
};
SceneFrame scene_frame(Scene scene) {
  if (scene == Scene::kBeam) {
    const ArmScene& s = arm_scene();
    return {s.cell.get(), s.robot_camera, &s.links};
  }
  static std::map<Scene, std::unique_ptr<sim::Cell>> cells;
  auto& cell = cells[scene];
  if (!cell) cell = make_cell(scene == Scene::kPlane ? "plane" : "cylinder");
  return {cell.get(), cell->scenario.world_T_initial(), nullptr};
}

void BM_OneCore(benchmark::State& state, Scene scene, bool reference) {
  const SceneFrame f = scene_frame(scene);
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  sim::RenderScratch scratch;
  std::uint64_t frame = 0;
  double fastest = 1e300;  // the machine's noise only ever adds: the fastest frame is the steadiest figure
  for (auto _ : state) {
    const std::uint64_t seed = sim::frame_seed(1, frame++);
    const auto t0 = std::chrono::steady_clock::now();
    cv::Mat img = reference ? previous::render_image(*f.cell, f.camera, seed, nullptr, f.links)
                            : sim::render_image(*f.cell, f.camera, seed, &scratch, nullptr, f.links);
    benchmark::DoNotOptimize(img.data);
    fastest = std::min(fastest, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  state.counters["fastest_ms"] = fastest;
  cv::setNumThreads(threads);
}

// The reference, the AVX2 path and the best path (AVX-512 where the CPU has it) in turns,
// frame by frame: the machine's drift, which moves separate benchmarks by 20 % and more, moves
// the three alike. Counters: each one's median time and the medians of the per-turn ratios.
void BM_OneCoreInterleaved(benchmark::State& state, Scene scene) {
  const SceneFrame f = scene_frame(scene);
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  sim::RenderScratch avx2, best;
  avx2.avx512 = false;
  std::vector<double> t_ref, t_avx2, t_best, speedup, speedup_avx2;
  std::uint64_t frame = 0;
  for (auto _ : state) {
    using clock = std::chrono::steady_clock;
    const std::uint64_t seed = sim::frame_seed(1, frame++);
    const auto t0 = clock::now();
    const cv::Mat a = previous::render_image(*f.cell, f.camera, seed, nullptr, f.links);
    const auto t1 = clock::now();
    const cv::Mat b = sim::render_image(*f.cell, f.camera, seed, &avx2, nullptr, f.links);
    const auto t2 = clock::now();
    const cv::Mat c = sim::render_image(*f.cell, f.camera, seed, &best, nullptr, f.links);
    const auto t3 = clock::now();
    benchmark::DoNotOptimize(a.data);
    benchmark::DoNotOptimize(b.data);
    benchmark::DoNotOptimize(c.data);
    const auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
    t_ref.push_back(ms(t1 - t0));
    t_avx2.push_back(ms(t2 - t1));
    t_best.push_back(ms(t3 - t2));
    speedup.push_back(t_ref.back() / t_best.back());
    speedup_avx2.push_back(t_ref.back() / t_avx2.back());
  }
  cv::setNumThreads(threads);
  const auto median = [](std::vector<double> x) {
    std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
    return x.empty() ? 0.0 : x[x.size() / 2];
  };
  state.counters["reference_ms"] = median(t_ref);
  state.counters["avx2_ms"] = median(t_avx2);
  state.counters["render_ms"] = median(t_best);
  state.counters["speedup"] = median(speedup);
  state.counters["speedup_avx2"] = median(speedup_avx2);
}

}  // namespace

BENCHMARK_CAPTURE(BM_OneCoreInterleaved, plane, Scene::kPlane)->Name("one_core_interleaved/plane")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCoreInterleaved, cylinder, Scene::kCylinder)->Name("one_core_interleaved/cylinder")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCoreInterleaved, beam, Scene::kBeam)->Name("one_core_interleaved/arm_in_beam")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCore, plane_ref, Scene::kPlane, true)->Name("one_core_plane/baseline_reference")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCore, plane, Scene::kPlane, false)->Name("one_core_plane/render")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCore, cyl_ref, Scene::kCylinder, true)->Name("one_core_cylinder/baseline_reference")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCore, cyl, Scene::kCylinder, false)->Name("one_core_cylinder/render")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCore, beam_ref, Scene::kBeam, true)->Name("one_core_arm_in_beam/baseline_reference")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OneCore, beam, Scene::kBeam, false)->Name("one_core_arm_in_beam/render")->Unit(benchmark::kMillisecond);
