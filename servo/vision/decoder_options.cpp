#include "servo/vision/decoder_options.hpp"

#include <cmath>
#include <stdexcept>
#include <variant>

#include "common/decimal_number.hpp"

namespace vision {
namespace {

struct Field {
  const char* name;
  std::variant<double*, float*, int*> at;
  // the values it takes: [0, 1e9] but where a number sizes a buffer (the side of the window a
  // pixel's level is read in: 0 or 1e9 px would stop the segmentation; a run's length, 0-15 as
  // `--segment-length` takes it) or is an 8-bit level (a chroma floor past 255 would wrap)
  double least = 0, most = 1e9;
};

// (one table for names and setting: a number added to an options struct is added here once)
std::vector<Field> fields(DecoderOptions& o) {
  SegmentationOptions& s = o.segmentation;
  AdjacencyOptions& a = o.adjacency;
  EpipolarOptions& e = o.epipolar;
  GrowthOptions& g = e.growth;
  EdgeRunOptions& r = e.edge_run;
  return {{"segmentation.min_threshold", &s.min_threshold, 0, 255}, {"segmentation.min_peak", &s.min_peak, 0, 255},
          {"segmentation.noise_floor_factor", &s.noise_floor_factor, 0, 255}, {"segmentation.local_window_px", &s.local_window_px, 1, 255},
          {"segmentation.peak_ratio", &s.peak_ratio}, {"segmentation.min_area_px", &s.min_area_px},
          {"segmentation.max_area_px", &s.max_area_px}, {"segmentation.max_elongation", &s.max_elongation},
          {"segmentation.min_fill", &s.min_fill},
          {"segmentation.min_colour_match", &s.min_colour_match},
          {"segmentation.border_cut_px", &s.border_cut_px}, {"segmentation.border_reach_px", &s.border_reach_px},
          {"adjacency.row_cone_deg", &a.row_cone_deg}, {"adjacency.column_cone_deg", &a.column_cone_deg},
          {"adjacency.reach", &a.reach}, {"adjacency.angle_weight", &a.angle_weight},
          {"adjacency.chain_votes", &a.chain_votes}, {"adjacency.chain_share", &a.chain_share},
          {"adjacency.completion_slack", &a.completion_slack},
          {"cell_shape.bend", &o.cell_shape.bend}, {"cell_shape.cell_slack", &o.cell_shape.cell_slack},
          {"cell_shape.step_ratio", &o.cell_shape.step_ratio},
          {"min_votes", &o.min_votes}, {"min_island", &o.min_island}, {"fragment_area", &o.fragment_area},
          {"speck_area", &o.speck_area},
          {"epipolar.tolerance_px", &e.tolerance_px}, {"epipolar.min_island", &e.min_island},
          {"epipolar.min_sources", &e.min_sources}, {"epipolar.segment_length", &e.segment_length, 0, 15},
          {"grown_limit.times_median", &e.grown_limit.times_median}, {"grown_limit.floor_px", &e.grown_limit.floor_px},
          {"growth.slack", &g.slack}, {"growth.unlike", &g.unlike},
          {"growth.faintest", &g.faintest}, {"growth.tight_slack", &g.tight_slack},
          {"growth.on_line_stretch", &g.on_line_stretch}, {"growth.alike", &g.alike},
          {"edge_run.nearest", &r.nearest}, {"edge_run.aside", &r.aside},
          {"edge_run.length", &r.length}, {"edge_run.largest", &r.largest}, {"edge_run.gaps", &r.gaps},
          {"reference.full_level", &o.reference.full_level, 1, 255}};
}

}  // namespace

std::vector<std::string> decoder_option_names() {
  DecoderOptions scratch;
  std::vector<std::string> names;
  for (const Field& f : fields(scratch)) names.emplace_back(f.name);
  return names;
}

void set_decoder_option(DecoderOptions& options, const std::string& assignment) {
  const auto fail = [&](const std::string& why) {
    throw std::invalid_argument("--decoder-option '" + assignment.substr(0, 80) + "': " + why);
  };
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos) fail("expected NAME=VALUE");
  const std::string name = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  // a number as the command line reads every other (not strtod's "0x10", "inf" or " 1")
  const std::optional<double> parsed = common::decimal_number(text);
  if (!parsed || *parsed < 0 || *parsed > 1e9) fail("the value must be a decimal number in [0, 1e9]");
  const double value = *parsed;
  for (const Field& f : fields(options)) {
    if (name != f.name) continue;
    if (value < f.least || value > f.most)
      fail("the value must be in [" + std::to_string(static_cast<int>(f.least)) + ", " +
           std::to_string(static_cast<int>(f.most)) + "] for this one");
    if (int* const* i = std::get_if<int*>(&f.at)) {
      if (value != std::floor(value)) fail("the value of a count must be a whole number");
      **i = static_cast<int>(value);
    } else if (float* const* x = std::get_if<float*>(&f.at)) {
      **x = static_cast<float>(value);
    } else {
      *std::get<double*>(f.at) = value;
    }
    return;
  }
  fail("no such decoder option (cellsim decode-sweep --help lists them)");
}

}  // namespace vision
