// Property: decode(render(pattern, pose)) recovers the true ids, at random poses around the
// desired one (the simulator's ground truth is the oracle; the decoder never sees it).
#include <gtest/gtest.h>

#include <random>

#include "servo/pattern/pattern_file.hpp"
#include "servo/vision/spot_decoder.hpp"
#include "sim/render/renderer.hpp"

namespace {

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
        const sim::SpotTruth* nearest = nullptr;
        double best = 1e18;
        for (const auto& tr : truth)
          if (tr.visible && std::hypot(tr.uv.x() - d.u, tr.uv.y() - d.v) < best)
            best = std::hypot(tr.uv.x() - d.u, tr.uv.y() - d.v), nearest = &tr;
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

}  // namespace
