// Property: decode(render(pattern, pose)) recovers the true ids, at random poses around the
// desired one (the simulator's ground truth is the oracle; the decoder never sees it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "servo/pattern/pattern_file.hpp"
#include "servo/vision/spot_decoder.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/render/renderer.hpp"
#include "support/previous_renderer.hpp"

namespace {

// The visible spot nearest an image point (null: none visible), its distance in `best`.
const sim::SpotTruth* nearest_visible(const std::vector<sim::SpotTruth>& truth, double u, double v, double& best) {
  const sim::SpotTruth* nearest = nullptr;
  best = 1e18;
  for (const auto& tr : truth)
    if (tr.visible && std::hypot(tr.uv.x() - u, tr.uv.y() - v) < best)
      best = std::hypot(tr.uv.x() - u, tr.uv.y() - v), nearest = &tr;
  return nearest;
}

TEST(DecodeRender, RecoversTrueIdsAtRandomPoses) {
  const std::string dir = std::string(CELL_SOURCE_DIR) + "/sim/scenarios/";
  for (const char* name : {"plane", "cylinder", "ham"}) {
    const auto cell = sim::build_cell(sim::load_scenario(dir + name + ".yaml"));
    const vision::SpotDecoder decoder(pattern::WindowTable(cell->projector->pattern(), {3, 3}));
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> t(-6, 6), r(-6, 6);
    // wrong: the named spot is not the visible spot nearest the decoded blob; mislocated: it
    // is, the centroid more than 2 px from its centre (a spot on a surface seen at a grazing
    // angle, or cut by an edge: 2-4 px)
    int decoded = 0, wrong = 0, mislocated = 0;
    for (int k = 0; k < 6; ++k) {
      const Eigen::Isometry3d wTc = sim::offset_pose(cell->scenario.world_T_desired, {t(rng), t(rng), t(rng)},
                                                     {r(rng), r(rng), r(rng)}, cell->scenario.offset_frame_rotation_deg);
      const auto truth = sim::compute_truth(*cell, wTc);
      const auto result = decoder.decode(sim::render_image(*cell, wTc, sim::frame_seed(7, k)));
      for (const auto& d : result.decoded) {
        double best = 0;
        const sim::SpotTruth* nearest = nearest_visible(truth, d.u, d.v, best);
        wrong += !nearest || nearest->row != d.row || nearest->col != d.col;
        mislocated += best >= 2.0;
        ++decoded;
      }
    }
    EXPECT_EQ(wrong, 0) << name;
    EXPECT_LE(mislocated, decoded / 100) << name;
    EXPECT_GT(decoded, 6 * 80) << name;
  }
}

// A frame's ids checked against the truth: right, the visible spot nearest the centroid and
// within 2 px of it; wrong, not that spot, on its line (off_line: kept from the law).
struct Scored {
  int right = 0, wrong = 0;
};
Scored score(const vision::DecodeResult& r, const std::vector<sim::SpotTruth>& truth) {
  Scored s;
  for (const auto& d : r.decoded) {
    double best = 0;
    const sim::SpotTruth* nearest = nearest_visible(truth, d.u, d.v, best);
    const bool named = nearest && nearest->row == d.row && nearest->col == d.col;
    s.right += named && best < 2.0;
    s.wrong += !named && !d.off_line;
  }
  return s;
}

// Issue 41: on the printed box the label's inks take a spot's hue or most of its light; with
// the white reference frame taken at the same pose the decoder reads the ratio, and names more
// of the box's spots right, and no more wrong ones on their lines, at random poses about the
// desired one (decoded as the loop decodes: without the projector's calibration, each id off
// the lines fitted to the frame's own spots marked).
TEST(DecodeRender, TheWhiteFrameNamesMoreOfAPrintedBoxsSpots) {
  const auto cell = sim::build_cell(sim::load_scenario(std::string(CELL_SOURCE_DIR) + "/sim/scenarios/printed_box.yaml"));
  const vision::SpotDecoder decoder(pattern::WindowTable(cell->projector->pattern(), {3, 3}));
  const sim::CameraSpec& c = cell->scenario.camera;
  calibration::CameraIntrinsics camera{c.intrinsics.fx, c.intrinsics.fy, c.intrinsics.cx, c.intrinsics.cy};
  for (int k = 0; k < 5; ++k) camera.distortion[static_cast<std::size_t>(k)] = c.distortion[static_cast<std::size_t>(k)];
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> t(-3, 3), r(-3, 3);
  Scored alone, with_white;
  for (int k = 0; k < 6; ++k) {
    const Eigen::Isometry3d wTc = sim::offset_pose(cell->scenario.world_T_desired, {t(rng), t(rng), t(rng)},
                                                   {r(rng), r(rng), r(rng)}, cell->scenario.offset_frame_rotation_deg);
    const auto truth = sim::compute_truth(*cell, wTc);
    const std::uint64_t seed = sim::frame_seed(11, k);
    const cv::Mat pattern = sim::render_image(*cell, wTc, seed);
    const cv::Mat white = sim::render_image(*cell, wTc, sim::white_frame_seed(seed), nullptr, nullptr, nullptr,
                                            sim::Cast::kWhite);
    const Scored a = score(decoder.decode_uncalibrated(pattern, camera), truth),
                 b = score(decoder.decode_uncalibrated(pattern, white, camera), truth);
    alone.right += a.right, alone.wrong += a.wrong;
    with_white.right += b.right, with_white.wrong += b.wrong;
  }
  std::printf("printed box, 6 poses: right / wrong ids %d / %d from the pattern frame alone, %d / %d with the white "
              "frame\n", alone.right, alone.wrong, with_white.right, with_white.wrong);
  EXPECT_GT(with_white.right, alone.right + alone.right / 10);
  EXPECT_LE(with_white.wrong, alone.wrong);
}

TEST(DecodeRender, PapersCountsAtTheTaughtPoses) {
  const std::string dir = std::string(CELL_SOURCE_DIR) + "/sim/scenarios/";
  const auto count = [&](const char* name, bool initial) {
    const auto cell = sim::build_cell(sim::load_scenario(dir + name + ".yaml"));
    const vision::SpotDecoder decoder(pattern::WindowTable(cell->projector->pattern(), {3, 3}));
    const Eigen::Isometry3d wTc = initial ? cell->scenario.world_T_initial() : cell->scenario.world_T_desired;
    return decoder.decode(sim::render_image(*cell, wTc, sim::frame_seed(cell->scenario.seed, 0))).decoded.size();
  };
  EXPECT_GE(count("plane", false), 370u);     // paper: 370 of 400
  EXPECT_GE(count("plane", true), 361u);      // paper: 361
  EXPECT_GE(count("cylinder", false), 160u);  // paper: 160
  EXPECT_GE(count("cylinder", true), 148u);   // paper: 148
}

// Issue 22 redefined the images (single precision, the spots found on the projector's grid, a
// smaller noise pool). Without noise, the decoder must name the same spots in the frames of the
// renderer before (tests/support/previous_renderer), at the same places to a few hundredths of
// a pixel: what the experiments measured before the change still describes these images.
TEST(DecodeRender, TheDecoderSeesThePreviousRenderersSpotsWhereItSawThem) {
  const std::string dir = std::string(CELL_SOURCE_DIR) + "/sim/scenarios/";
  for (const char* name : {"plane", "cylinder", "ham"}) {
    const auto cell = sim::build_cell(sim::load_scenario(dir + name + ".yaml"));
    const vision::SpotDecoder decoder(pattern::WindowTable(cell->projector->pattern(), {3, 3}));
    sim::CameraSpec quiet = cell->scenario.camera;
    quiet.noise_sigma = quiet.shot_noise = 0;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> t(-6, 6), r(-6, 6);
    int both = 0, only_one = 0;
    std::vector<double> shifts;
    for (int k = 0; k < 6; ++k) {
      const Eigen::Isometry3d wTc =
          k == 0 ? cell->scenario.world_T_desired
          : k == 1 ? cell->scenario.world_T_initial()
                   : sim::offset_pose(cell->scenario.world_T_desired, {t(rng), t(rng), t(rng)}, {r(rng), r(rng), r(rng)},
                                      cell->scenario.offset_frame_rotation_deg);
      const auto now = decoder.decode(sim::render_image(*cell, wTc, 1, nullptr, &quiet)).decoded;
      const auto was = decoder.decode(previous::render_image(*cell, wTc, 1, &quiet)).decoded;
      for (const auto& a : now) {
        const auto b = std::find_if(was.begin(), was.end(), [&](const auto& x) { return x.row == a.row && x.col == a.col; });
        if (b == was.end()) {
          ++only_one;
          continue;
        }
        ++both;
        shifts.push_back(std::hypot(a.u - b->u, a.v - b->v));
      }
      for (const auto& b : was)
        only_one += std::none_of(now.begin(), now.end(), [&](const auto& x) { return x.row == b.row && x.col == b.col; });
    }
    ASSERT_FALSE(shifts.empty()) << name;
    std::sort(shifts.begin(), shifts.end());
    const double median = shifts[shifts.size() / 2], p99 = shifts[shifts.size() * 99 / 100];
    std::printf("%s: %d spots named in both renderers' frames, %d in one only; centroid shift median %.4f px, "
                "99th percentile %.3f px, largest %.3f px\n",
                name, both, only_one, median, p99, shifts.back());
    EXPECT_LE(only_one, both / 100) << name;
    EXPECT_LT(median, 0.005) << name;
    EXPECT_LT(p99, 0.02) << name;
    EXPECT_LT(shifts.back(), 0.1) << name;
  }
}

}  // namespace
