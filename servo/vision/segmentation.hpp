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

struct SegmentationOptions {
  int colours = 3;             // symbols 0..k-1, coloured as pattern::kPalette
  // chroma floor (8-bit), above the sensor noise: where a spot's pixels end
  int min_threshold = 10;
  // and the chroma a blob must reach somewhere to be a spot: a dim spot (a dark or printed
  // surface, crosstalk) keeps its whole extent down to the floor, while the wash of the far
  // wall's defocused spots, whose peaks hardly clear the floor, makes no blob (issue 41)
  int min_peak = 14;
  // The camera's channel crosstalk, as calibrated: the fraction of each colour channel that
  // leaks into each of the others (a real camera's is measured once, each primary cast on a
  // white card). A primary's light I reads (1 - 2x) I in its own channel and x I in the others,
  // so its chroma is (1 - 3x) I: the floor and the peak above were set on images at 0.06 (the
  // simulator's camera) and are scaled by (1 - 3x) / (1 - 3 x 0.06), so that a camera with more
  // crosstalk keeps the spots a clean one keeps. Not a tuning number: at 0.06 nothing changes.
  // In [0, 0.3] (at 1/3 a primary has no chroma left). The decoder scales them only when it
  // has the projector's calibration (SpotDecoder::decode says why).
  double crosstalk = 0.06;
  double noise_floor_factor = 3.0;  // and at least this times the image's median chroma
  // a noisy image (one whose noise would set the floor above min_peak) averaged over 3 x 3
  // pixels first: a spot covers tens of pixels and the sensor's noise is independent from pixel
  // to pixel, so the average keeps the spots and divides the noise's spread by 3, and the floor
  // falls with it. Not a quiet one: the average also closes the 1-2 px gaps between the spots
  // seen edge-on at a silhouette (issue 41). The image's own spots, at its own floor, that touch
  // none of the average's are kept too: the average dims a spot seen edge-on, 1-2 px wide, under
  // the level its brighter neighbours set
  bool smoothing = true;
  // Not an image divided by its white reference frame (SpotDecoder::segment): the division
  // multiplies each pixel's noise by the inverse of its albedo, so the image's own floor, one
  // for the whole image, does not hold the noise of its dark parts (a printed label's ink),
  // where only the average does
  bool own_spots = true;
  int local_window_px = 11;    // neighbourhood whose peak sets the local level (~ a spot's size)
  double peak_ratio = 0.4;     // local level = this fraction of the local peak
  int min_area_px = 4;
  int max_area_px = 2500;
  double max_elongation = 6.0;   // bounding-box aspect ratio (curved surfaces stretch spots)
  // Beyond it a sliver (Spot::sliver), listed after the spots: at a silhouette the surface turns
  // away and the last line of spots is seen edge-on, 1-2 px wide. No ceiling: only the edge runs
  // use slivers, and they ask the pattern's colour, the place and the line of each; one of 12
  // bounded nothing (the same wrong ids in 72 calibrated tuning sweeps of 400 poses and 144 of
  // 1000 at seeds 7 and 11 wide, 110 ids more of 35 million).
  double min_fill = 0.25;        // area / bounding-box area
  double min_colour_match = 0.85;  // cosine between the blob's chroma and its palette colour
  // A blob touching the image border is cut (Spot::truncated: it helps decode its neighbours,
  // its centroid is not reported) when it reaches less far from its centroid towards the border
  // than away from it, by more than border_cut_px, or less than border_reach_px towards it (a
  // spot's half-width's worth: a sliver whose centre lies beyond the border reaches as far both
  // ways). Pixels.
  double border_cut_px = 0.5, border_reach_px = 1.5;
};

// the crosstalk of the images SegmentationOptions' chroma levels were set on, and the most a
// camera may have (at 1/3 a primary's chroma is gone)
inline constexpr double kLevelsCrosstalk = 0.06, kMaxCrosstalk = 0.3;

// The options with the chroma floor and peak scaled to the camera's crosstalk (the same at
// kLevelsCrosstalk). Throws std::invalid_argument when the crosstalk is outside [0, kMaxCrosstalk].
SegmentationOptions at_crosstalk(const SegmentationOptions& given);

struct Segmentation {
  std::vector<Spot> spots;  // the slivers last
  int threshold = 0;
  int rejected = 0;  // blobs that were not spots (size, shape, colour)
};

// Per-frame buffers, reused from call to call when the caller keeps one (allocating and
// first-touching ~4 MB of images per frame costs as much as half the segmentation).
struct SegmentationScratch {
  cv::Mat smooth, lo, chroma, peak, mask;  // peak: the brightest chroma around each pixel
  // a noisy image's: the pixels of the average's spots, and its own chroma and smallest channel
  // while the average's are read
  cv::Mat covered, own_chroma, own_lo;
  struct RowRun {
    int v, xl, xr;
  };
  std::vector<RowRun> row_runs;
  std::vector<int> row_start, parent, blob_of;
  std::vector<std::uint16_t> box_rows;
};

// The 3 x 3 mean of an RGB8 image, each channel apart, its border replicated, rounded to the
// nearest (SegmentationOptions::smoothing). `ring`: room it reuses.
void mean_3x3(const cv::Mat& rgb, cv::Mat& out, std::vector<std::uint16_t>& ring);

// Throws std::invalid_argument when the image is empty or not 8-bit, 3-channel.
Segmentation segment_spots(const cv::Mat& rgb, const SegmentationOptions& params = {},
                           SegmentationScratch* scratch = nullptr);

}  // namespace vision
