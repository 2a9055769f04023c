// Albedo normalisation against a white reference frame (issue 41: features "independently of
// the object appearance").
//
// A surface returns each channel of the light scaled by its albedo in that channel: a spot on a
// dark, coloured or printed surface is dimmer, and under a label's ink it may fall below the
// segmentation's chroma levels or take the ink's hue. A real cell can take, beside each pattern
// frame, a frame with the projector casting white over the pattern's extent: the same surface
// lit as the spots light it, channel by channel. Their ratio, pixel by pixel and channel by
// channel, is the light the projector put there whatever the albedo: a spot reads as its primary
// and the surface between the spots at the ambient light's share, on a white wall or under
// black ink. The segmentation runs on the ratio as on any frame (SpotDecoder::decode with a
// white frame; servo decode --white, cellsim decode-sweep --white-frame).
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "servo/vision/spot.hpp"

namespace vision {

struct ReferenceOptions {
  // The white frame's level (8-bit, its 3 x 3 mean) at and above which the ratio divides the
  // surface out exactly; below it the pattern frame is divided by this level instead, so the
  // gain is at most 255 / full_level. Where the white frame is dim (a shadow, the ambient light
  // alone beyond the pattern, a dark face at grazing light) the ratio of two noisy levels is
  // noise, and beyond the pattern it covers most of a frame: amplified 16 times at 16, it
  // raised the segmentation's noise floor over the spots (the plane under crosstalk 0.2 lost
  // 17 points). Set on the tuning scenes (docs/decoding.md, Appearance: 16, 32 and 64 tried).
  int full_level = 32;
};

// `out` (RGB8, the pattern frame's size): 255 x pattern / max(white, full_level) per channel,
// rounded, at most 255, where `white` is the white frame's 3 x 3 mean: the white frame's own
// noise averaged out, as the surface it shows is smooth but at its edges (taken as it is, under
// noise sigma 12 it added two wrong window readings on the can). `white_mean`: room for that
// mean, reused when given. Throws std::invalid_argument when either image is empty or not RGB8,
// their sizes differ, or full_level is outside [1, 255].
void normalise_by_white(const cv::Mat& pattern_rgb, const cv::Mat& white_rgb, cv::Mat& out,
                        const ReferenceOptions& options = {}, cv::Mat* white_mean = nullptr);

// Each spot segmented on the ratio given the strength the pattern frame shows it with: its
// strength on the ratio times the white frame's level in its colour's channels at its centroid
// (over 3 x 3 pixels, at least full_level) / 255. The decoder's likeness tests compare a spot
// with its neighbours by strength: a spot of the surface behind, farther from the projector
// or lit at a slant, is fainter than the lattice it seems to continue, and the ratio would hide
// that.
void strengths_as_shown(std::vector<Spot>& spots, const cv::Mat& white_rgb, const ReferenceOptions& options = {});

}  // namespace vision
