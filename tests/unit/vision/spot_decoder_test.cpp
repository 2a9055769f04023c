#include "servo/vision/overlay.hpp"
#include "servo/vision/spot_decoder.hpp"

#include <gtest/gtest.h>

#include <random>
#include <set>
#include <stdexcept>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "servo/pattern/palette.hpp"
#include "servo/pattern/pattern_file.hpp"
#include "servo/vision/decoder_options.hpp"
#include "servo/vision/decoder_support.hpp"

namespace vision {
namespace {

const pattern::MArray& paper_pattern() {
  static const pattern::MArray a =
      pattern::load_pattern(std::string(CELL_SOURCE_DIR) + "/servo/pattern/data/marray_20x20_k3_w3.txt", {3, 3}, 3);
  return a;
}
const pattern::WindowTable& table() {
  static const pattern::WindowTable t(paper_pattern(), {3, 3});
  return t;
}

// Spots of the pattern on a lattice: (row, col) at u = 30 + 20 col, v = 30 + 20 row, with
// a shear and small jitter so the graph is not trivially axis-aligned.
struct Lattice {
  std::vector<Spot> spots;
  std::vector<std::pair<int, int>> id;  // true (row, col) of each spot
};
Lattice lattice_of(const pattern::MArray& a, double shear = 0.0) {
  Lattice l;
  for (int r = 0; r < a.rows; ++r)
    for (int c = 0; c < a.cols; ++c) {
      Spot s;
      s.u = 30 + 20 * c + shear * 20 * r + 0.7 * std::sin(r * 3.1 + c);
      s.v = 30 + 20 * r + 0.7 * std::cos(r + c * 2.3);
      s.colour = a.at(r, c);
      s.area_px = 20;
      l.spots.push_back(s);
      l.id.push_back({r, c});
    }
  return l;
}
Lattice lattice(double shear = 0.0) { return lattice_of(paper_pattern(), shear); }

// Every decoded id is the spot's true id; returns how many were decoded.
int check_ids(const Lattice& l, const std::vector<DecodedSpot>& decoded) {
  for (const auto& d : decoded) {
    EXPECT_EQ(d.row, l.id[d.spot].first) << "spot " << d.spot;
    EXPECT_EQ(d.col, l.id[d.spot].second) << "spot " << d.spot;
  }
  return static_cast<int>(decoded.size());
}

std::vector<DecodedSpot> decode_all(const std::vector<Spot>& spots, int min_votes = DecoderOptions{}.min_votes,
                                    int min_island = DecoderOptions{}.min_island) {
  const AdjacencyGraph g = build_adjacency(spots);
  const Neighbourhoods h = check_graph_consistency(g);
  auto decoded = check_decoding_consistency(spots, h, read_windows(spots, h, table()), min_votes);
  return min_island > 0 ? check_island_consistency(g, decoded, static_cast<int>(spots.size()), min_island) : decoded;
}

TEST(AdjacencyGraph, FindsTheFourNeighboursOnALattice) {
  const Lattice l = lattice();
  const AdjacencyGraph g = build_adjacency(l.spots);
  const int i = 5 * 20 + 7;  // (5, 7)
  EXPECT_EQ(g.next[i][kEast], i + 1);
  EXPECT_EQ(g.next[i][kWest], i - 1);
  EXPECT_EQ(g.next[i][kSouth], i + 20);
  EXPECT_EQ(g.next[i][kNorth], i - 20);
  EXPECT_EQ(g.next[0][kWest], -1);
  EXPECT_EQ(g.next[0][kNorth], -1);
}

TEST(AdjacencyGraph, FollowsAShearedGrid) {
  // columns lean 17 deg (perspective on an oblique surface)
  const Lattice l = lattice(0.3);
  const AdjacencyGraph g = build_adjacency(l.spots);
  const int i = 8 * 20 + 8;
  EXPECT_EQ(g.next[i][kSouth], i + 20);
  EXPECT_EQ(g.next[i][kNorth], i - 20);
  EXPECT_EQ(check_ids(l, decode_all(l.spots, 2)), 400 - 4);
}

TEST(IslandConsistency, AmbiguousShearGivesNoWrongIds) {
  // columns lean 35 deg: the lattice is the same point set as one leaning -17 deg, so the
  // geometry alone reads the columns wrongly; the code must not turn that into ids
  const Lattice l = lattice(0.7);
  check_ids(l, decode_all(l.spots));
  // the paper's rules alone (one vote, no islands) do produce wrong ids here
  const auto paper = decode_all(l.spots, 1, 0);
  int wrong = 0;
  for (const auto& d : paper) wrong += d.row != l.id[d.spot].first || d.col != l.id[d.spot].second;
  EXPECT_GT(wrong, 0);
}

// An image grid of rows x cols spots, linked to their four neighbours; spot (y, x)'s id is
// `id(y, x)`.
template <typename Id>
std::pair<AdjacencyGraph, std::vector<DecodedSpot>> linked_grid(int rows, int cols, Id id) {
  AdjacencyGraph g;
  std::vector<DecodedSpot> decoded;
  g.next.assign(static_cast<std::size_t>(rows * cols), {-1, -1, -1, -1});
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      const int i = y * cols + x;
      if (x + 1 < cols) g.next[i][kEast] = i + 1, g.next[i + 1][kWest] = i;
      if (y + 1 < rows) g.next[i][kSouth] = i + cols, g.next[i + cols][kNorth] = i;
      const auto [r, c] = id(y, x);
      decoded.push_back({r, c, 20.0 * x, 20.0 * y, i});
    }
  return {g, decoded};
}

TEST(IslandConsistency, TwoLargeRegionsMeetingAtADepthEdgeKeepTheirIdsAMisreadPatchDoesNot) {
  // the top two rows are one surface (pattern rows 2-3), the bottom two another, whose lattice
  // the image shows cut off (pattern rows 10-11, shifted 3 columns): every link between image
  // rows 1 and 2 contradicts, as the nearest-spot rule links across the ham's silhouette
  const auto surfaces = [](int y, int x) { return y < 2 ? std::pair{2 + y, 4 + x} : std::pair{8 + y, 7 + x}; };
  auto [g, decoded] = linked_grid(4, 8, surfaces);
  EXPECT_EQ(check_island_consistency(g, decoded, 32, 12).size(), 32u);
  // the same edge with only four spots (two by two) below it: too small a region to outweigh
  // the links, a misread patch: it is dropped, the large region it contradicts is not
  auto [g2, patch] = linked_grid(4, 8, surfaces);
  for (int i = 0; i < 32; ++i)
    if (i / 8 >= 2 && i % 8 >= 2) {
      for (int k = 0; k < 4; ++k)
        if (const int j = g2.next[i][k]; j >= 0) g2.next[j][(k + 2) % 4] = -1;
      g2.next[i] = {-1, -1, -1, -1};
    }
  std::erase_if(patch, [](const DecodedSpot& d) { return d.spot / 8 >= 2 && d.spot % 8 >= 2; });
  const auto kept = check_island_consistency(g2, patch, 32, 12);
  for (const auto& d : kept) EXPECT_LT(d.spot / 8, 2) << d.spot;
  EXPECT_EQ(kept.size(), 16u);  // the top rows, the two above the patch too
  // a single misread spot inside one surface is dropped, alone: its links condemn only it
  auto [g3, one] = linked_grid(4, 8, [](int y, int x) { return std::pair{2 + y, 4 + x}; });
  one[10].col += 5;
  const auto left = check_island_consistency(g3, one, 32, 12);
  EXPECT_EQ(left.size(), 31u);
  for (const auto& d : left) EXPECT_NE(d.spot, 10);
}

TEST(IslandConsistency, ALinkAcrossASilhouetteWithinOneRegionIsWhatIsWrongAndItsSpotsComeLast) {
  // an object on the table (image rows 1-3, columns 2-5) shows the pattern one row further on
  // than the table beside it; at its sides the rows shift by one per link (a sheared link,
  // which agrees with the calibration), so object and table are one region. Above it the
  // table's row 3 is hidden: the column links from the table's row 2 reach the object's row 4.
  const auto cell = [](int y, int x) {
    const bool object = y >= 1 && x >= 2 && x <= 5;
    return std::pair{2 + y + (object ? 1 : 0), 4 + x};
  };
  auto [g, decoded] = linked_grid(4, 8, cell);
  // step 5 condemns both ends of each of those four links
  const auto strict = check_island_consistency(g, decoded, 32, 3, true);
  EXPECT_EQ(strict.size(), 24u);
  // each end is held by agreeing links and lies on its id's line: the links are what is wrong
  EXPECT_EQ(check_island_consistency(g, decoded, 32, 3, true, true).size(), 32u);
  // step 5b adds them back after the steps that grow from identified spots
  EXPECT_EQ(restore_window_spots(g, decoded, strict, 32, 3, paper_pattern()).size(), 32u);
  // where a later step gave one of those blobs, or its id, to another spot, it stays so
  auto later = strict;
  later.push_back({2, 6, 0.0, 0.0, 2, NamedBy::kLattice});  // blob (0, 2)'s own id, named again
  const auto added = restore_window_spots(g, decoded, later, 32, 3, paper_pattern());
  EXPECT_EQ(added.size(), 32u);
  EXPECT_EQ(std::count_if(added.begin(), added.end(), [](const DecodedSpot& d) { return d.spot == 2; }), 1);
  // a spot misread inside the region still goes, alone
  auto [g2, misread] = linked_grid(4, 8, cell);
  misread[8 + 6].col += 5;
  const auto left = check_island_consistency(g2, misread, 32, 3, true, true);
  EXPECT_EQ(left.size(), 31u);
  for (const auto& d : left) EXPECT_NE(d.spot, 8 + 6);
}

TEST(AdjacencyGraph, DoesNotLinkAcrossAMissingSpot) {
  Lattice l = lattice();
  const int gone = 6 * 20 + 6;
  l.spots.erase(l.spots.begin() + gone);
  l.id.erase(l.id.begin() + gone);
  const AdjacencyGraph g = build_adjacency(l.spots);
  const int west = 6 * 20 + 5;  // (6, 5): its east neighbour is gone
  EXPECT_EQ(g.next[west][kEast], -1);
}

TEST(GraphConsistency, DropsACornerWhoseTwoPathsDisagree) {
  AdjacencyGraph g;
  // 0 1      spot 3's north is 1, west is 2; N of W (2 -> 0) and W of N (1 -> 4) differ
  // 2 3      (spot 4 is a stray the west link of 1 points to)
  g.next.assign(5, {-1, -1, -1, -1});
  g.next[3][kNorth] = 1;
  g.next[3][kWest] = 2;
  g.next[2][kNorth] = 0;
  g.next[1][kWest] = 4;
  Neighbourhoods h = check_graph_consistency(g);
  EXPECT_EQ(h.window[3][0], -1);
  g.next[1][kWest] = 0;  // now both paths reach 0
  h = check_graph_consistency(g);
  EXPECT_EQ(h.window[3][0], 0);
  EXPECT_EQ(h.window[3][4], 3);
}

TEST(SpotDecoding, PerfectLatticeDecodesEverySpot) {
  const Lattice l = lattice();
  EXPECT_EQ(check_ids(l, decode_all(l.spots, 1)), 400);  // the paper's rule
  EXPECT_EQ(check_ids(l, decode_all(l.spots, 2)), 396);  // corners have one window only
  EXPECT_EQ(check_ids(l, decode_all(l.spots, 3)), 388);  // their neighbours on the border, two
}

TEST(SpotDecoding, MissingNeighbourCostsOnlyItsWindows) {
  Lattice l = lattice();
  const int gone = 10 * 20 + 10;
  l.spots.erase(l.spots.begin() + gone);
  l.id.erase(l.id.begin() + gone);
  const int n = check_ids(l, decode_all(l.spots));
  EXPECT_GT(n, 380);
  EXPECT_LT(n, 399);
}

TEST(SpotDecoding, FlippedColourNeverGivesAWrongId) {
  for (int at : {0, 21, 105, 210, 399}) {
    Lattice l = lattice();
    l.spots[at].colour = (l.spots[at].colour + 1) % 3;
    const auto decoded = decode_all(l.spots);
    check_ids(l, decoded);
    for (const auto& d : decoded) EXPECT_NE(d.spot, at) << "the misread spot itself must not be decoded";
    EXPECT_GT(decoded.size(), 330u);
  }
}

TEST(SpotDecoding, SpuriousBlobNeverGivesAWrongId) {
  Lattice l = lattice();
  Spot stray;
  stray.u = 30 + 20 * 7 + 9;  // between (5, 7) and (5, 8)
  stray.v = 30 + 20 * 5 + 2;
  stray.colour = 2;
  l.spots.push_back(stray);
  l.id.push_back({-1, -1});
  const auto decoded = decode_all(l.spots);
  check_ids(l, decoded);
  EXPECT_GT(decoded.size(), 340u);
}

TEST(DecodingConsistency, ConflictingWindowsRemoveTheSpot) {
  const Lattice l = lattice();
  const Neighbourhoods h = check_graph_consistency(build_adjacency(l.spots));
  std::vector<WindowReading> readings = read_windows(l.spots, h, table());
  const int centre = 8 * 20 + 8;
  for (auto& r : readings)
    if (r.centre == centre) r.id = {3, 3};  // this window now names its spots wrongly
  const auto decoded = check_decoding_consistency(l.spots, h, readings, 1);
  for (const auto& d : decoded) {
    const int dr = d.spot / 20 - 8, dc = d.spot % 20 - 8;
    EXPECT_FALSE(std::abs(dr) <= 1 && std::abs(dc) <= 1) << "spot " << d.spot << " kept despite a conflict";
  }
  EXPECT_EQ(decoded.size(), 400u - 9u);
}

TEST(Tolerance, RecoversAWindowWithOneMissingNeighbourWithoutWrongIds) {
  Lattice l = lattice();
  // remove a checkerboard of spots in one region: windows there miss neighbours
  std::vector<Spot> kept;
  Lattice sparse;
  for (std::size_t i = 0; i < l.spots.size(); ++i) {
    const int r = static_cast<int>(i) / 20, c = static_cast<int>(i) % 20;
    if (r >= 4 && r <= 14 && c >= 4 && c <= 14 && (r * 7 + c * 3) % 11 == 0) continue;
    sparse.spots.push_back(l.spots[i]);
    sparse.id.push_back(l.id[i]);
  }
  const Neighbourhoods h = check_graph_consistency(build_adjacency(sparse.spots));
  const auto strict = check_decoding_consistency(sparse.spots, h, read_windows(sparse.spots, h, table()), 2);
  const auto tolerant = check_decoding_consistency(
      sparse.spots, h, read_windows(sparse.spots, h, table(), ToleranceOptions{true}), 2);
  check_ids(sparse, strict);
  check_ids(sparse, tolerant);
  EXPECT_GE(tolerant.size(), strict.size());
}

// A drawn pattern, rotated and seen in perspective, decodes to the right ids.
TEST(SpotDecoder, RotatedPerspectivePatternImage) {
  const auto& a = paper_pattern();
  cv::Mat flat(600, 600, CV_8UC3, cv::Scalar(12, 12, 12));
  for (int r = 0; r < a.rows; ++r)
    for (int c = 0; c < a.cols; ++c) {
      const pattern::Rgb rgb = pattern::symbol_colour(a.at(r, c));
      cv::circle(flat, {75 + 24 * c, 75 + 24 * r}, 7, cv::Scalar(rgb.r, rgb.g, rgb.b), cv::FILLED, cv::LINE_AA);
    }
  // 15 deg rotation plus a keystone
  const std::vector<cv::Point2f> from{{0, 0}, {600, 0}, {600, 600}, {0, 600}};
  std::vector<cv::Point2f> to;
  const double th = 15 * M_PI / 180;
  for (const auto& p : std::vector<cv::Point2f>{{40, 60}, {600, 0}, {560, 600}, {0, 520}}) {
    const double x = p.x - 320, y = p.y - 240;
    to.push_back(cv::Point2f(static_cast<float>(320 + x * std::cos(th) - y * std::sin(th)),
                             static_cast<float>(240 + x * std::sin(th) + y * std::cos(th))));
  }
  const cv::Mat H = cv::getPerspectiveTransform(from, to);
  cv::Mat img;
  cv::warpPerspective(flat, img, H, {640, 560});
  const SpotDecoder decoder(table());
  const DecodeResult r = decoder.decode(img);
  int correct = 0;
  for (const auto& d : r.decoded) {
    std::vector<cv::Point2f> p{{75.f + 24 * d.col, 75.f + 24 * d.row}}, q;
    cv::perspectiveTransform(p, q, H);
    EXPECT_LT(std::hypot(q[0].x - d.u, q[0].y - d.v), 1.5) << d.row << "," << d.col;
    ++correct;
  }
  EXPECT_GT(correct, 300);
}

// A red spot of Gaussian profile (sigma 1.6 px, peak chroma 200) centred at (u, v).
void paint_spot(cv::Mat& rgb, double u, double v) {
  for (int y = 0; y < rgb.rows; ++y)
    for (int x = 0; x < rgb.cols; ++x) {
      const double d2 = (x - u) * (x - u) + (y - v) * (y - v);
      const int c = static_cast<int>(std::lround(200 * std::exp(-d2 / (2 * 1.6 * 1.6))));
      cv::Vec3b& px = rgb.at<cv::Vec3b>(y, x);
      px[0] = static_cast<std::uint8_t>(std::min(255, px[0] + c));
    }
}

TEST(Segmentation, ASpotGrazingTheBorderKeepsItsCentroidASpotCutByItIsTruncated) {
  cv::Mat rgb(60, 80, CV_8UC3, cv::Scalar(0, 0, 0));
  paint_spot(rgb, 2.0, 15.0);   // its rim touches the left border, the same reach on both sides
  paint_spot(rgb, 0.3, 45.0);   // cut through: nearly half of it is beyond the border
  paint_spot(rgb, 40.0, 30.0);  // inside
  paint_spot(rgb, 40.0, 57.0);  // its rim touches the bottom border
  paint_spot(rgb, 65.0, 59.9);  // its centre beyond the bottom border: a sliver of two rows
  const Segmentation seg = segment_spots(rgb);
  ASSERT_EQ(seg.spots.size(), 5u);
  const auto at = [&](double u, double v) -> const Spot& {
    for (const Spot& s : seg.spots)
      if (std::hypot(s.u - u, s.v - v) < 2.0) return s;
    ADD_FAILURE() << "no spot near " << u << ", " << v;
    return seg.spots.front();
  };
  EXPECT_FALSE(at(2.0, 15.0).truncated);
  EXPECT_NEAR(at(2.0, 15.0).u, 2.0, 0.25);
  EXPECT_TRUE(at(0.3, 45.0).truncated);
  EXPECT_FALSE(at(40.0, 30.0).truncated);
  EXPECT_FALSE(at(40.0, 57.0).truncated);
  EXPECT_NEAR(at(40.0, 57.0).v, 57.0, 0.25);
  EXPECT_TRUE(at(65.0, 58.7).truncated);
  // the test's two numbers are the options': a spot grazing the border is cut when its reach
  // towards it must be longer than it is (2 px, the left one's and the bottom rim's)
  SegmentationOptions strict;
  strict.border_reach_px = 3;
  const Segmentation cut = segment_spots(rgb, strict);
  ASSERT_EQ(cut.spots.size(), 5u);
  for (const Spot& s : cut.spots)  // all but the inner one
    EXPECT_EQ(s.truncated, std::hypot(s.u - 40.0, s.v - 30.0) > 2.0) << s.u << ", " << s.v;
}

// A spot seen edge-on at a silhouette: 1 px wide, 9 px tall (elongation 9) is a sliver, listed
// after the spots, and so is a streak 15 px tall; 1 x 5 (5) is a spot.
TEST(Segmentation, ASpotSeenEdgeOnIsASliverListedLast) {
  cv::Mat rgb(60, 80, CV_8UC3, cv::Scalar(0, 0, 0));
  const auto streak = [&](int x, int y0, int y1) {
    for (int y = y0; y <= y1; ++y) rgb.at<cv::Vec3b>(y, x) = cv::Vec3b(200, 0, 0);
  };
  streak(10, 5, 13);   // the sliver
  paint_spot(rgb, 40.0, 30.0);
  streak(60, 10, 24);  // a streak
  streak(70, 40, 44);
  const Segmentation seg = segment_spots(rgb);
  ASSERT_EQ(seg.spots.size(), 4u);
  EXPECT_FALSE(seg.spots[0].sliver);
  EXPECT_FALSE(seg.spots[1].sliver);
  EXPECT_TRUE(seg.spots[2].sliver);
  EXPECT_TRUE(seg.spots[3].sliver);
  const auto at_column = [&](double u) {
    return std::count_if(seg.spots.begin() + 2, seg.spots.end(), [&](const Spot& s) { return std::abs(s.u - u) < 1e-9; });
  };
  EXPECT_EQ(at_column(10.0), 1);
  EXPECT_EQ(at_column(60.0), 1);
  for (const Spot& s : seg.spots) {
    if (std::abs(s.u - 10.0) < 1e-9) {
      EXPECT_NEAR(s.v, 9.0, 1e-9);
    }
  }
  EXPECT_EQ(seg.rejected, 0);
  // the decoder without a calibration sets slivers aside: they never reach its graph
  const SpotDecoder decoder(table());
  EXPECT_EQ(decoder.decode(rgb).detected.size(), 2u);
}

// A hollow blob, under a quarter of its bounding box (a ring 1 px wide: 56 of 225 pixels), is no
// spot; 2 px wide (104 of 225) it is one, its centroid the ring's centre (SegmentationOptions::
// min_fill: without it a ragged blob at the held-out step's edge was named wrongly).
TEST(Segmentation, AHollowBlobUnderAQuarterOfItsBoxIsNoSpot) {
  cv::Mat rgb(60, 80, CV_8UC3, cv::Scalar(0, 0, 0));
  paint_spot(rgb, 20.0, 30.0);
  cv::rectangle(rgb, {50, 20}, {64, 34}, cv::Scalar(200, 0, 0), 1);
  Segmentation seg = segment_spots(rgb);
  ASSERT_EQ(seg.spots.size(), 1u);
  EXPECT_EQ(seg.rejected, 1);
  EXPECT_LT(seg.spots[0].u, 40);
  cv::rectangle(rgb, {51, 21}, {63, 33}, cv::Scalar(200, 0, 0), 1);
  seg = segment_spots(rgb);
  ASSERT_EQ(seg.spots.size(), 2u);
  EXPECT_EQ(seg.rejected, 0);
  const auto ring = std::find_if(seg.spots.begin(), seg.spots.end(), [](const Spot& s) { return s.u > 40; });
  ASSERT_NE(ring, seg.spots.end());
  EXPECT_EQ(ring->area_px, 104);
  EXPECT_NEAR(ring->u, 57.0, 1e-9);
  EXPECT_NEAR(ring->v, 27.0, 1e-9);
}

TEST(DecodingConsistency, TwoExactVotesNameASpotWhenAskedRepairedOrDisagreeingOnesDoNot) {
  const std::vector<Spot> spots(6);
  const pattern::SpotId a{4, 4}, b{4, 5}, c{4, 6}, d{4, 7}, e{4, 8};
  std::vector<IdVote> votes{{0, a, false}, {0, a, false},                    // two exact
                            {1, b, false}, {1, b, true},                     // one of them repaired
                            {2, c, false}, {2, {4, 9}, false},               // disagreeing
                            {3, d, false}, {3, d, false}, {3, d, true},      // three, one exact suffices
                            {4, e, false}};                                  // one
  const auto ids = [](const std::vector<DecodedSpot>& decoded) {
    std::vector<int> out;
    for (const auto& x : decoded) out.push_back(x.spot);
    std::sort(out.begin(), out.end());
    return out;
  };
  EXPECT_EQ(ids(check_vote_consistency(spots, votes, 3, true)), (std::vector<int>{0, 3}));
  EXPECT_EQ(ids(check_vote_consistency(spots, votes, 3, false)), (std::vector<int>{3}));
  // another spot named the same id by two exact votes: neither keeps it
  votes.push_back({5, a, false});
  votes.push_back({5, a, false});
  EXPECT_EQ(ids(check_vote_consistency(spots, votes, 3, true)), (std::vector<int>{3}));
}

TEST(SpotDecoder, BadImagesGiveAClearErrorOrNoSpots) {
  const SpotDecoder decoder(table());
  EXPECT_THROW(decoder.decode(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(decoder.decode(cv::Mat(480, 640, CV_8UC1, cv::Scalar(128))), std::invalid_argument);
  EXPECT_THROW(decoder.decode(cv::Mat(480, 640, CV_16UC3, cv::Scalar(1, 2, 3))), std::invalid_argument);
  // grey or binary content in an RGB image: no chroma, no spots
  cv::Mat grey(480, 640, CV_8UC3, cv::Scalar(90, 90, 90));
  cv::circle(grey, {100, 100}, 8, cv::Scalar(255, 255, 255), cv::FILLED);
  EXPECT_TRUE(decoder.decode(grey).decoded.empty());
  EXPECT_TRUE(decoder.decode(cv::Mat(1, 1, CV_8UC3, cv::Scalar(0, 0, 255))).decoded.empty());
  EXPECT_TRUE(decoder.decode(cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0))).decoded.empty());
}

}  // namespace
}  // namespace vision

namespace vision {
namespace {

// Issue 19: the decoder with the distance-3 pattern corrects and completes windows.
const pattern::MArray& d3_pattern() {
  static const pattern::MArray a = pattern::load_pattern(
      std::string(CELL_SOURCE_DIR) + "/servo/pattern/data/marray_20x20_k3_w3_d3.txt", {3, 3}, 3);
  return a;
}

TEST(CorrectingDecoder, ReadsTheDistanceOfItsPattern) {
  EXPECT_EQ(SpotDecoder(pattern::WindowTable(paper_pattern(), {3, 3})).pattern_distance(), 1);
  EXPECT_EQ(SpotDecoder(pattern::WindowTable(d3_pattern(), {3, 3})).pattern_distance(), 3);
}

// One wrong colour per window: every window over a misread spot is corrected, names the
// right ids, and does not vote for the misread spot; with misread spots every 4 rows and
// columns (each window holds at most one) the decoder names far more spots than without
// correction, and none of the misread ones.
TEST(CorrectingDecoder, CorrectsOneWrongColourAndLeavesTheMisreadSpotUnnamed) {
  const pattern::WindowTable t(d3_pattern(), {3, 3});
  for (int shift : {0, 1, 2}) {
    Lattice l = lattice_of(d3_pattern());
    std::vector<int> flipped;
    for (int r = 1 + shift; r < 20; r += 4)
      for (int c = 2 + shift; c < 20; c += 4) flipped.push_back(r * 20 + c);
    for (int at : flipped) l.spots[at].colour = (l.spots[at].colour + 1 + shift % 2) % 3;
    const Neighbourhoods h = check_graph_consistency(build_adjacency(l.spots));
    ToleranceOptions tol;
    tol.enabled = true;
    tol.max_missing = 2;
    const auto readings = read_windows(l.spots, h, t, tol);
    int corrected = 0;
    for (const auto& r : readings) {
      EXPECT_EQ(r.id.row, l.id[r.centre].first);
      EXPECT_EQ(r.id.col, l.id[r.centre].second);
      if (r.corrected) {
        ++corrected;
        ASSERT_GE(r.wrong, 0);
        EXPECT_NE(std::find(flipped.begin(), flipped.end(), h.window[r.centre][r.wrong]), flipped.end())
            << "the corrected cell is not a misread spot";
      }
    }
    EXPECT_GT(corrected, 150);
    SpotDecoder correcting(t);
    DecoderOptions plain_options;
    plain_options.tolerance.by_pattern_distance = false;
    SpotDecoder plain(t, plain_options);
    const auto with = correcting.decode_spots(l.spots).decoded;
    const auto without = plain.decode_spots(l.spots).decoded;
    check_ids(l, with);
    for (const auto& d : with)
      EXPECT_EQ(std::find(flipped.begin(), flipped.end(), d.spot), flipped.end()) << "a misread spot was given an id";
    // a corrected window votes only off its misread cell's row and column (votes_for): here,
    // a misread spot every 4 rows and columns, that names none the plain decoder does not
    EXPECT_GE(with.size(), without.size()) << with.size() << " against " << without.size();
  }
}

// A corrected window's misread cell, and the row and column through it, get no vote from it:
// the row the links skipped into reads two of three colours right by chance.
TEST(CorrectingDecoder, ACorrectedWindowVotesOnlyOffItsMisreadCellsRowAndColumn) {
  WindowReading exact{0, {5, 5}, false, -1};
  for (int i = 0; i < 9; ++i) EXPECT_TRUE(votes_for(exact, i)) << i;
  const auto voted = [](int wrong) {
    std::vector<int> cells;
    for (int i = 0; i < 9; ++i)
      if (votes_for(WindowReading{0, {5, 5}, true, wrong}, i)) cells.push_back(i);
    return cells;
  };
  EXPECT_EQ(voted(8), (std::vector<int>{0, 1, 3, 4}));  // the south-east cell misread
  EXPECT_EQ(voted(4), (std::vector<int>{0, 2, 6, 8}));  // the centre: only the corners
  EXPECT_EQ(voted(1), (std::vector<int>{3, 5, 6, 8}));
  // through the decoder's votes: no vote on the misread cell's row and column
  Lattice l = lattice();
  const Neighbourhoods h = check_graph_consistency(build_adjacency(l.spots));
  const int centre = 5 * 20 + 5;
  std::vector<IdVote> votes;
  add_window_votes(h, {WindowReading{centre, {5, 5}, true, 8}}, votes);
  std::vector<int> spots;
  for (const IdVote& v : votes) spots.push_back(v.spot);
  std::sort(spots.begin(), spots.end());
  EXPECT_EQ(spots, (std::vector<int>{4 * 20 + 4, 4 * 20 + 5, 5 * 20 + 4, 5 * 20 + 5}));
}

// A surface seen past an edge, one column over from the lattice below (the can's top past its
// rim, of which one row shows): row 6 of the paper's pattern shifted a step west above rows
// 7-19. Row 6 holds a run of five red spots (columns 7-11), so the windows centred on (7, 8) and
// (7, 9) read exactly as their own with their top row one column off, and two exact votes named
// the spots there (6, 8) and (6, 9) where they are (6, 9) and (6, 10). The spot linked beyond the
// row's east end, (6, 12) in place of (6, 11), shows the shifted row's colour: a window votes for
// no line whose place its code does not fix.
TEST(WindowVotes, AWindowDoesNotNameALineItsCodeDoesNotPlace) {
  const pattern::MArray& a = paper_pattern();
  for (int c = 7; c <= 11; ++c) ASSERT_EQ(a.at(6, c), 2) << "the run this test stands on";
  ASSERT_NE(a.at(6, 12), a.at(6, 11));
  Lattice l;
  for (int r = 6; r < a.rows; ++r)
    for (int c = 0; c < a.cols; ++c) {
      const int id_col = r == 6 ? c + 1 : c;  // the shifted row: the spot at column c is c + 1's
      if (id_col >= a.cols) continue;
      Spot s;
      s.u = 30 + 20 * c + 0.7 * std::sin(r * 3.1 + c);
      s.v = 30 + 20 * r + 0.7 * std::cos(r + c * 2.3);
      s.colour = a.at(r, id_col);
      s.area_px = 20;
      l.spots.push_back(s);
      l.id.push_back({r, id_col});
    }
  const AdjacencyGraph g = build_adjacency(l.spots);
  const Neighbourhoods h = check_graph_consistency(g);
  const int centre = 19 + 9;  // (7, 9): row 6 has 19 spots
  ASSERT_EQ(l.id[centre], (std::pair{7, 9}));
  const WindowReading own{centre, {7, 9}, false, -1};
  const std::vector<WindowReading> read = read_windows(l.spots, h, table());
  ASSERT_NE(std::find_if(read.begin(), read.end(), [&](const WindowReading& r) { return r.centre == centre && r.id == own.id; }),
            read.end()) << "the window reads as its own";
  const LineContext lines{l.spots, g, a};
  EXPECT_TRUE(line_shifted(lines, h.window[centre], own.id, 0)) << "its top row";
  for (int k = 1; k < 6; ++k) EXPECT_FALSE(line_shifted(lines, h.window[centre], own.id, k)) << "line " << k;
  std::vector<IdVote> one;
  add_window_votes(h, {own}, one, &lines);
  EXPECT_EQ(one.size(), 6U);
  // every window's votes, two exact ones naming a spot (the calibrated decoder's step 4): the
  // shifted row's spots one column off without the check, none with it
  const auto wrong = [&](const LineContext* ctx) {
    std::vector<IdVote> votes;
    add_window_votes(h, read, votes, ctx);
    int n = 0;
    for (const DecodedSpot& d : check_vote_consistency(l.spots, votes, 3, true))
      n += l.id[d.spot] != std::pair{d.row, d.col};
    return n;
  };
  EXPECT_EQ(wrong(nullptr), 2) << "the case this test stands on";
  EXPECT_EQ(wrong(&lines), 0);
}

// One or two missing neighbours: the window is completed by the one code that fits.
TEST(CorrectingDecoder, CompletesWindowsWithOneOrTwoMissingNeighbours) {
  const pattern::WindowTable t(d3_pattern(), {3, 3});
  Lattice l = lattice_of(d3_pattern());
  // two spots of the window centred at (10, 10) gone: its north-east and south-west corners
  // (a missing side neighbour would also cost the corners next to it their second path)
  const int centre = 10 * 20 + 10;
  std::vector<Spot> spots;
  Lattice kept;
  for (std::size_t i = 0; i < l.spots.size(); ++i) {
    if (static_cast<int>(i) == 9 * 20 + 11 || static_cast<int>(i) == 11 * 20 + 9) continue;
    kept.spots.push_back(l.spots[i]);
    kept.id.push_back(l.id[i]);
  }
  const Neighbourhoods h = check_graph_consistency(build_adjacency(kept.spots));
  ToleranceOptions tol;
  tol.enabled = true;
  tol.max_missing = 2;
  int centre_index = -1;
  for (std::size_t i = 0; i < kept.id.size(); ++i)
    if (kept.id[i] == std::make_pair(10, 10)) centre_index = static_cast<int>(i);
  ASSERT_GE(centre_index, 0);
  int missing = 0;
  for (int v : h.window[centre_index]) missing += v < 0;
  ASSERT_EQ(missing, 2);
  bool completed = false;
  for (const auto& r : read_windows(kept.spots, h, t, tol)) {
    EXPECT_EQ(r.id.row, kept.id[r.centre].first);
    EXPECT_EQ(r.id.col, kept.id[r.centre].second);
    completed |= r.centre == centre_index;
  }
  EXPECT_TRUE(completed) << "the window with two missing neighbours was not completed";
  (void)centre;
  check_ids(kept, SpotDecoder(t).decode_spots(kept.spots).decoded);
}

// A window recoloured into another valid window (three spots changed: the distance) reads as
// that window; its neighbours' windows disagree, and no spot comes out with a wrong id.
TEST(CorrectingDecoder, AWindowBuiltToTemptAWrongIdComesOutRightOrUnidentified) {
  const pattern::MArray& a = d3_pattern();
  const pattern::WindowTable t(a, {3, 3});
  Lattice l = lattice_of(a);
  // the window at (8, 8) and the nearest other window of the pattern
  const auto window = [&](int r, int c) {
    std::array<int, 9> w{};
    for (int i = 0; i < 9; ++i) w[i] = a.at(r - 1 + i / 3, c - 1 + i % 3);
    return w;
  };
  const auto mine = window(8, 8);
  int best = 10, br = 0, bc = 0;
  for (int r = 1; r < 19; ++r)
    for (int c = 1; c < 19; ++c) {
      if (r == 8 && c == 8) continue;
      const auto other = window(r, c);
      int d = 0;
      for (int i = 0; i < 9; ++i) d += other[i] != mine[i];
      if (d < best) best = d, br = r, bc = c;
    }
  ASSERT_EQ(best, 3);
  const auto other = window(br, bc);
  for (int i = 0; i < 9; ++i) l.spots[(8 - 1 + i / 3) * 20 + (8 - 1 + i % 3)].colour = other[i];
  const auto decoded = SpotDecoder(t).decode_spots(l.spots).decoded;
  check_ids(l, decoded);  // right, or not named at all
  EXPECT_GT(decoded.size(), 300u);
}

// With the paper's distance-1 pattern the decoder is what it was, id for id: the distance
// turns nothing on.
TEST(CorrectingDecoder, TheDistanceOnePatternDecodesAsBefore) {
  const pattern::WindowTable t(paper_pattern(), {3, 3});
  DecoderOptions off;
  off.tolerance.by_pattern_distance = false;
  const SpotDecoder now(t), before(t, off);
  for (int at : {0, 105, 210}) {
    Lattice l = lattice();
    l.spots[at].colour = (l.spots[at].colour + 1) % 3;
    l.spots.erase(l.spots.begin() + at + 41);
    l.id.erase(l.id.begin() + at + 41);
    const auto a = now.decode_spots(l.spots).decoded, b = before.decode_spots(l.spots).decoded;
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].spot, b[i].spot);
      EXPECT_EQ(a[i].row, b[i].row);
      EXPECT_EQ(a[i].col, b[i].col);
    }
  }
}

}  // namespace
}  // namespace vision

namespace vision {
namespace {

// Columns slanted by 0.9 of a step per row (a surface whose depth changes along the columns):
// the nearest spot below is the south-west diagonal, and step 1 links it. Resolving the shear
// by the code relinks the columns, and the decoder names the lattice, every id right.
TEST(ColumnShear, TheCodeTellsTheTrueColumnsOfAShearedLattice) {
  for (const pattern::MArray* a : {&paper_pattern(), &d3_pattern()}) {
    const pattern::WindowTable t(*a, {3, 3});
    const Lattice l = lattice_of(*a, 0.9);
    const AdjacencyGraph g = build_adjacency(l.spots);
    int diagonal = 0;
    for (std::size_t s = 0; s < l.spots.size(); ++s) {
      const int j = g.next[s][kSouth];
      diagonal += j >= 0 && l.id[j].second != l.id[s].second;
    }
    EXPECT_GT(diagonal, 200) << "the lattice is not sheared enough to mislead step 1";
    const AdjacencyGraph resolved = resolve_shear(l.spots, g, check_graph_consistency(g), t);
    int right = 0;
    for (std::size_t s = 0; s < l.spots.size(); ++s) {
      const int j = resolved.next[s][kSouth];
      if (j < 0) continue;
      EXPECT_EQ(l.id[j].second, l.id[s].second) << "spot " << s;
      EXPECT_EQ(l.id[j].first, l.id[s].first + 1) << "spot " << s;
      ++right;
    }
    EXPECT_GT(right, 300);
    DecoderOptions off;
    off.mend_links = false;
    const int with = check_ids(l, SpotDecoder(t).decode_spots(l.spots).decoded);
    const int without = check_ids(l, SpotDecoder(t, off).decode_spots(l.spots).decoded);
    EXPECT_GT(with, 300);
    EXPECT_LT(without, 100);
  }
}

// A window across a depth edge: its top row comes from the surface behind, shifted along the
// row by 0.6 of a step, colours intact. It is not a lattice cell, and it is not read.
TEST(ColumnShear, AWindowAcrossADepthEdgeIsNotRead) {
  Lattice l = lattice();
  const Neighbourhoods h = check_graph_consistency(build_adjacency(l.spots));
  const int centre = 5 * 20 + 5;
  const auto reads_centre = [&](const std::vector<Spot>& spots) {
    for (const auto& r : read_windows(spots, h, table()))
      if (r.centre == centre) return true;
    return false;
  };
  ASSERT_TRUE(reads_centre(l.spots));
  for (int c = 4; c <= 6; ++c) l.spots[4 * 20 + c].u += 0.6 * 20 * (c - 3) / 2.0;
  EXPECT_FALSE(reads_centre(l.spots));
}

// Issue 41: a dim spot keeps its extent down to the floor (10) and is a spot where it reaches
// the seed level (14) somewhere; a faint wash that never does makes no blob. Under strong noise
// the image is averaged first: the spots come out, the noise's blobs do not.
TEST(Segmentation, ADimSpotIsKeptAFaintWashIsNotAndANoisyImageIsAveraged) {
  cv::Mat rgb(60, 80, CV_8UC3, cv::Scalar(20, 20, 20));
  const auto paint = [&](double u, double v, double peak) {
    for (int y = 0; y < rgb.rows; ++y)
      for (int x = 0; x < rgb.cols; ++x) {
        const double d2 = (x - u) * (x - u) + (y - v) * (y - v);
        rgb.at<cv::Vec3b>(y, x)[1] = cv::saturate_cast<std::uint8_t>(rgb.at<cv::Vec3b>(y, x)[1] + peak * std::exp(-d2 / (2 * 2.0 * 2.0)));
      }
  };
  paint(20, 30, 24);  // dim: its peak clears 14
  paint(50, 30, 12);  // a wash: above the floor of 10 at its middle, never 14
  const Segmentation quiet = segment_spots(rgb);
  ASSERT_EQ(quiet.spots.size(), 1u);
  EXPECT_NEAR(quiet.spots[0].u, 20, 0.05);
  EXPECT_GE(quiet.spots[0].area_px, 9);  // the pixels down to the floor
  SegmentationOptions high = {};
  high.min_threshold = 14;
  EXPECT_LT(segment_spots(rgb, high).spots[0].area_px, quiet.spots[0].area_px);

  cv::Mat noisy(120, 160, CV_8UC3, cv::Scalar(60, 60, 60));
  for (int k = 0; k < 6; ++k) {
    const double u = 20 + 24 * k, v = 60;
    for (int y = 0; y < noisy.rows; ++y)
      for (int x = 0; x < noisy.cols; ++x) {
        const double d2 = (x - u) * (x - u) + (y - v) * (y - v);
        noisy.at<cv::Vec3b>(y, x)[k % 3] = cv::saturate_cast<std::uint8_t>(noisy.at<cv::Vec3b>(y, x)[k % 3] + 45 * std::exp(-d2 / (2 * 2.5 * 2.5)));
      }
  }
  cv::Mat noise(noisy.size(), CV_16SC3);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::NORMAL, 0, 12);
  cv::Mat sum;
  noisy.convertTo(sum, CV_16SC3);
  sum += noise;
  sum.convertTo(noisy, CV_8UC3);
  SegmentationOptions raw = {};
  raw.smoothing = false;
  const Segmentation averaged = segment_spots(noisy), plain = segment_spots(noisy, raw);
  EXPECT_EQ(averaged.spots.size(), 6u);
  for (const Spot& s : averaged.spots) EXPECT_NEAR(s.v, 60, 1.0);  // a noise of 12 levels moves a centroid
  EXPECT_LT(plain.spots.size(), 6u);  // without the average the floor rises over the spots
}

// Issue 41: under noise the image is averaged over 3 x 3 first, and the mean dims a spot seen
// edge-on (1-2 px wide, the last column before a silhouette) under the local level its bright
// neighbours set. The image itself, at its own noise floor, keeps it: one spot each, the edge-on
// one too, none twice.
TEST(Segmentation, UnderNoiseASpotSeenEdgeOnBesideBrightOnesIsKeptAndNoSpotIsFoundTwice) {
  int kept = 0;
  for (int draw = 1; draw <= 20; ++draw) {
    cv::Mat rgb(60, 120, CV_8UC3, cv::Scalar(60, 60, 60));
    const auto paint = [&](double u, double v, int channel, double peak, double su, double sv) {
      for (int y = 0; y < rgb.rows; ++y)
        for (int x = 0; x < rgb.cols; ++x) {
          const double e = (x - u) * (x - u) / (2 * su * su) + (y - v) * (y - v) / (2 * sv * sv);
          auto& px = rgb.at<cv::Vec3b>(y, x)[channel];
          px = cv::saturate_cast<std::uint8_t>(px + peak * std::exp(-e));
        }
    };
    for (int k = 0; k < 4; ++k) paint(20 + 12 * k, 30, k % 3, 120, 2.5, 2.5);
    paint(62, 30, 1, 70, 0.5, 3.0);  // edge-on, 6 px from the last bright one
    cv::Mat noise(rgb.size(), CV_16SC3), sum;
    cv::RNG rng(draw);
    rng.fill(noise, cv::RNG::NORMAL, 0, 4);  // enough to set the floor over the peak of 14: averaged
    rgb.convertTo(sum, CV_16SC3);
    sum += noise;
    sum.convertTo(rgb, CV_8UC3);
    const Segmentation seg = segment_spots(rgb);
    const auto near = [&](double u, double v) {
      return std::count_if(seg.spots.begin(), seg.spots.end(),
                           [&](const Spot& s) { return std::hypot(s.u - u, s.v - v) < 1.5; });
    };
    for (int k = 0; k < 4; ++k) EXPECT_EQ(near(20 + 12 * k, 30), 1) << "draw " << draw << ", the spot at " << 20 + 12 * k;
    EXPECT_LE(near(62, 30), 1) << "draw " << draw;
    kept += near(62, 30) == 1 && seg.spots.size() == 5;
  }
  // the mean alone keeps it in none of these draws, both passes in 19 here: a margin for another
  // machine's rounding of the painted light
  EXPECT_GE(kept, 15) << "the spot seen edge-on, of 20 noise draws";
}

// Issue 41: the 3 x 3 mean spreads a blob a pixel each way, but not past the image border, so
// a spot 2 px from the border reaches less far towards it than away from it in the mean: the
// border test gives that pixel back. Under noise such a spot is reported with its centroid
// (a tenth of a pixel off), and one whose centre is within a pixel of the border is still cut.
TEST(Segmentation, UnderNoiseASpotNearTheBorderIsCutOnlyWhenItIs) {
  int near_cut = 0, through_cut = 0;
  for (int draw = 1; draw <= 40; ++draw) {
    cv::Mat rgb(40, 60, CV_8UC3, cv::Scalar(60, 60, 60));
    for (int y = 0; y < rgb.rows; ++y)
      for (int x = 0; x < rgb.cols; ++x) {
        const auto light = [&](double u, double v) {
          return 120 * std::exp(-((x - u) * (x - u) + (y - v) * (y - v)) / (2 * 2.0 * 2.0));
        };
        auto& px = rgb.at<cv::Vec3b>(y, x);
        px[0] = cv::saturate_cast<std::uint8_t>(px[0] + light(2.0, 12.0) + light(0.8, 30.0));
        px[1] = cv::saturate_cast<std::uint8_t>(px[1] + light(30.0, 20.0));
      }
    cv::Mat noise(rgb.size(), CV_16SC3), sum;
    cv::RNG rng(draw);
    rng.fill(noise, cv::RNG::NORMAL, 0, 6);
    rgb.convertTo(sum, CV_16SC3);
    sum += noise;
    sum.convertTo(rgb, CV_8UC3);
    for (const Spot& s : segment_spots(rgb).spots) {
      if (std::hypot(s.u - 2.0, s.v - 12.0) < 1.0) {
        near_cut += s.truncated;
        EXPECT_NEAR(s.u, 2.0, 0.4) << "draw " << draw;
      }
      if (std::hypot(s.u - 0.8, s.v - 30.0) < 2.0) through_cut += s.truncated;
    }
  }
  // none here, 10 without the pixel given back: a margin for another machine's rounding
  EXPECT_LE(near_cut, 2) << "of 40 draws, the spot 2 px from the border taken for cut";
  EXPECT_EQ(through_cut, 40) << "of 40 draws, the spot 0.8 px from the border";
}

// Issue 41: a camera with more channel crosstalk sees every primary with less chroma, (1 - 3x)
// of its light: told its crosstalk, the segmentation keeps the dim spots such a camera shows
// (its chroma levels scale from the 0.06 they were set at), each with its own colour; at 0.06
// nothing changes, and a crosstalk no camera can have is refused in one line.
TEST(Segmentation, ACameraWithMoreCrosstalkKeepsItsDimSpotsWhenItsCrosstalkIsGiven) {
  constexpr double x = 0.2;
  cv::Mat rgb(40, 160, CV_8UC3, cv::Scalar(30, 30, 30));
  for (int k = 0; k < 6; ++k) {  // primaries of light 26 seen through the crosstalk: chroma peak 10.4
    const double u = 15 + 26 * k, v = 20;
    for (int y = 0; y < rgb.rows; ++y)
      for (int xx = 0; xx < rgb.cols; ++xx) {
        const double d2 = (xx - u) * (xx - u) + (y - v) * (y - v), light = 26 * std::exp(-d2 / (2 * 2.5 * 2.5));
        for (int ch = 0; ch < 3; ++ch) {
          auto& px = rgb.at<cv::Vec3b>(y, xx)[ch];
          px = cv::saturate_cast<std::uint8_t>(px + light * (ch == k % 3 ? 1 - 2 * x : x));
        }
      }
  }
  EXPECT_TRUE(segment_spots(rgb).spots.empty()) << "told 0.06, the spots' chroma of 10 is under the peak of 14";
  SegmentationOptions told;
  told.crosstalk = x;
  const Segmentation seg = segment_spots(rgb, told);
  ASSERT_EQ(seg.spots.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_NEAR(seg.spots[k].u, 15 + 26.0 * static_cast<double>(k), 0.1);
    EXPECT_EQ(seg.spots[k].colour, 2 - static_cast<int>(k % 3)) << "each primary keeps its colour (red is symbol 2)";
  }
  const SegmentationOptions same = at_crosstalk(SegmentationOptions{});
  EXPECT_EQ(same.min_threshold, SegmentationOptions{}.min_threshold);
  EXPECT_EQ(same.min_peak, SegmentationOptions{}.min_peak);
  for (const double bad : {-0.01, 0.31, std::nan("")}) {
    SegmentationOptions o;
    o.crosstalk = bad;
    EXPECT_THROW(segment_spots(rgb, o), std::invalid_argument) << bad;
    DecoderOptions d;
    d.segmentation.crosstalk = bad;
    EXPECT_THROW(SpotDecoder(pattern::WindowTable(paper_pattern(), {3, 3}), d), std::invalid_argument) << bad;
  }
}

// Issue 41: the 3 x 3 mean the segmentation smooths with is the mean of each pixel's
// neighbourhood (the border replicated), rounded to the nearest, for every width's vector tail.
TEST(Segmentation, TheThreeByThreeMeanIsEachNeighbourhoodsRoundedMean) {
  std::mt19937 rng(7);
  std::vector<std::uint16_t> ring;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {2, 3}, {5, 1}, {16, 4}, {17, 9}, {33, 7}, {640, 3}}) {
    cv::Mat rgb(h, w, CV_8UC3);
    for (int v = 0; v < h; ++v)
      for (int k = 0; k < 3 * w; ++k) rgb.ptr<std::uint8_t>(v)[k] = static_cast<std::uint8_t>(rng() % 256);
    if (w == 16) rgb.setTo(cv::Scalar(255, 255, 255));  // the largest sums
    cv::Mat out;
    mean_3x3(rgb, out, ring);
    ASSERT_EQ(out.size(), rgb.size());
    for (int v = 0; v < h; ++v)
      for (int u = 0; u < w; ++u)
        for (int c = 0; c < 3; ++c) {
          int sum = 0;
          for (int dv = -1; dv <= 1; ++dv)
            for (int du = -1; du <= 1; ++du)
              sum += rgb.at<cv::Vec3b>(std::clamp(v + dv, 0, h - 1), std::clamp(u + du, 0, w - 1))[c];
          ASSERT_EQ(out.at<cv::Vec3b>(v, u)[c], (sum + 4) / 9) << w << " x " << h << " at " << u << ", " << v;
        }
  }
}


// The foreground is weighed 16 pixels at a time and its runs read from their bit mask: the
// same spots wherever a run starts or ends within those 16 (the image shifted by every offset
// from 0 to 17 px gives the same spots, shifted). Spots from one pixel wide to wider than 16,
// a width that leaves a tail of 5 pixels, a bar through the last columns (cut by the border:
// a blob, not a spot).
TEST(Segmentation, TheSameSpotsWhereverTheirRunsFallInTheSixteenPixelChunks) {
  std::mt19937 rng(11);
  struct Paint {
    double u, v, sigma;
    int channel;
  };
  std::vector<Paint> paints;
  for (int k = 0; k < 40; ++k)
    paints.push_back({24.0 + (k % 10) * 17.3 + (rng() % 100) / 100.0, 20.0 + (k / 10) * 18.0 + (rng() % 100) / 100.0,
                      0.5 + (rng() % 100) / 40.0, k % 3});
  const auto image = [&](int dx) {
    cv::Mat rgb(96, 245, CV_8UC3, cv::Scalar(30, 30, 30));
    for (const Paint& p : paints)
      for (int y = 0; y < rgb.rows; ++y)
        for (int x = 0; x < rgb.cols; ++x) {
          const double d2 = (x - dx - p.u) * (x - dx - p.u) + (y - p.v) * (y - p.v);
          auto& px = rgb.at<cv::Vec3b>(y, x)[p.channel];
          px = cv::saturate_cast<std::uint8_t>(px + 200 * std::exp(-d2 / (2 * p.sigma * p.sigma)));
        }
    for (int y = 84; y < 90; ++y)
      for (int x = 236; x < 245; ++x) rgb.at<cv::Vec3b>(y, x)[1] = 230;
    return rgb;
  };
  // the painted spots (the bar stays where it is: the border cuts it)
  const auto painted = [](const Segmentation& seg) {
    Segmentation out;
    for (const Spot& s : seg.spots)
      if (s.u < 220) out.spots.push_back(s);
    EXPECT_EQ(out.spots.size() + 1, seg.spots.size());
    return out;
  };
  const Segmentation at0 = painted(segment_spots(image(0)));
  ASSERT_GE(at0.spots.size(), 30u);
  for (int dx = 1; dx <= 17; ++dx) {
    const Segmentation shifted = painted(segment_spots(image(dx)));
    ASSERT_EQ(shifted.spots.size(), at0.spots.size()) << "shifted by " << dx;
    for (std::size_t i = 0; i < at0.spots.size(); ++i) {
      EXPECT_DOUBLE_EQ(shifted.spots[i].u, at0.spots[i].u + dx) << "spot " << i << " shifted by " << dx;
      EXPECT_DOUBLE_EQ(shifted.spots[i].v, at0.spots[i].v);
      EXPECT_EQ(shifted.spots[i].area_px, at0.spots[i].area_px);
      EXPECT_EQ(shifted.spots[i].colour, at0.spots[i].colour);
    }
  }
}

// A disc's search visits every spot within it, in the order the square of cells around it
// would (its candidates are found in that order, so ties fall the same way), fewer others.
TEST(SpatialGrid, ADiscVisitsItsSpotsInTheOrderOfTheSquareAroundIt) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> at(0, 300);
  std::vector<Spot> spots(500);
  for (Spot& s : spots) s.u = at(rng), s.v = at(rng) * 0.7;
  const double cell = 17;
  const decoder_support::SpatialGrid grid(spots, cell);
  std::size_t square_visits = 0, disc_visits = 0;
  for (int t = 0; t < 300; ++t) {
    const double u = at(rng) - 20, v = at(rng) * 0.8 - 20, radius = 0.2 + (t % 7 == 0 ? 400 : at(rng) / 5);
    const auto within = [&](int j) { return std::hypot(spots[j].u - u, spots[j].v - v) <= radius; };
    std::vector<int> square, disc;
    grid.around(u, v, static_cast<int>(std::ceil(radius / cell)) + 1, [&](int j) {
      ++square_visits;
      if (within(j)) square.push_back(j);
    });
    grid.around_disc(u, v, radius, [&](int j) {
      ++disc_visits;
      if (within(j)) disc.push_back(j);
    });
    ASSERT_EQ(disc, square) << "disc of " << radius << " at " << u << ", " << v;
  }
  EXPECT_LT(disc_visits, square_visits * 3 / 4);
}


// A speck: a blob under a fifth of the median area of the spots identified around its id,
// wherever its links go; with fewer than two identified around it, nothing is judged.
TEST(DecodedSpots, ASpeckWhereAnIdsSpotShouldBeIsFlaggedAFewNeighboursJudgeNothing) {
  std::vector<Spot> spots(12);
  std::vector<DecodedSpot> decoded;
  for (int i = 0; i < 9; ++i) {
    spots[i].area_px = 60 + i;
    decoded.push_back({4 + i / 3, 4 + i % 3, 0, 0, i});
  }
  spots[4].area_px = 11;  // the centre: 11 px against a median of 65 (the upper middle of 8)
  spots[9].area_px = 5;   // (8, 8): no identified spot around it: not judged
  decoded.push_back({8, 8, 0, 0, 9});
  spots[10].area_px = 5;  // (2, 3): none around it either
  decoded.push_back({2, 3, 0, 0, 10});
  std::vector<char> flagged = decoder_support::specks(spots, decoded, paper_pattern(), 0.2);
  EXPECT_EQ(flagged, (std::vector<char>{0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0}));
  spots[4].area_px = 13;  // a fifth of 65: a small spot, not a speck
  EXPECT_EQ(decoder_support::specks(spots, decoded, paper_pattern(), 0.2)[4], 0);
  // (3, 5), above the lattice's first row: (4, 4), (4, 5) and (4, 6) judge it
  spots[11].area_px = 10;
  decoded.push_back({3, 5, 0, 0, 11});
  EXPECT_EQ(decoder_support::specks(spots, decoded, paper_pattern(), 0.2).back(), 1);
}

TEST(DecoderOptionNames, SetEachNumberByItsNameAndRefuseWhatIsNotOne) {
  const std::vector<std::string> names = decoder_option_names();
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size()) << "a name twice";
  DecoderOptions o;
  set_decoder_option(o, "growth.slack=0.3");
  set_decoder_option(o, "growth.faintest=7.5");
  set_decoder_option(o, "edge_run.length=6");
  set_decoder_option(o, "segmentation.min_peak=20");
  set_decoder_option(o, "cell_shape.cell_slack=0.25");
  set_decoder_option(o, "epipolar.segment_length=0");
  EXPECT_DOUBLE_EQ(o.epipolar.growth.slack, 0.3);
  EXPECT_FLOAT_EQ(o.epipolar.growth.faintest, 7.5F);
  EXPECT_EQ(o.epipolar.edge_run.length, 6);
  EXPECT_EQ(o.segmentation.min_peak, 20);
  EXPECT_DOUBLE_EQ(o.cell_shape.cell_slack, 0.25);
  EXPECT_EQ(o.epipolar.segment_length, 0);
  // every listed name is settable, and setting one leaves the others as they were
  for (const std::string& n : names) {
    DecoderOptions x;
    EXPECT_NO_THROW(set_decoder_option(x, n + "=1")) << n;
  }
  for (const char* bad : {"growth.nothing=1", "growth.slack=-1", "growth.slack=nan", "growth.slack=inf", "growth.slack=1e10",
                          "growth.slack=", "growth.slack", "=1", "edge_run.length=2.5", "growth.slack=0.3x", "growth.slack=0x1",
                          "growth.slack= 0.3",
                          "segmentation.local_window_px=0", "segmentation.local_window_px=256",
                          "epipolar.segment_length=16"}) {
    DecoderOptions x;
    try {
      set_decoder_option(x, bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + bad + "'"), std::string::npos) << e.what();
    }
    EXPECT_DOUBLE_EQ(x.epipolar.growth.slack, GrowthOptions{}.slack) << bad;
  }
}

// The overlay rings a spot off its epipolar line in orange, the others in white.
TEST(Overlay, ASpotOffItsLineIsRingedInOrange) {
  const cv::Mat black(40, 60, CV_8UC3, cv::Scalar::all(0));
  DecodeResult r;
  r.detected = {Spot{}, Spot{}};
  r.decoded = {DecodedSpot{1, 2, 15.0, 20.0, 0}, DecodedSpot{3, 4, 45.0, 20.0, 1}};
  r.decoded[1].off_line = true;
  const cv::Mat out = draw_overlay(black, r);
  // the ring's rightmost pixel, 5 px from the centre at the overlay's scale of 2
  const auto ring = [&](double u) {
    return out.at<cv::Vec3b>(static_cast<int>((20 + 0.5) * 2), static_cast<int>((u + 0.5) * 2 + 10));
  };
  // (anti-aliased: the ring's colour scaled by its coverage of the pixel)
  const cv::Vec3b white = ring(15.0), orange = ring(45.0);
  EXPECT_GT(white[0], 150);
  EXPECT_TRUE(white[0] == white[1] && white[1] == white[2]) << white;
  EXPECT_GT(orange[0], 150);
  EXPECT_NEAR(orange[1], orange[0] * 160 / 255, 2) << orange;
  EXPECT_EQ(orange[2], 0) << orange;
}

}  // namespace
}  // namespace vision
