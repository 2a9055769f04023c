// The white reference frame's stage (servo/vision/reference.hpp) on hand-made frames: the
// surface's albedo divided out, the gain bounded where the white frame is dim, the strengths
// given back as the pattern frame shows them, and bad frames refused.
#include "servo/vision/reference.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace vision {
namespace {

// A camera's pixel: the light (ambient plus the projector's, per channel) times the surface's
// albedo, in 8-bit units, clamped.
cv::Vec3b seen(const std::array<double, 3>& light, const std::array<double, 3>& albedo) {
  cv::Vec3b p;
  for (int c = 0; c < 3; ++c) p[c] = static_cast<std::uint8_t>(std::clamp(std::lround(255 * light[c] * albedo[c]), 0L, 255L));
  return p;
}

// 3 x 3 blocks of one surface each: pattern frame = a red spot's light, white frame = white.
struct Pair {
  cv::Mat pattern, white;
};
Pair surface(const std::array<double, 3>& albedo, double ambient = 0.06, double projector = 0.9) {
  const std::array<double, 3> spot{ambient + projector, ambient, ambient};
  const std::array<double, 3> white{ambient + projector, ambient + projector, ambient + projector};
  return {cv::Mat(9, 9, CV_8UC3, seen(spot, albedo)), cv::Mat(9, 9, CV_8UC3, seen(white, albedo))};
}

TEST(Reference, TheRatioIsTheSameOnAWhiteADarkAndAColouredSurface) {
  const Pair grey = surface({0.9, 0.9, 0.9}), dark = surface({0.25, 0.25, 0.25}), ham = surface({0.80, 0.52, 0.48});
  cv::Mat a, b, c;
  normalise_by_white(grey.pattern, grey.white, a);
  normalise_by_white(dark.pattern, dark.white, b);
  normalise_by_white(ham.pattern, ham.white, c);
  const cv::Vec3b x = a.at<cv::Vec3b>(4, 4), y = b.at<cv::Vec3b>(4, 4), z = c.at<cv::Vec3b>(4, 4);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(x[ch], y[ch], 5) << "channel " << ch;
    EXPECT_NEAR(x[ch], z[ch], 5) << "channel " << ch;
  }
  // the spot's own channel at full scale, the others at the ambient light's share
  EXPECT_GE(x[0], 250);
  EXPECT_NEAR(x[1], 255 * 0.06 / 0.96, 2);
  // the raw frames differ by the albedo: the dark one is a quarter as bright
  EXPECT_LT(dark.pattern.at<cv::Vec3b>(4, 4)[0], grey.pattern.at<cv::Vec3b>(4, 4)[0] / 3);
}

TEST(Reference, WhereTheWhiteFrameIsDimTheGainIsBounded) {
  // the ambient light alone (beyond the pattern): both frames at 10, the ratio would be 255
  const cv::Mat dim(9, 9, CV_8UC3, cv::Vec3b(10, 10, 10));
  ReferenceOptions o;
  cv::Mat out;
  normalise_by_white(dim, dim, out, o);
  EXPECT_EQ(out.at<cv::Vec3b>(4, 4)[0], std::lround(10 * 255.0 / o.full_level));
  o.full_level = 255;  // no gain at all
  normalise_by_white(dim, dim, out, o);
  EXPECT_EQ(out.at<cv::Vec3b>(4, 4)[0], 10);
}

TEST(Reference, TheWhiteFramesNoiseIsAveragedOut) {
  // a white frame whose centre pixel alone reads 9 levels low: its 3 x 3 mean one level low
  const Pair grey = surface({0.9, 0.9, 0.9});
  cv::Mat white = grey.white.clone(), out;
  white.at<cv::Vec3b>(4, 4) -= cv::Vec3b(9, 9, 9);
  normalise_by_white(grey.pattern, white, out);
  const double expected = 255.0 * grey.pattern.at<cv::Vec3b>(4, 4)[1] / (grey.white.at<cv::Vec3b>(4, 4)[1] - 1);
  EXPECT_NEAR(out.at<cv::Vec3b>(4, 4)[1], expected, 1.0);
}

TEST(Reference, StrengthsAreGivenBackAsThePatternFrameShowsThem) {
  // a red spot and a blue one on a surface returning 200 of red and 50 of blue
  const cv::Mat white(9, 9, CV_8UC3, cv::Vec3b(200, 120, 50));
  Spot red, blue;
  red.u = blue.u = 4, red.v = blue.v = 4;
  red.colour = 2, blue.colour = 0;
  red.strength = blue.strength = 100;
  std::vector<Spot> spots{red, blue};
  strengths_as_shown(spots, white);
  EXPECT_NEAR(spots[0].strength, 100 * 200 / 255.0, 1e-3);
  EXPECT_NEAR(spots[1].strength, 100 * 50 / 255.0, 1e-3);
}

TEST(Reference, FramesThatDoNotMatchAreRefused) {
  const cv::Mat a(9, 9, CV_8UC3, cv::Vec3b(1, 2, 3)), b(8, 9, CV_8UC3, cv::Vec3b(1, 2, 3)), grey(9, 9, CV_8UC1);
  cv::Mat out;
  EXPECT_THROW(normalise_by_white(a, b, out), std::invalid_argument);
  EXPECT_THROW(normalise_by_white(a, grey, out), std::invalid_argument);
  EXPECT_THROW(normalise_by_white(cv::Mat(), a, out), std::invalid_argument);
  ReferenceOptions o;
  o.full_level = 0;
  EXPECT_THROW(normalise_by_white(a, a, out, o), std::invalid_argument);
  try {
    normalise_by_white(a, b, out);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("9 x 8"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vision
