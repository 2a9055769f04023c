// The paper's Fig. 2 view: the image with each decoded spot's id printed beside it.
#pragma once

#include <opencv2/core.hpp>

#include "servo/vision/spot_decoder.hpp"

namespace vision {

// Returns an RGB8 copy of `rgb` with detected spots ringed in grey and decoded spots ringed
// in white and labelled "row,col".
cv::Mat draw_overlay(const cv::Mat& rgb, const DecodeResult& result);

}  // namespace vision
