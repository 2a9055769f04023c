// The decoder's epipolar steps (issue 12): the check itself, the rejection of a window that
// reads a valid but wrong code, and the grown lattice and the edge runs, on frames the
// simulator renders (its truth is the oracle; the decoder never sees it).
#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <optional>

#include "servo/pipeline/servo_pipeline.hpp"
#include "servo/vision/epipolar.hpp"
#include "servo/vision/spot_decoder.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/experiment/experiment.hpp"
#include "sim/render/renderer.hpp"

namespace {

std::string scenario(const char* name) { return std::string(CELL_SOURCE_DIR) + "/sim/scenarios/" + name + ".yaml"; }

// what `cellsim calibration` writes, exact, and the scenario's camera
calibration::ProjectorModel calibration_of(const sim::Cell& cell) { return experiment::projector_model_of(cell); }
calibration::CameraIntrinsics intrinsics_of(const sim::Cell& cell) { return experiment::camera_intrinsics_of(cell); }

struct Frame {
  std::unique_ptr<sim::Cell> cell;
  Eigen::Isometry3d wTc;
  cv::Mat rgb;
  std::vector<sim::SpotTruth> truth;
};

Frame render(const char* name, bool initial) {
  Frame f;
  f.cell = sim::build_cell(sim::load_scenario(scenario(name)));
  f.wTc = initial ? f.cell->scenario.world_T_initial() : f.cell->scenario.world_T_desired;
  f.rgb = sim::render_image(*f.cell, f.wTc, sim::frame_seed(f.cell->scenario.seed, 0));
  f.truth = sim::compute_truth(*f.cell, f.wTc);
  return f;
}

// the id of the visible spot within 2 px of (u, v), or none
std::optional<pattern::SpotId> truth_at(const Frame& f, double u, double v) {
  for (const auto& t : f.truth)
    if (t.visible && std::hypot(t.uv.x() - u, t.uv.y() - v) < 2.0) return pattern::SpotId{t.row, t.col};
  return std::nullopt;
}

TEST(EpipolarGeometry, TheTrueIdLiesOnItsLineAndItsNeighboursAcrossTheLinesDoNot) {
  const Frame f = render("plane", false);
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
  int checked = 0, neighbours_off = 0, neighbours = 0;
  for (const auto& t : f.truth) {
    if (!t.visible) continue;
    const Eigen::Vector2d xy = g.normalise(t.uv.x(), t.uv.y());
    EXPECT_LT(g.residual_px(xy, {t.row, t.col}), 0.05) << t.row << "," << t.col;
    ++checked;
    for (int dr : {-1, 1}) {  // the next row's id is on another line
      if (t.row + dr < 0 || t.row + dr >= 20) continue;
      ++neighbours;
      neighbours_off += !g.consistent(xy, {t.row + dr, t.col});
    }
  }
  EXPECT_GT(checked, 350);
  EXPECT_GT(neighbours_off, neighbours * 9 / 10);
  // outside the pattern, and NaN coordinates, never pass
  EXPECT_FALSE(g.consistent({0, 0}, {-1, 0}));
  EXPECT_FALSE(g.consistent({0, 0}, {0, 20}));
  EXPECT_FALSE(g.consistent({std::nan(""), 0}, {5, 5}));
}

// The camera at the origin looking along +Z; the projector 0.3 m to its side, looking the same way.
struct SideBySide {
  SideBySide() { p.world_T_projector.translation() = o; }
  calibration::ProjectorModel p;
  Eigen::Vector3d o{0.3, 0, 0};
  calibration::CameraIntrinsics cam{800, 800, 319.5, 239.5, {0, 0, 0, 0, 0}};
  vision::EpipolarGeometry geometry() const { return {cam, p, Eigen::Isometry3d::Identity(), 3.0}; }
};

TEST(EpipolarGeometry, APointOnTheLineButBehindTheProjectorIsRejected) {
  const SideBySide rig;
  const calibration::ProjectorModel& p = rig.p;
  const vision::EpipolarGeometry g = rig.geometry();
  const Eigen::Vector3d o = rig.o, b = p.spot_ray(7, 12);
  const auto image_of = [](const Eigen::Vector3d& x) { return Eigen::Vector2d(x.x() / x.z(), x.y() / x.z()); };
  const Eigen::Vector3d in_front = o + 1.0 * b;
  EXPECT_LT(g.residual_px(image_of(in_front), {7, 12}), 1e-6);
  EXPECT_FALSE(g.consistent(image_of(in_front), {8, 12}));
  // a point on the projector ray's backward extension (t < 0; here also behind the camera)
  // is on both lines, so its image lies on the epipolar line, yet no light of spot (7, 12)
  // can be seen there
  const Eigen::Vector3d x_back = o - 0.5 * b;
  ASSERT_LT(x_back.z(), 0);
  const Eigen::Vector2d xy_back = image_of(x_back);
  EXPECT_LT(std::abs(Eigen::Vector3d(xy_back.x(), xy_back.y(), 1).dot(o.cross(b))) /
                std::hypot(o.cross(b).x(), o.cross(b).y()) * 800, 1e-6);
  EXPECT_FALSE(g.consistent(xy_back, {7, 12}));
}

// The front check's two signs apart: with the projector 1 m ahead of the camera, a point on its
// ray's backward extension lies in front of the camera (s > 0) and behind the projector (t < 0);
// a point on its forward ray lies in front of both.
TEST(EpipolarGeometry, APointInFrontOfTheCameraButBehindTheProjectorIsRejected) {
  SideBySide rig;
  rig.o = {0.3, 0, 1.0};
  rig.p.world_T_projector.translation() = rig.o;
  const vision::EpipolarGeometry g = rig.geometry();
  const Eigen::Vector3d b = rig.p.spot_ray(7, 12);
  const auto image_of = [](const Eigen::Vector3d& x) { return Eigen::Vector2d(x.x() / x.z(), x.y() / x.z()); };
  const Eigen::Vector3d ahead = rig.o + 0.5 * b, behind = rig.o - 0.5 * b;
  ASSERT_GT(behind.z(), 0);
  EXPECT_LT(g.residual_px(image_of(ahead), {7, 12}), 1e-6);
  EXPECT_LT(g.line_distance_px(image_of(behind), 7 * 20 + 12), 1e-6);  // on the line...
  EXPECT_FALSE(g.consistent(image_of(behind), {7, 12}));               // ...but not lit by the spot
}

// line_distance_px is residual_px's first number: equal where residual_px is finite, so that a
// search may skip every id it puts beyond a bound.
TEST(EpipolarGeometry, TheLinesDistanceIsTheResidualWhereTheRaysMeet) {
  const SideBySide rig;
  const vision::EpipolarGeometry g = rig.geometry();
  int finite = 0;
  for (double x = -0.4; x <= 0.4; x += 0.05)
    for (double y = -0.3; y <= 0.3; y += 0.05)
      for (int r = 0; r < 20; r += 3)
        for (int c = 0; c < 20; c += 3) {
          const double residual = g.residual_px({x, y}, {r, c});
          const double distance = g.line_distance_px({x, y}, static_cast<std::size_t>(r) * 20 + c);
          if (std::isfinite(residual)) {
            EXPECT_EQ(residual, distance);
            ++finite;
          }
          EXPECT_LE(distance, residual);
        }
  EXPECT_GT(finite, 1000);
}

// The decoder's steps read a geometry's lines by the pattern's ids: a geometry of another grid
// of spots (a calibration of another projector) is refused, not read beyond its lines.
TEST(EpipolarDecoding, AGeometryOfAnotherGridOfSpotsIsRefused) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  SideBySide rig;
  rig.p.rows = pat.rows / 2;
  const vision::EpipolarGeometry smaller = rig.geometry();
  const vision::SpotDecoder decoder(pattern::WindowTable(pat, {3, 3}));
  try {
    (void)decoder.decode(f.rgb, &smaller);
    FAIL() << "decoded with a " << smaller.rows() << " x " << smaller.cols() << " geometry";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("10 x 20 spots, the pattern 20 x 20"), std::string::npos) << e.what();
  }
}

// Issue 41: beyond the windows, a spot must lie on its id's line as closely as the frame's
// window-read spots lie on theirs: the limit is 4 times their median residual, at least 1 px,
// at most the tolerance; with fewer than 9 of them, the tolerance.
TEST(EpipolarGeometry, TheGrownLimitFollowsTheFramesWindowReadResiduals) {
  const SideBySide rig;
  const calibration::ProjectorModel& p = rig.p;
  const vision::EpipolarGeometry g = rig.geometry();
  const Eigen::Vector3d o = rig.o;
  // spot k: id (5, k) on its line, moved off it across the line by `off_px` camera pixels
  const auto spots_off = [&](const std::vector<double>& off_px) {
    std::vector<vision::Spot> spots;
    std::vector<vision::DecodedSpot> decoded;
    for (std::size_t k = 0; k < off_px.size(); ++k) {
      const Eigen::Vector3d x = o + 1.0 * p.spot_ray(5, static_cast<int>(k));
      const Eigen::Vector3d line = o.cross(p.spot_ray(5, static_cast<int>(k)));
      const Eigen::Vector2d normal = line.head<2>().normalized();
      const Eigen::Vector2d xy = Eigen::Vector2d(x.x() / x.z(), x.y() / x.z()) + normal * off_px[k] / 800.0;
      vision::Spot s;
      s.u = 800 * xy.x() + 319.5, s.v = 800 * xy.y() + 239.5;
      spots.push_back(s);
      decoded.push_back({5, static_cast<int>(k), s.u, s.v, static_cast<int>(k)});
    }
    return std::pair{spots, decoded};
  };
  {
    const auto [spots, decoded] = spots_off(std::vector<double>(11, 0.2));
    vision::EpipolarCheck check(g, spots);
    check.set_grown_limit(decoded);
    EXPECT_NEAR(check.grown_limit_px, 1.0, 1e-9);  // 4 x 0.2 is below the floor
    EXPECT_TRUE(check.confirms_grown(3, {5, 3}));
  }
  {
    const auto [spots, decoded] = spots_off({0.5, 0.6, 0.5, 0.55, 0.6, 0.5, 0.5, 0.6, 0.55, 2.1, 0.5});
    vision::EpipolarCheck check(g, spots);
    check.set_grown_limit(decoded);
    EXPECT_NEAR(check.grown_limit_px, 2.2, 0.05);  // 4 x the median, 0.55
    EXPECT_TRUE(check.confirms(9, {5, 9}));        // within the tolerance, 3 px
    EXPECT_TRUE(check.confirms_grown(9, {5, 9}));  // 2.1 px: as close as this frame's spots lie
  }
  {
    const auto [spots, decoded] = spots_off({0.1, 0.15, 0.1, 0.12, 0.1, 0.1, 0.14, 0.1, 0.1, 2.1, 0.1});
    vision::EpipolarCheck check(g, spots);
    check.set_grown_limit(decoded);
    EXPECT_TRUE(check.confirms(9, {5, 9}));
    EXPECT_FALSE(check.confirms_grown(9, {5, 9}));  // 2.1 px where the frame's spots lie 0.1 px off
  }
  {
    const auto [spots, decoded] = spots_off({2.5, 2.4, 2.6, 2.5, 2.5, 2.4, 2.6, 2.5, 2.5});
    vision::EpipolarCheck check(g, spots);
    check.set_grown_limit(decoded);
    EXPECT_NEAR(check.grown_limit_px, 3.0, 1e-9);  // a calibration error: never beyond the tolerance
    const auto few = spots_off({0.1, 0.1, 0.1});
    vision::EpipolarCheck sparse(g, few.first);
    sparse.set_grown_limit(few.second);
    EXPECT_NEAR(sparse.grown_limit_px, 3.0, 1e-9);  // too few to say
  }
}

// Recolour the 9 spots of one decoded window with the colours of another window of the
// pattern: the window then reads as a valid code, with a wrong id.
TEST(EpipolarDecoding, AWindowThatReadsAValidButWrongCodeComesOutUnidentifiedOrRight) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  const pattern::WindowTable table(pat, {3, 3});
  const vision::SpotDecoder decoder(table);
  const vision::DecodeResult clean = decoder.decode(f.rgb);
  std::vector<vision::Spot> spots = clean.detected;
  const vision::AdjacencyGraph graph = vision::build_adjacency(spots);
  const vision::Neighbourhoods hoods = vision::check_graph_consistency(graph);
  // a full window near the centre of the image, and the pattern window (r0, c0) to imitate
  int centre = -1;
  for (std::size_t s = 0; s < spots.size() && centre < 0; ++s) {
    const auto id = truth_at(f, spots[s].u, spots[s].v);
    bool full = true;
    for (int k : hoods.window[s]) full = full && k >= 0;
    if (full && id && id->row == 10 && id->col == 10) centre = static_cast<int>(s);
  }
  ASSERT_GE(centre, 0);
  const pattern::SpotId fake{4, 15};  // far away, on other epipolar lines
  for (int i = 0; i < 9; ++i)
    spots[hoods.window[centre][i]].colour = pat.at(fake.row + i / 3 - 1, fake.col + i % 3 - 1);

  // without the check the tampered window is read as the fake id: the temptation is real
  const auto plain = vision::read_windows(spots, hoods, table);
  const auto read_as_fake = [&](const std::vector<vision::WindowReading>& readings) {
    for (const auto& r : readings)
      if (r.centre == centre && r.id == fake) return true;
    return false;
  };
  ASSERT_TRUE(read_as_fake(plain));

  // with it, the reading is rejected, even in error-tolerant mode ...
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
  const vision::EpipolarCheck check(g, spots);
  EXPECT_FALSE(read_as_fake(vision::read_windows(spots, hoods, table, {}, &check)));
  EXPECT_FALSE(read_as_fake(vision::read_windows(spots, hoods, table, vision::ToleranceOptions{true}, &check)));
  // ... and every spot the full decoder names (with votes as low as 1) is named right
  for (int min_votes : {1, 3}) {
    vision::DecoderOptions o;
    o.min_votes = min_votes;
    o.epipolar.min_island = 1;
    o.epipolar.tolerant = true;
    const vision::SpotDecoder d(table, o);
    const vision::DecodeResult r = d.decode_spots(spots, &g);
    int wrong = 0;
    for (const auto& s : r.decoded) {
      const auto id = truth_at(f, s.u, s.v);
      wrong += !id || !(*id == pattern::SpotId{s.row, s.col});
    }
    EXPECT_EQ(wrong, 0) << "min_votes " << min_votes;
    EXPECT_GT(r.decoded.size(), 300u);
  }
}

// Step 6 from an island: the grown lattice names the plane from 32 identified spots, a spot
// only where three sources predict its id and its colour and epipolar line agree.
TEST(EpipolarDecoding, TheGrownLatticeNamesThePlaneFromAnIslandOnlyWhereSourcesColourAndLineAgree) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  const std::vector<vision::Spot>& spots = vision::SpotDecoder(pattern::WindowTable(pat, {3, 3})).decode(f.rgb).detected;
  const vision::AdjacencyGraph graph = vision::build_adjacency(spots);
  // each call grows its own copy of the graph (grow_lattice adds the links it finds)
  const auto grow = [&](const std::vector<vision::Spot>& s, const vision::EpipolarCheck& c,
                        const std::vector<vision::DecodedSpot>& from) {
    vision::AdjacencyGraph own = graph;
    return vision::grow_lattice(s, own, c, pat, from, 3);
  };
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
  const vision::EpipolarCheck check(g, spots);
  // seeds: the true ids of rows 8..11, columns 6..13 (a decoded island); everything else is
  // undecoded and must be reached by growth
  std::vector<vision::DecodedSpot> seeds;
  std::map<int, pattern::SpotId> truth;
  for (std::size_t s = 0; s < spots.size(); ++s)
    if (const auto id = truth_at(f, spots[s].u, spots[s].v)) {
      truth[static_cast<int>(s)] = *id;
      if (id->row >= 8 && id->row <= 11 && id->col >= 6 && id->col <= 13)
        seeds.push_back({id->row, id->col, spots[s].u, spots[s].v, static_cast<int>(s)});
    }
  ASSERT_EQ(seeds.size(), 32u);
  const auto grown = grow(spots, check, seeds);
  int wrong = 0;
  for (const auto& d : grown) wrong += !(truth.at(d.spot) == pattern::SpotId{d.row, d.col});
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(grown.size(), 300u);  // from 32 seeds over the plane

  // a spot whose colour disagrees with the pattern at the id it would take stays unnamed
  std::vector<vision::Spot> recoloured = spots;
  int victim = -1;
  for (const auto& [s, id] : truth)
    if (id.row == 12 && id.col == 9) victim = s;
  ASSERT_GE(victim, 0);
  recoloured[victim].colour = (recoloured[victim].colour + 1) % 3;
  const vision::EpipolarCheck check2(g, recoloured);
  for (const auto& d : grow(recoloured, check2, seeds)) EXPECT_NE(d.spot, victim);

  // a spot as bright as its sources but half their area is a clipped footprint: named, once
  // its row neighbours are, and kept from the law (DecodedSpot::clipped); no spot of the whole
  // plane is clipped
  for (const auto& d : grown) EXPECT_FALSE(d.clipped) << d.row << ',' << d.col;
  std::vector<vision::Spot> shrunk = spots;
  shrunk[victim].area_px /= 2;
  const vision::EpipolarCheck check3(g, shrunk);
  const auto with_clipped = grow(shrunk, check3, seeds);
  const auto named = std::find_if(with_clipped.begin(), with_clipped.end(), [&](const auto& d) { return d.spot == victim; });
  ASSERT_NE(named, with_clipped.end());
  EXPECT_EQ(named->row, 12);
  EXPECT_EQ(named->col, 9);
  EXPECT_TRUE(named->clipped);
  EXPECT_TRUE(named->apart());
  EXPECT_EQ(std::count_if(with_clipped.begin(), with_clipped.end(), [](const auto& d) { return d.clipped; }), 1);

  // a lone identified spot is one source for each neighbour, and has no step: nothing grows
  std::vector<vision::DecodedSpot> one{seeds.front()};
  EXPECT_EQ(grow(spots, check, one).size(), 1u);
  // two decoded rows: a spot above them has one column source (whose step the row below
  // gives) and two corners, and the rows grow upwards (and on)
  std::vector<vision::DecodedSpot> rows;
  for (const auto& d : seeds)
    if (d.row >= 10) rows.push_back(d);
  const auto from_rows = grow(spots, check, rows);
  EXPECT_TRUE(std::any_of(from_rows.begin(), from_rows.end(), [](const auto& d) { return d.row == 9; }));
}

// Step 6 where the graph has no links (cut here for a whole pattern row): the lattice grown
// from the identified spots predicts each id's place and names the spot found there, and adds
// the links it found. A spot whose colour or look (a speck, a wash blob far bigger than its
// sources) does not fit stays unnamed.
TEST(EpipolarDecoding, TheGrownLatticeNamesSpotsWhoseLinksAreMissingAndNoneWrong) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  const std::vector<vision::Spot> spots =
      vision::SpotDecoder(pattern::WindowTable(pat, {3, 3})).decode(f.rgb).detected;
  vision::AdjacencyGraph graph = vision::build_adjacency(spots);
  std::vector<vision::DecodedSpot> seeds;
  std::map<int, pattern::SpotId> truth;
  std::vector<int> cut;  // the spots of pattern row 12, columns 6..13
  for (std::size_t s = 0; s < spots.size(); ++s)
    if (const auto id = truth_at(f, spots[s].u, spots[s].v)) {
      const int i = static_cast<int>(s);
      truth[i] = *id;
      if (id->row >= 8 && id->row <= 11 && id->col >= 6 && id->col <= 13)
        seeds.push_back({id->row, id->col, spots[s].u, spots[s].v, i});
      if (id->row == 12 && id->col >= 6 && id->col <= 13) cut.push_back(i);
    }
  ASSERT_EQ(seeds.size(), 32u);
  ASSERT_EQ(cut.size(), 8u);
  for (const int i : cut)
    for (int k = 0; k < 4; ++k)
      if (const int j = graph.next[i][k]; j >= 0) graph.next[i][k] = graph.next[j][(k + 2) % 4] = -1;
  const vision::Neighbourhoods hoods = vision::check_graph_consistency(graph);
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
  const auto named = [](const std::vector<vision::DecodedSpot>& d, int spot) {
    return std::any_of(d.begin(), d.end(), [&](const vision::DecodedSpot& x) { return x.spot == spot; });
  };
  {
    const vision::EpipolarCheck check(g, spots);
    vision::AdjacencyGraph grown_graph = graph;
    const auto grown = vision::grow_lattice(spots, grown_graph, check, pat, seeds, 3);
    int wrong = 0;
    for (const auto& d : grown) wrong += !(truth.at(d.spot) == pattern::SpotId{d.row, d.col});
    EXPECT_EQ(wrong, 0);
    for (const int i : cut) EXPECT_TRUE(named(grown, i)) << "spot " << i;
    EXPECT_GT(grown.size(), 300u);  // and on over the plane, links or none
    // the links it found are back, both ways
    for (const int i : cut)
      for (int k = 0; k < 4; ++k)
        if (const int j = grown_graph.next[i][k]; j >= 0) {
          EXPECT_EQ(grown_graph.next[j][(k + 2) % 4], i);
        }
    EXPECT_GE(grown_graph.next[cut[3]][vision::kNorth], 0);
  }
  // the same row with one spot recoloured, one shrunk to a speck and one swollen to a wash blob
  std::vector<vision::Spot> tempted = spots;
  const int recoloured = cut[2], speck = cut[4], wash = cut[6];
  tempted[recoloured].colour = (tempted[recoloured].colour + 1) % 3;
  tempted[speck].area_px = 4;
  tempted[wash].area_px *= 6;
  const vision::EpipolarCheck check(g, tempted);
  const auto grown = vision::grow_lattice(tempted, graph, check, pat, seeds, 3);
  for (const int i : {recoloured, speck, wash}) EXPECT_FALSE(named(grown, i)) << "spot " << i;
  EXPECT_TRUE(named(grown, cut[3]));
  int wrong = 0;
  for (const auto& d : grown) wrong += !(truth.at(d.spot) == pattern::SpotId{d.row, d.col});
  EXPECT_EQ(wrong, 0);
}

// At a silhouette only two identified spots may touch the next one: a row or column neighbour
// and a corner. One source fewer than asked names it when both predictions land within 0.12 of
// a step of the blob, or when it lies on the neighbour's step line at 1/1.2-1.2 of the step (the
// last step foreshortened or stretched), and it looks like them. Farther along or aside (still within the
// three-source slack), half their size or 0.45 as strong, it stays unnamed. From a 2 x 2 block
// the plane then grows whole.
TEST(EpipolarDecoding, TwoSourcesNameASpotOnlyWhereBothPredictionsLandOnIt) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  const std::vector<vision::Spot> spots =
      vision::SpotDecoder(pattern::WindowTable(pat, {3, 3})).decode(f.rgb).detected;
  std::map<int, pattern::SpotId> truth;
  std::map<std::pair<int, int>, int> spot_of;
  for (std::size_t s = 0; s < spots.size(); ++s)
    if (const auto id = truth_at(f, spots[s].u, spots[s].v)) {
      truth[static_cast<int>(s)] = *id;
      spot_of[{id->row, id->col}] = static_cast<int>(s);
    }
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
  // the block (9..10, 10..11) and the spot west of it, (10, 9), alone
  const std::vector<std::pair<int, int>> block{{9, 10}, {9, 11}, {10, 10}, {10, 11}};
  const auto grow_alone = [&](const std::function<void(vision::Spot&)>& change) {
    std::vector<vision::Spot> few;
    std::vector<vision::DecodedSpot> seeds;
    for (const auto& rc : block) {
      few.push_back(spots[static_cast<std::size_t>(spot_of.at(rc))]);
      seeds.push_back({rc.first, rc.second, few.back().u, few.back().v, static_cast<int>(few.size()) - 1});
    }
    few.push_back(spots[static_cast<std::size_t>(spot_of.at({10, 9}))]);
    change(few.back());
    vision::AdjacencyGraph graph = vision::build_adjacency(few);
    const vision::EpipolarCheck check(g, few);
    const auto grown = vision::grow_lattice(few, graph, check, pat, seeds, 3);
    return std::any_of(grown.begin(), grown.end(), [&](const vision::DecodedSpot& d) {
      return d.spot == 4 && d.row == 10 && d.col == 9;
    });
  };
  EXPECT_TRUE(grow_alone([](vision::Spot&) {}));
  const vision::Spot& east = spots[static_cast<std::size_t>(spot_of.at({10, 10}))];
  const double step_u = east.u - spots[static_cast<std::size_t>(spot_of.at({10, 9}))].u;
  // on the step's line, 1.16 of the step: beyond the tight slack, within 1/1.2-1.2 (the middle
  // of the band this frame names, -0.19 to +0.15 of a step, with the same margin either side)
  EXPECT_TRUE(grow_alone([&](vision::Spot& x) { x.u -= 0.16 * step_u; }));
  EXPECT_FALSE(grow_alone([&](vision::Spot& x) { x.u -= 0.3 * step_u; }));  // stretched too far
  EXPECT_FALSE(grow_alone([&](vision::Spot& x) { x.v += 0.2 * step_u; }));  // aside
  EXPECT_FALSE(grow_alone([](vision::Spot& x) { x.area_px /= 2; }));
  EXPECT_FALSE(grow_alone([](vision::Spot& x) { x.strength *= 0.45F; }));
  // and no larger than 1/0.6 of them (GrowthOptions::unlike): 1.4 times is a spot, 1.8 a blob
  // that is not one of theirs
  EXPECT_TRUE(grow_alone([](vision::Spot& x) { x.area_px = static_cast<int>(x.area_px * 1.4); }));
  EXPECT_FALSE(grow_alone([](vision::Spot& x) { x.area_px = static_cast<int>(x.area_px * 1.8); }));
  // all the spots: from the block over the plane, none wrong
  std::vector<vision::DecodedSpot> seeds;
  for (const auto& rc : block) {
    const int i = spot_of.at(rc);
    seeds.push_back({rc.first, rc.second, spots[static_cast<std::size_t>(i)].u, spots[static_cast<std::size_t>(i)].v, i});
  }
  vision::AdjacencyGraph graph = vision::build_adjacency(spots);
  const vision::EpipolarCheck check(g, spots);
  const auto grown = vision::grow_lattice(spots, graph, check, pat, seeds, 3);
  EXPECT_GT(grown.size(), 300u);
  for (const auto& d : grown) EXPECT_EQ(truth.at(d.spot), (pattern::SpotId{d.row, d.col})) << "spot " << d.spot;
}

// Along a row the epipolar lines coincide: the id beside a spot, when it has the spot's colour,
// fits the blob as well as the spot's own id. Three sources or more, two of them row or column
// neighbours, all within 0.12 of a step, pin the spot: it is named though the id beside it fits
// too. Moved 0.2 of a step aside (still within the lattice's slack) it is not pinned, and the
// id beside it leaves it unnamed.
TEST(EpipolarDecoding, ALatticePinnedSpotIsNamedThoughTheIdBesideItFitsToo) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  const std::vector<vision::Spot> spots =
      vision::SpotDecoder(pattern::WindowTable(pat, {3, 3})).decode(f.rgb).detected;
  std::map<std::pair<int, int>, int> spot_of;
  for (std::size_t s = 0; s < spots.size(); ++s)
    if (const auto id = truth_at(f, spots[s].u, spots[s].v)) spot_of[{id->row, id->col}] = static_cast<int>(s);
  // on the plane the rows' lines lie 3 px apart and more: a tolerance of 20 px makes the ids
  // beside fit as they do where the lines coincide (the ham's rows, the table seen obliquely)
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 20.0);
  const vision::EpipolarCheck all(g, spots);
  // a spot (r, c) whose east neighbour's id has its colour and whose line passes it as well
  int row = -1, col = -1;
  for (int r = 4; r < 16 && row < 0; ++r)
    for (int c = 4; c < 15 && row < 0; ++c) {
      const auto it = spot_of.find({r, c});
      if (it == spot_of.end()) continue;
      for (int dr = -1; dr <= 1; ++dr)
        if (pat.at(r, c) == pat.at(r + dr, c + 1) && all.confirms(it->second, {r + dr, c + 1})) row = r, col = c;
    }
  ASSERT_GE(row, 0) << "no spot with a same-coloured id east of it on its line";
  // the block west of it and the spots north and south of it, seeded; the spot, alone beside them
  const auto grow_alone = [&](const std::function<void(vision::Spot&)>& change) {
    std::vector<vision::Spot> few;
    std::vector<vision::DecodedSpot> seeds;
    for (int r = row - 1; r <= row + 1; ++r)
      for (int c = col - 3; c <= col; ++c) {
        if (r == row && c == col) continue;
        few.push_back(spots[static_cast<std::size_t>(spot_of.at({r, c}))]);
        seeds.push_back({r, c, few.back().u, few.back().v, static_cast<int>(few.size()) - 1});
      }
    few.push_back(spots[static_cast<std::size_t>(spot_of.at({row, col}))]);
    change(few.back());
    const int x = static_cast<int>(few.size()) - 1;
    vision::AdjacencyGraph graph = vision::build_adjacency(few);
    const vision::EpipolarCheck check(g, few);
    const auto grown = vision::grow_lattice(few, graph, check, pat, seeds, 3);
    int named = 0;
    for (const auto& d : grown)
      if (d.spot == x) {
        EXPECT_EQ((pattern::SpotId{d.row, d.col}), (pattern::SpotId{row, col}));
        ++named;
      }
    return named == 1;
  };
  EXPECT_TRUE(grow_alone([](vision::Spot&) {}));
  const vision::Spot& west = spots[static_cast<std::size_t>(spot_of.at({row, col - 1}))];
  const double step = std::hypot(spots[static_cast<std::size_t>(spot_of.at({row, col}))].u - west.u,
                                 spots[static_cast<std::size_t>(spot_of.at({row, col}))].v - west.v);
  EXPECT_FALSE(grow_alone([&](vision::Spot& x) { x.v += 0.2 * step; }));
}

// A 2 x 2 block below the cut row is seeded one column off (a misread patch): its sources claim
// the cut row's spots one column over, against the three or more right sources above. The
// spots at the block's corners have one dissenting source and are outvoted at once; those above
// it have two and wait until the ids the block claims for them are taken by their right owners
// (the one of (12, 12) is not seen). Every spot of the row comes out right, and the block's
// wrong ids spread nowhere. (The vote's gain is in the curved-object test below: 2 of the
// ham's spots at its initial pose.)
TEST(EpipolarDecoding, TheGrownLatticeNamesARowThatAMisreadBlockDisputesAndNoneWrong) {
  const Frame f = render("plane", false);
  const pattern::MArray& pat = f.cell->projector->pattern();
  std::vector<vision::Spot> spots = vision::SpotDecoder(pattern::WindowTable(pat, {3, 3})).decode(f.rgb).detected;
  // spot (12, 12) is not seen: the id the block claims at (12, 11) is never taken by its owner
  std::erase_if(spots, [&](const vision::Spot& s) { return truth_at(f, s.u, s.v) == pattern::SpotId{12, 12}; });
  vision::AdjacencyGraph graph = vision::build_adjacency(spots);
  std::vector<vision::DecodedSpot> seeds;
  std::map<int, pattern::SpotId> truth;
  std::map<std::pair<int, int>, int> spot_of;  // true id -> spot
  for (std::size_t s = 0; s < spots.size(); ++s)
    if (const auto id = truth_at(f, spots[s].u, spots[s].v)) {
      const int i = static_cast<int>(s);
      truth[i] = *id;
      spot_of[{id->row, id->col}] = i;
      if (id->row >= 8 && id->row <= 11 && id->col >= 6 && id->col <= 13)
        seeds.push_back({id->row, id->col, spots[s].u, spots[s].v, i});
      if ((id->row == 13 || id->row == 14) && (id->col == 9 || id->col == 10))  // misread: one column over
        seeds.push_back({id->row, id->col + 1, spots[s].u, spots[s].v, i});
    }
  ASSERT_EQ(seeds.size(), 36u);
  const std::vector<int> cut_cols{6, 7, 8, 9, 10, 11, 13};
  for (const int c : cut_cols) {  // the cut row: no links, only the lattice names it
    ASSERT_TRUE(spot_of.count({12, c}));
    const int i = spot_of.at({12, c});
    for (int k = 0; k < 4; ++k)
      if (const int j = graph.next[i][k]; j >= 0) graph.next[i][k] = graph.next[j][(k + 2) % 4] = -1;
  }
  const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
  const vision::EpipolarCheck check(g, spots);
  const auto grown = vision::grow_lattice(spots, graph, check, pat, seeds, 3);
  const auto id_of = [&](int r, int c) -> std::optional<pattern::SpotId> {
    for (const auto& d : grown)
      if (d.spot == spot_of.at({r, c})) return pattern::SpotId{d.row, d.col};
    return std::nullopt;
  };
  for (const int c : cut_cols) EXPECT_EQ(id_of(12, c), (pattern::SpotId{12, c})) << "column " << c;
  // nothing but the seeded block carries a wrong id
  for (const auto& d : grown) {
    const pattern::SpotId& t = truth.at(d.spot);
    if ((t.row == 13 || t.row == 14) && (t.col == 9 || t.col == 10)) continue;
    EXPECT_EQ(t, (pattern::SpotId{d.row, d.col})) << "spot " << d.spot;
  }
}

// At an occluder's edge the wash of the wall behind continues the lattice on the epipolar
// line, with the id the lattice would put there. This pose of `cylinder_occlusion` (the sweep's
// widened draw, seed 2, pose 730) shows it: a rule that passed ids along links named spot
// (11, 5) on a blob of the wall 69 px from where (11, 5) lies; the decoder names no spot
// wrongly there.
TEST(EpipolarDecoding, AtAnOccludersEdgeTheDecoderNamesNoSpotOfTheWallBehind) {
  const auto cell = sim::build_cell(sim::load_scenario(scenario("cylinder_occlusion")));
  const Eigen::Isometry3d wTc = sim::offset_pose(cell->scenario.world_T_desired, {-1.17672, -0.46037, -5.23275},
                                                 {-6.26992, 1.88161, -3.01912}, cell->scenario.offset_frame_rotation_deg);
  sim::CameraSpec sensor = cell->scenario.camera;
  sensor.noise_sigma = 3;
  const cv::Mat rgb = sim::render_image(*cell, wTc, sim::frame_seed(2, 730), nullptr, &sensor);
  const auto truth = sim::compute_truth(*cell, wTc);
  const vision::EpipolarGeometry g(intrinsics_of(*cell), calibration_of(*cell), wTc, 3.0);
  const vision::SpotDecoder decoder(pattern::WindowTable(cell->projector->pattern(), {3, 3}));
  const auto r = decoder.decode(rgb, &g);
  int wrong = 0;
  for (const auto& d : r.decoded) {
    const sim::SpotTruth* nearest = nullptr;
    for (const auto& t : truth)
      if (t.visible && (!nearest || (t.uv - Eigen::Vector2d(d.u, d.v)).norm() < (nearest->uv - Eigen::Vector2d(d.u, d.v)).norm()))
        nearest = &t;
    wrong += !nearest || nearest->row != d.row || nearest->col != d.col;
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(r.decoded.size(), 100u);
}

// Step 7 (edge runs). At this pose of the cylinder (the sweep's draw, seed 1, pose 71) the
// surface turns away from the camera at pattern column 16: its spots are slivers 1-2 px wide,
// 5-6 px beyond column 15, a third of its spots' area, which the grown lattice refuses one at
// a time. As a run along column 15 they are named, where their centres are; swollen to wash
// blobs every other one, no run is left and none of them is named.
TEST(EpipolarDecoding, TheForeshortenedColumnAtTheSilhouetteIsNamedAsARunAndNoneWrong) {
  const auto cell = sim::build_cell(sim::load_scenario(scenario("cylinder")));
  const Eigen::Isometry3d wTc = sim::offset_pose(cell->scenario.world_T_desired, {-7.10989, 2.20323, 17.08},
                                                 {3.97486, 5.76856, 2.13357}, cell->scenario.offset_frame_rotation_deg);
  const cv::Mat rgb = sim::render_image(*cell, wTc, sim::frame_seed(1, 71));
  const auto truth = sim::compute_truth(*cell, wTc);
  const pattern::MArray& pat = cell->projector->pattern();
  const vision::EpipolarGeometry g(intrinsics_of(*cell), calibration_of(*cell), wTc, 3.0);
  int column_16 = 0;  // visible spots of column 16
  for (const auto& t : truth) column_16 += t.visible && t.col == 16;
  ASSERT_GE(column_16, 15);
  // the nearest visible spot to a decoded one, and how far
  const auto nearest = [&](double u, double v, double& dist) {
    const sim::SpotTruth* best = nullptr;
    for (const auto& t : truth)
      if (t.visible && (!best || (t.uv - Eigen::Vector2d(u, v)).norm() < (best->uv - Eigen::Vector2d(u, v)).norm()))
        best = &t;
    dist = best ? (best->uv - Eigen::Vector2d(u, v)).norm() : 1e9;
    return best;
  };
  const auto decode = [&](bool edge_runs, int& in_column_16) {
    vision::DecoderOptions options;
    options.epipolar.edge_runs = edge_runs;
    const auto r = vision::SpotDecoder(pattern::WindowTable(pat, {3, 3}), options).decode(rgb, &g);
    in_column_16 = 0;
    for (const auto& d : r.decoded) {
      double dist = 0;
      const sim::SpotTruth* t = nearest(d.u, d.v, dist);
      EXPECT_TRUE(t && t->row == d.row && t->col == d.col) << d.row << "," << d.col;
      if (d.col == 16) {
        ++in_column_16;
        EXPECT_LT(dist, 1.0) << d.row << "," << d.col;  // the sliver is the whole spot, edge-on
      }
    }
    return r;
  };
  int with = 0, without = 0;
  decode(true, with);
  decode(false, without);
  EXPECT_EQ(without, 0);
  EXPECT_GE(with, 12) << "of " << column_16;

  // the run taken apart: every other blob of column 16 swollen to a wash blob
  std::vector<vision::Spot> spots = vision::segment_spots(rgb).spots;
  std::vector<vision::Spot> plain;
  for (const auto& s : spots)
    if (!s.sliver) plain.push_back(s);
  vision::DecoderOptions options;
  options.epipolar.edge_runs = false;
  const auto seeds = vision::SpotDecoder(pattern::WindowTable(pat, {3, 3}), options).decode_spots(plain, &g);
  // slivers last, as segment_spots lists them: the decoder's indices of the others hold
  vision::AdjacencyGraph graph = seeds.graph;
  graph.next.resize(spots.size(), {-1, -1, -1, -1});
  int swollen = 0;
  for (auto& s : spots) {
    double dist = 0;
    const sim::SpotTruth* t = nearest(s.u, s.v, dist);
    if (t && dist < 2 && t->col == 16 && t->row % 2 == 0) s.area_px *= 8, ++swollen;
  }
  ASSERT_GE(swollen, 6);
  const vision::EpipolarCheck check(g, spots);
  const auto runs = vision::name_edge_runs(spots, graph, check, pat, seeds.decoded);
  for (const auto& d : runs) EXPECT_NE(d.col, 16) << d.row << "," << d.col;
}

// (at the cylinder's initial pose both name 168 since the links are mended from the code)
TEST(EpipolarDecoding, CalibratedDecodingNamesNoFewerSpotsOnTheCurvedObjectsAndNoneWrong) {
  for (const char* name : {"cylinder", "ham"}) {
    const Frame f = render(name, true);
    const vision::SpotDecoder decoder(pattern::WindowTable(f.cell->projector->pattern(), {3, 3}));
    const vision::EpipolarGeometry g(intrinsics_of(*f.cell), calibration_of(*f.cell), f.wTc, 3.0);
    const auto without = decoder.decode(f.rgb);
    const auto with = decoder.decode(f.rgb, &g);
    EXPECT_GE(with.decoded.size(), without.decoded.size()) << name;
    // what this decoder names there, less about 2 % for another CPU's last bits (2026-12-02:
    // ham 165, 163 of them without the grown lattice's vote; cylinder 179). A change that names
    // fewer must say why, here.
    EXPECT_GE(with.decoded.size(), std::string(name) == "ham" ? 162u : 175u) << name;
    for (const auto& d : with.decoded) {
      // right: the nearest visible spot is the one named. Grown spots on the ham's most oblique
      // flank have their centroid up to 2.5 px from the spot's centre (the sweep's "mislocated")
      const sim::SpotTruth* nearest = nullptr;
      for (const auto& t : f.truth)
        if (t.visible && (!nearest || (t.uv - Eigen::Vector2d(d.u, d.v)).norm() < (nearest->uv - Eigen::Vector2d(d.u, d.v)).norm()))
          nearest = &t;
      ASSERT_NE(nearest, nullptr);
      EXPECT_LT((nearest->uv - Eigen::Vector2d(d.u, d.v)).norm(), 4.0) << name << " " << d.row << "," << d.col;
      EXPECT_TRUE(nearest->row == d.row && nearest->col == d.col) << name << " " << d.row << "," << d.col;
    }
  }
}

// The servo holding each id to the point its spot lit at teaching (ServoConfig::taught_points),
// on the ham's rendered frames with the projector's calibration: at the initial pose nearly
// every matched spot lies where its taught point projects (the ham's right ids lie a few
// hundredths of a pixel off); a spot moved 3 px along anything, as a spill past a silhouette
// lies, is no feature; without the option it still is.
TEST(EpipolarDecoding, TheServoHoldsEachIdToItsTaughtPoint) {
  const Frame desired = render("ham", false), initial = render("ham", true);
  servo::ServoConfig c;
  c.camera = intrinsics_of(*desired.cell);
  c.projector = calibration_of(*desired.cell);
  c.law.z_hat_m = 0.9;
  c.taught_points = true;
  servo::ServoPipeline held(pattern::WindowTable(desired.cell->projector->pattern(), {3, 3}), c);
  c.taught_points = false;
  servo::ServoPipeline free(pattern::WindowTable(desired.cell->projector->pattern(), {3, 3}), c);
  const std::vector<servo::ImageSpot> taught = held.locate(desired.rgb, desired.wTc);
  ASSERT_GT(held.teach(taught, desired.wTc), 150);
  free.teach(taught, desired.wTc);
  std::vector<servo::ImageSpot> spots = held.locate(initial.rgb, initial.wTc);
  const servo::StepResult as_seen = held.step(spots, initial.wTc);
  ASSERT_GT(as_seen.matched.size(), 100u);
  EXPECT_LE(as_seen.held_by_taught, 2) << "of " << as_seen.matched.size() << " matched";
  const auto moved = std::find_if(spots.begin(), spots.end(), [&](const servo::ImageSpot& s) {
    return !s.off_line && std::any_of(as_seen.matched.begin(), as_seen.matched.end(),
                                      [&](const control::MatchedPoint& m) { return m.row == s.row && m.col == s.col; });
  });
  ASSERT_NE(moved, spots.end());
  moved->u += 3.0;
  const servo::StepResult r = held.step(spots, initial.wTc);
  EXPECT_EQ(r.held_by_taught, as_seen.held_by_taught + 1);
  for (const auto& m : r.matched) EXPECT_FALSE(m.row == moved->row && m.col == moved->col) << "the moved spot served";
  const servo::StepResult f = free.step(spots, initial.wTc);
  EXPECT_EQ(f.held_by_taught, 0);
  EXPECT_TRUE(std::any_of(f.matched.begin(), f.matched.end(),
                          [&](const control::MatchedPoint& m) { return m.row == moved->row && m.col == moved->col; }));
  // s* given from a file has no pose with it: nothing is held
  held.set_reference(held.reference());
  EXPECT_EQ(held.step(spots, initial.wTc).held_by_taught, 0);
  // refused at start: without the calibration nothing is triangulated; a projector riding on
  // the camera lights points that move with it
  servo::ServoConfig none;
  none.taught_points = true;
  EXPECT_THROW(servo::ServoPipeline(pattern::WindowTable(desired.cell->projector->pattern(), {3, 3}), none),
               std::invalid_argument);
  servo::ServoConfig riding = none;
  calibration::ProjectorModel on_camera = calibration_of(*desired.cell);
  on_camera.on_camera = Eigen::Isometry3d::Identity();
  riding.projector = on_camera;
  riding.law.features = control::VisualFeatures::kPlane;
  try {
    servo::ServoPipeline p(pattern::WindowTable(desired.cell->projector->pattern(), {3, 3}), riding);
    ADD_FAILURE() << "taught points accepted with the projector on the camera";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rides on the camera"), std::string::npos) << e.what();
  }
}

}  // namespace
