// M-array decoding, the decoder: the steps in order (SpotDecoder; the steps are declared in spot_decoder.hpp).
#include <algorithm>
#include <cmath>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>

#include "servo/vision/decoder_support.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace vision {
using namespace decoder_support;

SpotDecoder::SpotDecoder(pattern::WindowTable table, DecoderOptions options)
    : table_(std::move(table)), options_(options) {
  options_.segmentation.colours = table_.array().colours;
  (void)at_crosstalk(options_.segmentation);  // a crosstalk out of range fails here, not at the first frame
  // the distance of the pattern decides how much a window may be repaired
  distance_ = table_.min_hamming();  // a table holds only arrays with the window property
  if (options_.tolerance.by_pattern_distance && distance_ >= 3) {
    options_.tolerance.enabled = true;
    options_.tolerance.max_missing = std::max(options_.tolerance.max_missing, std::min(2, distance_ - 1));
  }
}

namespace {

// Step 7's slivers join the spots, unlinked (no window, their normalised coordinates checked).
void join_slivers(const std::vector<Spot>& slivers, const EpipolarGeometry& geometry, std::vector<Spot>& detected,
                  AdjacencyGraph& graph, Neighbourhoods& hoods, EpipolarCheck& check, int& n) {
  for (const Spot& x : slivers) {
    detected.push_back(x);
    graph.next.push_back({-1, -1, -1, -1});
    Window w{-1, -1, -1, -1, -1, -1, -1, -1, -1};
    w[4] = n++;
    hoods.window.push_back(w);
    check.xy.push_back(geometry.normalise(x.u, x.v));
  }
}

// The spots reported of those decoded. A spot cut by the image border helps decode its
// neighbours, but its centroid is not where its centre is: it is not reported. Nor is a
// fragment, a blob far smaller than the spots linked to it (a spot cut by a depth edge or the
// object's silhouette), nor a speck, far smaller than the spots identified around its id, unless
// an edge run (`edge_run`) named it.
std::vector<DecodedSpot> reported_spots(const std::vector<Spot>& detected, const std::vector<DecodedSpot>& decoded,
                                        const AdjacencyGraph& graph, const pattern::MArray& pattern,
                                        const std::vector<char>& edge_run, const DecoderOptions& o) {
  const std::vector<char> speck = specks(detected, decoded, pattern, o.speck_area);
  std::vector<DecodedSpot> reported;
  for (std::size_t i = 0; i < decoded.size(); ++i) {
    const DecodedSpot& d = decoded[i];
    const bool run = d.spot < static_cast<int>(edge_run.size()) && edge_run[d.spot];
    const bool small = speck[i] || is_fragment(detected, graph, d.spot, o.fragment_area);
    if (!detected[d.spot].truncated && (!small || run)) reported.push_back(d);
  }
  return reported;
}

// With the calibration, the reported spots whose centroid lies off their id's line by more than
// the frame's grown limit (DecodedSpot::off_line). A spot's centre lies on its line; a blob of
// its light past a silhouette (on the surface behind, its centre hidden) or a spot split by a
// depth edge lies aside. On the 72 calibrated tuning sweeps (400 poses, seed 1) 74 % of the
// spills and 42 % of the ids over 2 px from their spot's centre lie so, 0.26 % of the right ids.
// Steps 6 and 7 hold their spots to that limit already: these are the windows' (step 3's).
void mark_off_line(std::vector<DecodedSpot>& reported, const EpipolarCheck& check) {
  for (DecodedSpot& d : reported) d.off_line = !check.confirms_grown(d.spot, {d.row, d.col});
}

}  // namespace

namespace {

// The frame's own lines, fitted to the spots `decoded` names (FittedEpipolarLines), with the
// normalised coordinates and grid positions they were fitted on.
struct FrameLines {
  FrameLines(const std::vector<DecodedSpot>& decoded, const calibration::CameraIntrinsics& camera, double tolerance_px,
             bool rank2)
      : xy(normalised(decoded, camera)), grid(grid_of(decoded)),
        lines(xy, grid, 0.5 * (camera.fx + camera.fy), tolerance_px, rank2) {}
  static std::vector<Eigen::Vector2d> normalised(const std::vector<DecodedSpot>& decoded,
                                                 const calibration::CameraIntrinsics& camera) {
    std::vector<Eigen::Vector2d> xy;
    xy.reserve(decoded.size());
    for (const DecodedSpot& d : decoded) xy.push_back(calibration::normalise(camera, {d.u, d.v}));
    return xy;
  }
  static std::vector<Eigen::Vector2d> grid_of(const std::vector<DecodedSpot>& decoded) {
    std::vector<Eigen::Vector2d> grid;
    grid.reserve(decoded.size());
    for (const DecodedSpot& d : decoded) grid.emplace_back(d.col, d.row);
    return grid;
  }
  std::vector<Eigen::Vector2d> xy, grid;
  FittedEpipolarLines lines;
};

}  // namespace

void mark_off_fitted_lines(std::vector<DecodedSpot>& decoded, const calibration::CameraIntrinsics& camera,
                           const EpipolarOptions& options) {
  const FrameLines frame(decoded, camera, options.tolerance_px, false);
  for (DecodedSpot& d : decoded) d.off_line = false;
  if (!frame.lines.fitted()) return;
  std::vector<double> residuals, finite;
  residuals.reserve(decoded.size());
  for (std::size_t k = 0; k < decoded.size(); ++k) residuals.push_back(frame.lines.residual_px(frame.xy[k], frame.grid[k]));
  std::copy_if(residuals.begin(), residuals.end(), std::back_inserter(finite), [](double r) { return std::isfinite(r); });
  const double limit = grown_limit_of(std::move(finite), options.grown_limit, options.tolerance_px);
  for (std::size_t k = 0; k < decoded.size(); ++k) decoded[k].off_line = !(residuals[k] <= limit);
}

DecodeResult SpotDecoder::decode_spots(std::vector<Spot> spots, const EpipolarGeometry* geometry) const {
  // the steps index the geometry's lines by the pattern's ids (EpipolarGeometry::line_distance_px)
  if (const pattern::MArray& pattern = table_.array();
      geometry && (geometry->rows() != pattern.rows || geometry->cols() != pattern.cols))
    throw std::invalid_argument("decode: the epipolar geometry has " + std::to_string(geometry->rows()) + " x " +
                                std::to_string(geometry->cols()) + " spots, the pattern " + std::to_string(pattern.rows) +
                                " x " + std::to_string(pattern.cols));
  DecodeResult r;
  r.detected = std::move(spots);
  // the slivers wait for step 7: the steps before see the spots only
  const auto first_sliver = std::stable_partition(r.detected.begin(), r.detected.end(), [](const Spot& s) { return !s.sliver; });
  std::vector<Spot> slivers(first_sliver, r.detected.end());
  r.detected.erase(first_sliver, r.detected.end());
  const CellShape& shape = options_.cell_shape;
  AdjacencyGraph graph = build_adjacency(r.detected, options_.mend_links, options_.adjacency, shape);
  Neighbourhoods hoods = check_graph_consistency(graph);
  int n = static_cast<int>(r.detected.size());
  std::vector<char> edge_run;  // the spots an edge run named (step 7)
  std::optional<EpipolarCheck> epipolar;
  if (geometry) epipolar.emplace(*geometry, r.detected);
  if (options_.mend_links) {
    for (const ShearAxis axis : {ShearAxis::kColumns, ShearAxis::kRows}) {
      graph = resolve_shear(r.detected, graph, hoods, table_, epipolar ? &*epipolar : nullptr, axis, shape);
      hoods = check_graph_consistency(graph);
    }
  }
  // what tells whether a window's code places each of its lines (step 3's votes, both ways)
  const LineContext lines{r.detected, graph, table_.array()};
  if (geometry) {
    const EpipolarOptions& e = options_.epipolar;
    const EpipolarCheck& check = *epipolar;
    ToleranceOptions tolerance = options_.tolerance;
    tolerance.enabled = tolerance.enabled || e.tolerant;
    const std::vector<WindowReading> readings = read_windows(r.detected, hoods, table_, tolerance, &check, shape);
    r.readings = static_cast<int>(readings.size());
    std::vector<IdVote> votes;
    add_window_votes(hoods, readings, votes, &lines);
    if (e.segment_length >= 3) {  // (a run of 1 or 2 has no inner spot to vote for)
      // the runs' residuals are held to the windows' (EpipolarCheck::set_grown_limit)
      const std::vector<DecodedSpot> by_windows = check_vote_consistency(r.detected, votes, options_.min_votes, e.two_exact_votes);
      epipolar->set_grown_limit(by_windows, e.grown_limit);
      read_segments(r.detected, graph, check, table_.array(), e.segment_length, by_windows, votes, shape, e.growth.unlike);
    }
    const auto islands = [&] { r.decoded = check_island_consistency(graph, std::move(r.decoded), n, e.min_island, true); };
    r.decoded = check_vote_consistency(r.detected, votes, options_.min_votes, e.two_exact_votes);
    const std::vector<DecodedSpot> voted = r.decoded;  // for step 5b
    islands();
    epipolar->set_grown_limit(r.decoded, e.grown_limit);
    if (e.grow) {
      r.decoded = grow_lattice(r.detected, graph, check, table_.array(), std::move(r.decoded), e.min_sources, e.growth,
                               &r.growth);
      islands();
      if (e.edge_runs) {
        join_slivers(slivers, *geometry, r.detected, graph, hoods, *epipolar, n);
        r.growth.resize(r.detected.size(), GrowthOutcome::kUnclaimed);  // the slivers step 6 never saw
        r.decoded = name_edge_runs(r.detected, graph, check, table_.array(), std::move(r.decoded), &edge_run, e.edge_run,
                                   e.growth, options_.cell_shape);
        islands();
      }
    }
    r.decoded = restore_window_spots(graph, voted, std::move(r.decoded), n, e.min_island, table_.array());
  } else {
    const std::vector<WindowReading> readings = read_windows(r.detected, hoods, table_, options_.tolerance, nullptr, shape);
    r.readings = static_cast<int>(readings.size());
    r.decoded = check_decoding_consistency(r.detected, hoods, readings, options_.min_votes, &lines);
    if (options_.min_island > 0)
      r.decoded = check_island_consistency(graph, std::move(r.decoded), n, options_.min_island);
  }
  r.decoded = reported_spots(r.detected, r.decoded, graph, table_.array(), edge_run, options_);
  if (epipolar) mark_off_line(r.decoded, *epipolar);
  r.graph = std::move(graph);
  r.hoods = std::move(hoods);
  return r;
}

DecodeResult SpotDecoder::decode_uncalibrated(const cv::Mat& rgb, const calibration::CameraIntrinsics& camera,
                                              DecodeScratch* scratch) const {
  return decode_uncalibrated(rgb, cv::Mat(), camera, scratch);
}

DecodeResult SpotDecoder::decode_uncalibrated(const cv::Mat& rgb, const cv::Mat& white,
                                              const calibration::CameraIntrinsics& camera, DecodeScratch* scratch) const {
  Segmentation seg = segment(rgb, white, false, scratch);
  const EpipolarOptions& e = options_.epipolar;
  DecodeResult r = decode_spots(e.fitted_lines ? seg.spots : std::move(seg.spots), nullptr);
  r.rejected_blobs = seg.rejected;
  if (e.fitted_lines) {
    const FrameLines frame(r.decoded, camera, e.tolerance_px, true);
    if (frame.lines.fitted()) {
      const pattern::MArray& pattern = table_.array();
      const EpipolarGeometry geometry(camera, frame.lines, pattern.rows, pattern.cols, e.tolerance_px);
      r = decode_spots(std::move(seg.spots), &geometry);
      r.rejected_blobs = seg.rejected;
      return r;
    }
  }
  mark_off_fitted_lines(r.decoded, camera, e);
  return r;
}

Segmentation SpotDecoder::segment(const cv::Mat& rgb, const cv::Mat& white, bool calibrated,
                                  DecodeScratch* scratch) const {
  // The chroma levels follow the camera's crosstalk with the calibration only: without it the
  // peak level is all that keeps the wash of a far surface's spots from the windows, and at a
  // crosstalk of 0.2 the scaled levels let an egg's windows name a table spot past its top
  // silhouette (1 in 400 poses at seed 1, 1 more in 1000 at seed 7 and at seed 11 wide); with
  // it the epipolar check holds them (no wrong id more in 72 + 2 x 12 tuning sweeps).
  // docs/decoding.md, Decisions.
  SegmentationOptions levels = options_.segmentation;
  if (!calibrated) levels.crosstalk = kLevelsCrosstalk;
  DecodeScratch own;
  DecodeScratch& s = scratch ? *scratch : own;
  if (white.empty()) return segment_spots(rgb, levels, &s.segmentation);
  normalise_by_white(rgb, white, s.ratio, options_.reference, &s.white_mean);
  levels.own_spots = false;  // the ratio's noise is no camera's (SegmentationOptions::own_spots)
  Segmentation seg = segment_spots(s.ratio, levels, &s.segmentation);
  strengths_as_shown(seg.spots, white, options_.reference);
  return seg;
}

DecodeResult SpotDecoder::decode(const cv::Mat& rgb, const EpipolarGeometry* geometry, DecodeScratch* scratch) const {
  return decode(rgb, cv::Mat(), geometry, scratch);
}

DecodeResult SpotDecoder::decode(const cv::Mat& rgb, const cv::Mat& white, const EpipolarGeometry* geometry,
                                 DecodeScratch* scratch) const {
  Segmentation seg = segment(rgb, white, geometry != nullptr, scratch);
  DecodeResult r = decode_spots(std::move(seg.spots), geometry);
  r.rejected_blobs = seg.rejected;
  return r;
}

}  // namespace vision
