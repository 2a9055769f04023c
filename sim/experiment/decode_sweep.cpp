#include "common/output_image.hpp"
#include "common/worker_threads.hpp"
#include "common/progress.hpp"
#include "sim/experiment/decode_sweep.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <tuple>

#include "servo/pipeline/servo_pipeline.hpp"
#include "servo/vision/overlay.hpp"
#include "sim/experiment/experiment.hpp"

namespace experiment {

namespace {
// a decoded blob this close to where some of the named spot's light lands is that light
constexpr double kPartialPx = 4.0;

struct WrongId {
  int pose, row, col;
  double u, v;
  int nearest_row, nearest_col;
  double nearest_px;
  bool named_visible;
  double named_px;  // from the decoded position to where the named spot's centre projects
  int step;         // the decoder step that named it (vision::NamedBy)
};

// An id given to a spill: the named spot's light, its centre hidden or elsewhere (a spot split by
// a depth edge, its light past a silhouette, a spot cut by the image border), and whether it
// reaches the law.
struct SpillId {
  int pose, row, col;
  double u, v;
  double centre_u, centre_v;  // where the named spot's centre projects
  bool centre_visible;
  int step;  // the decoder step that named it (vision::NamedBy)
  bool off_line, to_law, off_taught;
};

// What score_ids lists of a frame's ids for the sweep's files.
struct Listed {
  std::vector<WrongId> wrong;
  std::vector<SpillId> spills;
};

// All poses drawn up front from one seeded stream: the sweep does not depend on threading.
std::vector<SweepRow> draw_rows(const sim::Scenario& sc, const SweepOptions& o) {
  std::array<double, 6> range{};
  for (int i = 0; i < 3; ++i) {
    range[i] = o.max_translation_cm.value_or(std::max(2.0, std::abs(sc.initial_translation_cm[i])));
    range[3 + i] = o.max_rotation_deg.value_or(std::max(2.0, std::abs(sc.initial_rotation_deg[i])));
  }
  std::mt19937_64 rng(o.seed);
  std::vector<SweepRow> rows(static_cast<std::size_t>(o.poses));
  for (int k = 0; k < o.poses; ++k) {
    rows[k].pose = k;
    rows[k].noise_sigma = o.noise_sigmas[static_cast<std::size_t>(k) % o.noise_sigmas.size()];
    for (int i = 0; i < 6; ++i) rows[k].offset[i] = std::uniform_real_distribution<double>(-range[i], range[i])(rng);
  }
  return rows;
}

// The truth of one frame in pattern terms.
struct FrameTruth {
  const std::vector<sim::SpotTruth>& spots;
  int rows, cols;
  const sim::SpotTruth& at(int r, int c) const { return spots[static_cast<std::size_t>(r) * cols + c]; }
  // the spots covered by a 3 x 3 window all of whose spots pass `seen`
  // (with `one_object`, all nine on the object of the first)
  template <typename Seen>
  std::vector<char> in_full_window(Seen seen, bool one_object = false) const {
    std::vector<char> covered(spots.size(), 0);
    for (int r0 = 0; r0 + 3 <= rows; ++r0)
      for (int c0 = 0; c0 + 3 <= cols; ++c0) {
        bool all = true;
        for (int i = 0; i < 9 && all; ++i)
          all = seen(at(r0 + i / 3, c0 + i % 3)) && (!one_object || at(r0 + i / 3, c0 + i % 3).object == at(r0, c0).object);
        if (!all) continue;
        for (int i = 0; i < 9; ++i) covered[static_cast<std::size_t>(r0 + i / 3) * cols + c0 + i % 3] = 1;
      }
    return covered;
  }
};

// Each visible spot whose disc in the image no other visible spot's overlaps: their centres
// at least the two discs' radii apart (a disc's radius: its farthest rim hit on its object).
std::vector<char> apart_in_image(const std::vector<sim::SpotTruth>& spots) {
  std::vector<double> radius(spots.size(), 0);
  for (std::size_t i = 0; i < spots.size(); ++i)
    for (const auto& p : spots[i].footprint_px) radius[i] = std::max(radius[i], (p - spots[i].uv).norm());
  std::vector<std::size_t> visible;
  for (std::size_t i = 0; i < spots.size(); ++i)
    if (spots[i].visible) visible.push_back(i);
  std::vector<char> apart(spots.size(), 0);
  for (const std::size_t i : visible) {
    apart[i] = 1;
    for (std::size_t k = 0; k < visible.size() && apart[i]; ++k) {
      const std::size_t j = visible[k];
      if (j != i && (spots[j].uv - spots[i].uv).norm() < radius[i] + radius[j]) apart[i] = 0;
    }
  }
  return apart;
}

// Inside (or within kPartialPx of) the outline of the named spot's light: a blob cut by an
// edge has its centroid inside the footprint, far from the centre and the rim.
bool on_named_light(const sim::SpotTruth& named, double u, double v) {
  if (named.light_px.empty()) return false;
  std::vector<cv::Point2f> pts, hull;
  for (const auto& p : named.light_px) pts.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(pts, hull);
  return cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(u), static_cast<float>(v)), true) >= -kPartialPx;
}

// What the servo teaches at the desired pose: the ids of s* (per pattern spot) and, with
// SweepOptions::taught_points, the servo's own pipeline taught there, holding them to their points.
struct Taught {
  std::vector<char> ids;
  std::unique_ptr<servo::ServoPipeline> holding;
};

// Each decoded id against the truth: right, right but mislocated, a partial blob, or wrong;
// and whether it reaches the law (on its line, its id taught, not held out by its taught point:
// `off_taught` per decoded id, or empty).
// Returns which spots were named right; the wrong ones and the spills are appended to `listed`.
std::vector<char> score_ids(SweepRow& row, const vision::DecodeResult& r, const FrameTruth& truth, double tolerance_px,
                            const Taught& taught, const std::vector<char>& off_taught, Listed& listed) {
  std::vector<char> right(truth.spots.size(), 0), named(truth.spots.size(), 0);
  const auto at = [&](int id_row, int id_col) { return static_cast<std::size_t>(id_row) * truth.cols + id_col; };
  for (const auto& d : r.decoded) named[at(d.row, d.col)] = 1;
  const auto interior = [&](int id_row, int id_col) {
    for (const auto& [dr, dc] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
      const int rr = id_row + dr, cc = id_col + dc;
      if (rr < 0 || cc < 0 || rr >= truth.rows || cc >= truth.cols || !named[at(rr, cc)]) return false;
    }
    return true;
  };
  for (std::size_t k = 0; k < r.decoded.size(); ++k) {
    const vision::DecodedSpot& d = r.decoded[k];
    const bool held = !off_taught.empty() && off_taught[k];
    const bool to_law = !d.apart() && taught.ids[at(d.row, d.col)] && !held;
    row.to_law += to_law;
    row.off_taught += held;
    const sim::SpotTruth* nearest = nullptr;
    double best = 1e18;
    for (const auto& t : truth.spots) {
      if (!t.visible) continue;
      const double dist = std::hypot(t.uv.x() - d.u, t.uv.y() - d.v);
      if (dist < best) best = dist, nearest = &t;
    }
    const sim::SpotTruth& named_spot = truth.at(d.row, d.col);
    const bool nearest_is_named = nearest && nearest->row == d.row && nearest->col == d.col;
    row.off_line += d.off_line;
    if (!nearest_is_named && on_named_light(named_spot, d.u, d.v)) {
      ++row.partial;
      row.partial_interior += interior(d.row, d.col);
      row.off_line_partial += d.off_line;
      row.to_law_partial += to_law;
      row.off_taught_partial += held;
      listed.spills.push_back({row.pose, d.row, d.col, d.u, d.v, named_spot.uv.x(), named_spot.uv.y(),
                               named_spot.visible, static_cast<int>(d.by), d.off_line, to_law, held});
    } else if (!nearest_is_named) {
      ++row.wrong;
      row.off_line_wrong += d.off_line;
      row.to_law_wrong += to_law;
      row.off_taught_wrong += held;
      listed.wrong.push_back({row.pose, d.row, d.col, d.u, d.v, nearest ? nearest->row : -1,
                              nearest ? nearest->col : -1, nearest ? best : -1, named_spot.visible,
                              std::hypot(named_spot.uv.x() - d.u, named_spot.uv.y() - d.v), static_cast<int>(d.by)});
    } else if (best > tolerance_px) {
      ++row.mislocated;
      row.off_line_mislocated += d.off_line;
      row.to_law_mislocated += to_law;
      row.off_taught_mislocated += held;
    } else {
      ++row.correct;
      row.off_line_right += d.off_line;
      row.to_law_right += to_law;
      row.off_taught_right += held;
      right[at(d.row, d.col)] = 1;
    }
  }
  return right;
}

static_assert(kLostNearerBlob - kLostUnlikeClaim ==
                  static_cast<int>(vision::GrowthOutcome::kNearerBlob) - static_cast<int>(vision::GrowthOutcome::kUnlikeClaim),
              "LossCause lists step 6's refusals in GrowthOutcome's order");

// Why each readable spot segmented as blob `blob_of[i]` has no right id (LossCause).
void count_losses(SweepRow& row, const vision::DecodeResult& r, const FrameTruth& truth, const std::vector<char>& readable,
                  const std::vector<char>& right, const std::vector<int>& blob_of) {
  using vision::GrowthOutcome;
  std::vector<char> named(r.detected.size(), 0), identified(truth.spots.size(), 0);
  for (const auto& d : r.decoded) {
    named[static_cast<std::size_t>(d.spot)] = 1;
    identified[static_cast<std::size_t>(d.row) * truth.cols + d.col] = 1;
  }
  const auto alone = [&](int i) {  // no identified spot among its 8 pattern neighbours
    const int pr = i / truth.cols, pc = i % truth.cols;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = pr + dr, cc = pc + dc;
        if ((dr != 0 || dc != 0) && rr >= 0 && cc >= 0 && rr < truth.rows && cc < truth.cols &&
            identified[static_cast<std::size_t>(rr) * truth.cols + cc])
          return false;
      }
    return true;
  };
  for (std::size_t i = 0; i < truth.spots.size(); ++i) {
    const int b = blob_of[i];
    if (!readable[i] || b < 0 || right[i]) continue;
    LossCause cause = kLostUnclaimed;
    if (named[b]) cause = kLostOtherId;
    else if (r.detected[b].truncated) cause = kLostBorder;
    else if (r.growth.size() != r.detected.size()) cause = kLostNoGrowth;
    else if (const GrowthOutcome g = r.growth[b]; g == GrowthOutcome::kNamed) cause = kLostDropped;
    else if (g >= GrowthOutcome::kUnlikeClaim && g <= GrowthOutcome::kNearerBlob)  // the refusals, in order
      cause = static_cast<LossCause>(kLostUnlikeClaim + (static_cast<int>(g) - static_cast<int>(GrowthOutcome::kUnlikeClaim)));
    else if (alone(static_cast<int>(i))) cause = kLostAlone;
    ++row.lost[cause];
  }
}

// Where the readable spots are lost: segmented as a blob of their colour, all four links
// right, the whole window right after the graph check; and why a segmented one has no id.
void loss_funnel(SweepRow& row, const vision::DecodeResult& r, const FrameTruth& truth, const pattern::MArray& pattern,
                 const std::vector<char>& readable, const std::vector<char>& right, double tolerance_px) {
  const int cols = truth.cols, rows_n = truth.rows;
  // each detected blob's true id (the visible spot within the tolerance)
  std::vector<int> blob_of(truth.spots.size(), -1);
  for (std::size_t b = 0; b < r.detected.size(); ++b) {
    double best = tolerance_px;
    int id = -1;
    for (std::size_t i = 0; i < truth.spots.size(); ++i) {
      if (!truth.spots[i].visible) continue;
      const double dist = std::hypot(truth.spots[i].uv.x() - r.detected[b].u, truth.spots[i].uv.y() - r.detected[b].v);
      if (dist < best) best = dist, id = static_cast<int>(i);
    }
    if (id >= 0 && pattern.at(id / cols, id % cols) == r.detected[b].colour) blob_of[id] = static_cast<int>(b);
  }
  const auto truth_blob = [&](int rr, int cc) {
    return rr < 0 || cc < 0 || rr >= rows_n || cc >= cols ? -2 : blob_of[static_cast<std::size_t>(rr) * cols + cc];
  };
  for (std::size_t i = 0; i < truth.spots.size(); ++i) {
    if (!readable[i] || blob_of[i] < 0) continue;
    ++row.readable_segmented;
    const int pr = static_cast<int>(i) / cols, pc = static_cast<int>(i) % cols;
    // image directions against pattern directions: east = +col, south = +row
    const int dr[4] = {0, 1, 0, -1}, dc[4] = {1, 0, -1, 0};
    bool linked = true;
    for (int k = 0; k < 4 && linked; ++k) {
      const int want = truth_blob(pr + dr[k], pc + dc[k]);
      if (want != -2) linked = r.graph.next[blob_of[i]][k] == want && want >= 0;
    }
    row.readable_linked += linked;
    bool windowed = true;
    for (int w = 0; w < 9 && windowed; ++w) {
      const int want = truth_blob(pr + w / 3 - 1, pc + w % 3 - 1);
      if (want != -2) windowed = r.hoods.window[blob_of[i]][w] == want && want >= 0;
    }
    row.readable_windowed += windowed;
  }
  count_losses(row, r, truth, readable, right, blob_of);
}

// The rows' totals and mean rates, and the decode time's median and 99th percentile.
SweepSummary summarize(const std::vector<SweepRow>& rows) {
  SweepSummary s;
  s.rows = rows;
  std::vector<double> ms;
  double rate_sum = 0, decodable_rate_sum = 0, readable_rate_sum = 0, one_object_rate_sum = 0, apart_rate_sum = 0;
  int rated = 0, rated_decodable = 0, rated_readable = 0, rated_one_object = 0, rated_apart = 0;
  for (const auto& r : rows) {
    s.total_decodable += r.decodable;
    s.total_correct += r.correct;
    s.total_correct_decodable += r.correct_decodable;
    s.total_resolved += r.resolved;
    s.total_readable += r.readable;
    s.total_correct_readable += r.correct_readable;
    s.total_readable_segmented += r.readable_segmented;
    s.total_readable_linked += r.readable_linked;
    s.total_readable_windowed += r.readable_windowed;
    for (int c = 0; c < kLossCauses; ++c) s.total_lost[c] += r.lost[c];
    if (r.readable > 0) {
      readable_rate_sum += static_cast<double>(r.correct_readable) / r.readable;
      ++rated_readable;
    }
    s.total_readable_apart += r.readable_apart;
    s.total_correct_readable_apart += r.correct_readable_apart;
    if (r.readable_apart > 0) {
      apart_rate_sum += static_cast<double>(r.correct_readable_apart) / r.readable_apart;
      ++rated_apart;
    }
    s.total_readable_one_object += r.readable_one_object;
    s.total_correct_readable_one_object += r.correct_readable_one_object;
    if (r.readable_one_object > 0) {
      one_object_rate_sum += static_cast<double>(r.correct_readable_one_object) / r.readable_one_object;
      ++rated_one_object;
    }
    if (r.decodable > 0) {
      decodable_rate_sum += static_cast<double>(r.correct_decodable) / r.decodable;
      ++rated_decodable;
    }
    s.total_decoded += r.decoded;
    s.total_wrong += r.wrong;
    s.total_mislocated += r.mislocated;
    s.total_partial += r.partial;
    s.total_partial_interior += r.partial_interior;
    s.total_off_line += r.off_line;
    s.total_off_line_right += r.off_line_right;
    s.total_off_line_mislocated += r.off_line_mislocated;
    s.total_off_line_partial += r.off_line_partial;
    s.total_off_line_wrong += r.off_line_wrong;
    s.total_to_law += r.to_law;
    s.total_to_law_right += r.to_law_right;
    s.total_to_law_mislocated += r.to_law_mislocated;
    s.total_to_law_partial += r.to_law_partial;
    s.total_to_law_wrong += r.to_law_wrong;
    s.total_off_taught += r.off_taught;
    s.total_off_taught_right += r.off_taught_right;
    s.total_off_taught_mislocated += r.off_taught_mislocated;
    s.total_off_taught_partial += r.off_taught_partial;
    s.total_off_taught_wrong += r.off_taught_wrong;
    s.total_visible += r.visible;
    ms.push_back(r.decode_ms);
    if (r.visible > 0) {
      const double rate = static_cast<double>(r.correct) / r.visible;
      rate_sum += rate;
      s.min_rate = std::min(s.min_rate, rate);
      ++rated;
    }
  }
  s.mean_rate = rated ? rate_sum / rated : 0;
  s.mean_decodable_rate = rated_decodable ? decodable_rate_sum / rated_decodable : 0;
  s.mean_readable_rate = rated_readable ? readable_rate_sum / rated_readable : 0;
  s.mean_readable_one_object_rate = rated_one_object ? one_object_rate_sum / rated_one_object : 0;
  s.mean_readable_apart_rate = rated_apart ? apart_rate_sum / rated_apart : 0;
  std::sort(ms.begin(), ms.end());
  if (!ms.empty()) {
    s.median_ms = ms[ms.size() / 2];
    s.p99_ms = ms[std::min(ms.size() - 1, ms.size() * 99 / 100)];
  }
  return s;
}

// A file's rows in pose and id order, whichever thread found them.
template <typename Row>
void by_pose_and_id(std::vector<Row>& rows) {
  std::sort(rows.begin(), rows.end(),
            [](const Row& a, const Row& b) { return std::tie(a.pose, a.row, a.col) < std::tie(b.pose, b.row, b.col); });
}

// A list of ids to look at, one row each in pose and id order: `header`, then `row` writes each.
template <typename Row, typename WriteRow>
void write_listed(std::vector<Row> rows, const std::filesystem::path& file, const char* header, WriteRow row) {
  by_pose_and_id(rows);
  common::OutputStream w;
  w.open(file, "table");
  w << header << '\n';
  for (const Row& x : rows) {
    row(w, x);
    w << '\n';
  }
  w.close();
}

// every wrong id, to look at: what was named, what is there
void write_wrong_ids(std::vector<WrongId> wrong, const std::filesystem::path& file) {
  write_listed(std::move(wrong), file,
               "pose,row,col,u,v,nearest_visible_row,nearest_visible_col,nearest_visible_px,named_visible,named_px,step",
               [](std::ostream& w, const WrongId& x) {
                 w << x.pose << ',' << x.row << ',' << x.col << ',' << x.u << ',' << x.v << ',' << x.nearest_row << ','
                   << x.nearest_col << ',' << x.nearest_px << ',' << x.named_visible << ',' << x.named_px << ',' << x.step;
               });
}

// every id given to a spill, to look at: where it was named, where its spot's centre is
void write_spill_ids(std::vector<SpillId> spills, const std::filesystem::path& file) {
  write_listed(std::move(spills), file, "pose,row,col,u,v,centre_u,centre_v,centre_visible,step,off_line,to_law,off_taught",
               [](std::ostream& w, const SpillId& x) {
                 w << x.pose << ',' << x.row << ',' << x.col << ',' << x.u << ',' << x.v << ',' << x.centre_u << ','
                   << x.centre_v << ',' << x.centre_visible << ',' << x.step << ',' << x.off_line << ',' << x.to_law
                   << ',' << x.off_taught;
               });
}

void write_sweep_csv(const std::vector<SweepRow>& rows, const std::filesystem::path& file) {
  common::OutputStream csv;
  csv.open(file, "table");
  csv << "pose,noise_sigma,tx_cm,ty_cm,tz_cm,rx_deg,ry_deg,rz_deg,visible,detected,decoded,correct,wrong,mislocated,"
         "partial,partial_interior,"
         "decode_ms,decodable,correct_decodable,resolved,readable,correct_readable,readable_segmented,readable_linked,"
         "readable_windowed,readable_one_object,correct_readable_one_object,readable_apart,correct_readable_apart";
  for (const char* cause : kLossCauseNames) csv << ',' << cause;
  csv << ",off_line,off_line_right,off_line_mislocated,off_line_partial,off_line_wrong";
  csv << ",to_law,to_law_right,to_law_mislocated,to_law_partial,to_law_wrong";
  csv << ",off_taught,off_taught_right,off_taught_mislocated,off_taught_partial,off_taught_wrong\n";
  for (const auto& r : rows) {
    csv << r.pose << ',' << r.noise_sigma;
    for (double x : r.offset) csv << ',' << x;
    csv << ',' << r.visible << ',' << r.detected << ',' << r.decoded << ',' << r.correct << ',' << r.wrong << ','
        << r.mislocated << ',' << r.partial << ',' << r.partial_interior << ',' << r.decode_ms << ',' << r.decodable
        << ',' << r.correct_decodable << ',' << r.resolved << ',' << r.readable << ',' << r.correct_readable << ',' << r.readable_segmented << ','
        << r.readable_linked << ',' << r.readable_windowed << ',' << r.readable_one_object << ','
        << r.correct_readable_one_object << ',' << r.readable_apart << ',' << r.correct_readable_apart;
    for (const int n : r.lost) csv << ',' << n;
    csv << ',' << r.off_line << ',' << r.off_line_right << ',' << r.off_line_mislocated << ',' << r.off_line_partial << ','
        << r.off_line_wrong;
    csv << ',' << r.to_law << ',' << r.to_law_right << ',' << r.to_law_mislocated << ',' << r.to_law_partial << ','
        << r.to_law_wrong;
    csv << ',' << r.off_taught << ',' << r.off_taught_right << ',' << r.off_taught_mislocated << ','
        << r.off_taught_partial << ',' << r.off_taught_wrong << '\n';
  }
  csv.close();
}

// the first frames with a wrong id, drawn and as rendered (to decode again; with its white
// frame, `servo decode FRAME --white WHITE`)
void write_failure_images(const cv::Mat& img, const cv::Mat& white, const vision::DecodeResult& r, int pose,
                          const std::filesystem::path& dir) {
  const std::string stem = (dir / ("wrong_pose_" + std::to_string(pose))).string();
  cv::Mat bgr;
  cv::cvtColor(vision::draw_overlay(img, r), bgr, cv::COLOR_RGB2BGR);
  common::write_output_image(stem + ".png", bgr);
  cv::cvtColor(img, bgr, cv::COLOR_RGB2BGR);
  common::write_output_image(stem + "_frame.png", bgr);
  if (white.empty()) return;
  cv::cvtColor(white, bgr, cv::COLOR_RGB2BGR);
  common::write_output_image(stem + "_white.png", bgr);
}

// What the camera takes at a pose: the pattern frame and, with SweepOptions::white_frame, the
// white reference frame beside it (its own noise draw).
struct Shot {
  cv::Mat pattern, white;
};

Shot take(const sim::Cell& cell, const Eigen::Isometry3d& world_T_camera, std::uint64_t seed, sim::RenderScratch* scratch,
          const sim::CameraSpec* sensor, bool white_frame) {
  Shot shot;
  shot.pattern = sim::render_image(cell, world_T_camera, seed, scratch, sensor);
  if (white_frame)
    shot.white = sim::render_image(cell, world_T_camera, sim::white_frame_seed(seed), scratch, sensor, nullptr,
                                   sim::Cast::kWhite);
  return shot;
}

// A frame decoded as the sweep decodes: the pattern frame, or its ratio to the white frame;
// with the calibration's lines at the camera's pose, or without them (the lines fitted to the
// frame's own spots mark the ids off them).
vision::DecodeResult decode_frame(const vision::SpotDecoder& decoder, const Shot& shot, const SweepOptions& o,
                                  const calibration::CameraIntrinsics& camera, const Eigen::Isometry3d& world_T_camera,
                                  vision::DecodeScratch* scratch = nullptr) {
  if (!o.projector) return decoder.decode_uncalibrated(shot.pattern, shot.white, camera, scratch);
  const vision::EpipolarGeometry geometry(camera, *o.projector, world_T_camera, o.decoder.epipolar.tolerance_px);
  return decoder.decode(shot.pattern, shot.white, &geometry, scratch);
}

// A frame's ids as the servo locates them (ServoPipeline::locate's output).
std::vector<servo::ImageSpot> image_spots(const vision::DecodeResult& r) {
  std::vector<servo::ImageSpot> out;
  out.reserve(r.decoded.size());
  for (const vision::DecodedSpot& d : r.decoded) out.push_back(servo::image_spot(d));
  return out;
}

// What the servo teaches at the scenario's desired pose: the ids it names there on their lines
// (the frame rendered with the scenario camera's own noise) and, asked for, their points.
Taught teach(const sim::Cell& cell, const SweepOptions& o, const vision::DecoderOptions& decoder_options,
             const calibration::CameraIntrinsics& camera) {
  const sim::Scenario& sc = cell.scenario;
  const pattern::MArray& pattern = cell.projector->pattern();
  sim::RenderScratch scratch;
  const Shot shot = take(cell, sc.world_T_desired, sim::frame_seed(o.seed ^ 0x7465616368ull, 0), &scratch, nullptr,
                         o.white_frame);
  const vision::SpotDecoder decoder(pattern::WindowTable(pattern, {3, 3}), decoder_options);
  const vision::DecodeResult r = decode_frame(decoder, shot, o, camera, sc.world_T_desired);
  Taught t;
  t.ids.assign(static_cast<std::size_t>(pattern.rows) * pattern.cols, 0);
  for (const vision::DecodedSpot& d : r.decoded)
    if (!d.apart()) t.ids[static_cast<std::size_t>(d.row) * pattern.cols + d.col] = 1;
  if (o.projector && o.taught_points) {
    servo::ServoConfig config;
    config.decoder = decoder_options;
    config.camera = camera;
    config.projector = *o.projector;
    config.taught_points = true;
    t.holding = std::make_unique<servo::ServoPipeline>(pattern::WindowTable(pattern, {3, 3}), config);
    t.holding->teach(image_spots(r), sc.world_T_desired);
  }
  return t;
}

// Which of a frame's ids the servo holds out by their taught points (per r.decoded; empty: none).
std::vector<char> held_by_taught_points(const vision::DecodeResult& r, const Taught& taught,
                                        const Eigen::Isometry3d& world_T_camera) {
  if (!taught.holding) return {};
  // the servo's features are its ids on their lines, in order
  const std::vector<control::Feature> f = taught.holding->features(image_spots(r), world_T_camera);
  const servo::TaughtCheck c = taught.holding->hold_to_taught(f, world_T_camera);
  std::vector<char> off(r.decoded.size(), 0);
  std::size_t i = 0;
  for (std::size_t k = 0; k < r.decoded.size(); ++k)
    if (!r.decoded[k].apart()) off[k] = c.off[i++];
  return off;
}

// Which spots a frame could show decoded: decodable, covered by a fully visible 3 x 3 window;
// readable, by a fully resolved one (one_object: all on one object); apart in the image.
struct Coverage {
  std::vector<char> decodable, readable, one_object, apart;
};
Coverage coverage_of(const FrameTruth& truth) {
  return {truth.in_full_window([](const sim::SpotTruth& t) { return t.visible; }),
          truth.in_full_window([](const sim::SpotTruth& t) { return t.resolved; }),
          truth.in_full_window([](const sim::SpotTruth& t) { return t.resolved; }, true), apart_in_image(truth.spots)};
}

// The frame's visible, resolved, decodable and readable spots, and those of them named right.
void count_rates(SweepRow& row, const FrameTruth& truth, const Coverage& c, const std::vector<char>& right) {
  for (std::size_t i = 0; i < truth.spots.size(); ++i) {
    row.visible += truth.spots[i].visible;
    row.resolved += truth.spots[i].resolved;
    row.decodable += c.decodable[i];
    row.correct_decodable += c.decodable[i] && right[i];
    row.readable += c.readable[i];
    row.correct_readable += c.readable[i] && right[i];
    row.readable_one_object += c.one_object[i];
    row.correct_readable_one_object += c.one_object[i] && right[i];
    row.readable_apart += c.readable[i] && c.apart[i];
    row.correct_readable_apart += c.readable[i] && c.apart[i] && right[i];
  }
}

}  // namespace

SweepSummary run_decode_sweep(const sim::Cell& cell, const SweepOptions& o) {
  const sim::Scenario& sc = cell.scenario;
  if (!o.out_dir.empty()) {
    common::make_output_folder(o.out_dir);
    for (const char* table : {"wrong_ids.csv", "spills.csv", "sweep.csv"}) common::check_output_file(o.out_dir / table, "table");
  }
  std::vector<SweepRow> rows = draw_rows(sc, o);
  const calibration::CameraIntrinsics camera = camera_intrinsics_of(cell);
  // the decoder is told the camera's colour crosstalk as it is told its intrinsics
  vision::DecoderOptions decoder_options = o.decoder;
  decoder_options.segmentation.crosstalk = o.told_crosstalk.value_or(sc.camera.crosstalk);
  const pattern::MArray& pattern = cell.projector->pattern();
  const Taught taught = teach(cell, o, decoder_options, camera);
  std::atomic<int> next{0}, done{0};
  std::mutex io;
  common::Progress progress("decode-sweep " + sc.name, static_cast<std::size_t>(o.poses), "poses");
  std::vector<WrongId> wrong_ids;
  std::vector<SpillId> spill_ids;
  int failure_images = 0;
  std::exception_ptr image_error;  // a failure image refused: said once the tables are written
  const auto work = [&] {
    sim::RenderScratch scratch;
    scratch.threads = 1;  // the sweep's own threads share the cores
    // a decoder per thread (decoding holds no state, but the table is cheap to own), and the
    // decoder's room, reused from pose to pose as the servo reuses it from frame to frame
    const vision::SpotDecoder decoder(pattern::WindowTable(pattern, {3, 3}), decoder_options);
    vision::DecodeScratch decode_scratch;
    Listed listed;
    for (int k; (k = next++) < o.poses;) {
      SweepRow& row = rows[k];
      const Eigen::Isometry3d wTc = sim::offset_pose(sc.world_T_desired, {row.offset[0], row.offset[1], row.offset[2]},
                                                     {row.offset[3], row.offset[4], row.offset[5]},
                                                     sc.offset_frame_rotation_deg);
      sim::CameraSpec sensor = sc.camera;
      sensor.noise_sigma = row.noise_sigma;
      const Shot shot = take(cell, wTc, sim::frame_seed(o.seed, static_cast<std::uint64_t>(k)), &scratch, &sensor,
                             o.white_frame);
      const auto spots = sim::compute_truth(cell, wTc);
      const auto t0 = std::chrono::steady_clock::now();
      const vision::DecodeResult r = decode_frame(decoder, shot, o, camera, wTc, &decode_scratch);
      row.decode_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

      const FrameTruth truth{spots, pattern.rows, pattern.cols};
      const Coverage covered = coverage_of(truth);
      row.detected = static_cast<int>(r.detected.size());
      row.decoded = static_cast<int>(r.decoded.size());
      listed.wrong.clear(), listed.spills.clear();
      const std::vector<char> held = held_by_taught_points(r, taught, wTc);
      const std::vector<char> right = score_ids(row, r, truth, o.match_tolerance_px, taught, held, listed);
      loss_funnel(row, r, truth, pattern, covered.readable, right, o.match_tolerance_px);
      count_rates(row, truth, covered, right);
      progress.at(static_cast<std::size_t>(++done));
      if (row.wrong == 0 && listed.spills.empty()) continue;
      std::lock_guard<std::mutex> lock(io);
      spill_ids.insert(spill_ids.end(), listed.spills.begin(), listed.spills.end());
      if (row.wrong == 0) continue;
      wrong_ids.insert(wrong_ids.end(), listed.wrong.begin(), listed.wrong.end());
      if (o.out_dir.empty() || image_error || failure_images++ >= 20) continue;
      try {
        write_failure_images(shot.pattern, shot.white, r, k, o.out_dir);
      } catch (...) {
        image_error = std::current_exception();  // not thrown across the thread
      }
    }
  };
  // a pose that throws stops the others from taking one, and is rethrown here
  common::run_workers(o.threads, work, [&] { next = o.poses; });

  SweepSummary s = summarize(rows);
  s.taught = static_cast<int>(std::count(taught.ids.begin(), taught.ids.end(), 1));
  if (!o.out_dir.empty()) {
    write_wrong_ids(wrong_ids, o.out_dir / "wrong_ids.csv");
    write_spill_ids(spill_ids, o.out_dir / "spills.csv");
    write_sweep_csv(rows, o.out_dir / "sweep.csv");
  }
  if (image_error) std::rethrow_exception(image_error);
  return s;
}

}  // namespace experiment
