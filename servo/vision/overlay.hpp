// The paper's Fig. 2 view: the image with each decoded spot's id printed beside it.
#pragma once

#include <opencv2/core.hpp>
#include <optional>

#include "servo/vision/spot_decoder.hpp"

namespace vision {

// Returns an RGB8 copy of `rgb`, twice its size, with detected spots ringed in grey and decoded
// spots ringed in white (in kOffLine's orange when kept from the law, DecodedSpot::apart: off
// their epipolar line or clipped) and labelled "row,col" where a label has room (a ring without
// a label: the id is in `servo decode --json`).
inline const cv::Scalar kOffLine(255, 160, 0);
cv::Mat draw_overlay(const cv::Mat& rgb, const DecodeResult& result);

}  // namespace vision
