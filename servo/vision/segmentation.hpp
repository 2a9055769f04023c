// Pattern segmentation (paper §3.3): find the coloured spots in an RGB8 image.
//
// The projected spots are saturated primaries while the scene under ambient light is nearly
// grey, so the segmentation works on chroma (max - min channel), not brightness: a visible
// background scene or a darker object changes brightness, not chroma. A global threshold
// from the chroma histogram (Otsu, with a floor above the sensor noise) adapts to exposure.
#pragma once

#include <opencv2/core.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "servo/vision/spot.hpp"

namespace vision {

struct SegmentationParams {
  int colours = 3;             // symbols 0..k-1, coloured as pattern::kPalette
  int min_threshold = 14;      // chroma floor (8-bit), above the sensor noise
  double noise_floor_factor = 3.0;  // and at least this times the image's median chroma
  int local_window_px = 11;    // neighbourhood whose peak sets the local level (~ a spot's size)
  double peak_ratio = 0.4;     // local level = this fraction of the local peak
  int min_area_px = 4;
  int max_area_px = 2500;
  double max_elongation = 6.0;   // bounding-box aspect ratio (curved surfaces stretch spots)
  // up to this: a sliver (Spot::sliver), listed after the spots. At a silhouette the surface
  // turns away and the last line of spots is seen edge-on, 1-2 px wide.
  double max_sliver_elongation = 12.0;
  double min_fill = 0.25;        // area / bounding-box area
  double min_colour_match = 0.85;  // cosine between the blob's chroma and its palette colour
};

struct Segmentation {
  std::vector<Spot> spots;  // the slivers last
  int threshold = 0;
  int rejected = 0;  // blobs that were not spots (size, shape, colour)
};

// Per-frame buffers, reused from call to call when the caller keeps one (allocating and
// first-touching ~4 MB of images per frame costs as much as half the segmentation).
struct SegmentationScratch {
  cv::Mat lo, chroma, peak, mask;  // peak: the brightest chroma around each pixel
  struct RowRun {
    int v, xl, xr;
  };
  std::vector<RowRun> row_runs;
  std::vector<int> row_start, parent, blob_of;
};

// Throws std::invalid_argument when the image is empty or not 8-bit, 3-channel.
Segmentation segment_spots(const cv::Mat& rgb, const SegmentationParams& params = {},
                           SegmentationScratch* scratch = nullptr);

}  // namespace vision
