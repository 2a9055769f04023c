// Spots as the decoder sees them: image blobs with a centroid and a colour label.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include "servo/pattern/window_table.hpp"

namespace vision {

struct Spot {
  double u = 0, v = 0;   // sub-pixel centre of gravity (pixels, pixel centres at integers)
  int colour = 0;        // pattern symbol (0 blue, 1 green, 2 red)
  int area_px = 0;
  float strength = 0;    // mean chroma above the threshold
  bool truncated = false;  // cut by the image border: its centroid is biased
  // narrower than a spot may be (SegmentationOptions::max_elongation): a spot seen edge-on
  // beside a silhouette. Only the edge runs (decoder step 7) use slivers.
  bool sliver = false;
};

// Which decoder step named a spot (spot_decoder.hpp numbers the steps): the evidence behind
// an id, from the strongest (the windows of the paper) to the weakest (a run along an edge).
enum class NamedBy : unsigned char { kWindows = 0, kLattice = 6, kEdgeRun = 7 };

// A decoded spot: its identity in the pattern and where it is in the image.
struct DecodedSpot {
  int row = 0, col = 0;
  double u = 0, v = 0;
  int spot = 0;  // index into the segmented spots
  NamedBy by = NamedBy::kWindows;
  // Its centroid lies farther from its id's epipolar line than the frame's grown limit
  // (EpipolarCheck::grown_limit_px): the calibration's line, or without it the line fitted to
  // the frame's own spots (mark_off_fitted_lines). The id is right, but the blob is not where
  // the spot's centre is: its light past a silhouette on the surface behind, or a spot split by
  // a depth edge. It is reported, and kept out of the control law.
  bool off_line = false;
  // Named by the grown lattice (step 6) on a blob smaller than GrowthOptions::unlike of its
  // sources' mean area: the id's footprint clipped by an edge, its light a part of the spot's
  // (the box's spot cut by its edge on the projector's side, whose part that passes lights the
  // table where the table's lattice puts the id). The id is right and reported, but the blob's
  // centroid is not the spot's centre: kept out of the control law, as an off-line spot is.
  bool clipped = false;
  // no feature of the control law: the servo keeps it apart
  bool apart() const { return off_line || clipped; }
};

// The four main directions of the adjacency graph, in image terms (rows grow downwards).
enum Direction { kEast = 0, kSouth = 1, kWest = 2, kNorth = 3 };

// For every spot, the closest spot in each main direction (index, or -1).
struct AdjacencyGraph {
  std::vector<std::array<int, 4>> next;
  double grid_angle_rad = 0;  // the pattern's east direction in the image
};

// The 8-neighbourhood of every spot in window order:
// 0 NW, 1 N, 2 NE, 3 W, 4 (the spot itself), 5 E, 6 SW, 7 S, 8 SE; -1 when missing.
using Window = std::array<int, 9>;
struct Neighbourhoods {
  std::vector<Window> window;
};

}  // namespace vision
