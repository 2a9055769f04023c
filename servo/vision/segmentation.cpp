#include "servo/vision/segmentation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "servo/pattern/palette.hpp"

namespace vision {
namespace {

int otsu(const std::array<int, 256>& hist, int total) {
  double sum = 0;
  for (int i = 0; i < 256; ++i) sum += static_cast<double>(i) * hist[i];
  double sum_b = 0, best = -1;
  int w_b = 0, t_best = 0;
  for (int t = 0; t < 256; ++t) {
    w_b += hist[t];
    if (w_b == 0) continue;
    const int w_f = total - w_b;
    if (w_f == 0) break;
    sum_b += static_cast<double>(t) * hist[t];
    const double m_b = sum_b / w_b, m_f = (sum - sum_b) / w_f;
    const double between = static_cast<double>(w_b) * w_f * (m_b - m_f) * (m_b - m_f);
    if (between > best) {
      best = between;
      t_best = t;
    }
  }
  return t_best;
}

}  // namespace

Segmentation segment_spots(const cv::Mat& rgb, const SegmentationParams& p) {
  if (rgb.empty()) throw std::invalid_argument("segment_spots: empty image");
  if (rgb.type() != CV_8UC3)
    throw std::invalid_argument("segment_spots: expected an 8-bit 3-channel RGB image, got type " +
                                std::to_string(rgb.type()) + " with " + std::to_string(rgb.channels()) + " channels");
  if (p.colours < 2 || p.colours > static_cast<int>(pattern::kPalette.size()))
    throw std::invalid_argument("segment_spots: colours must be in 2..10");
  Segmentation out;
  const int W = rgb.cols, H = rgb.rows;

  // chroma and its histogram in one pass
  cv::Mat chroma(H, W, CV_8U);
  std::array<int, 256> hist{};
  for (int v = 0; v < H; ++v) {
    const std::uint8_t* in = rgb.ptr<std::uint8_t>(v);
    std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    for (int u = 0; u < W; ++u, in += 3) {
      const int r = in[0], g = in[1], b = in[2];
      const int hi = r > g ? (r > b ? r : b) : (g > b ? g : b);
      const int lo = r < g ? (r < b ? r : b) : (g < b ? g : b);
      c[u] = static_cast<std::uint8_t>(hi - lo);
    }
    for (int u = 0; u < W; ++u) ++hist[c[u]];
  }
  // Each pixel is compared with the brightest chroma around it: a spot is cut at a fraction
  // of its own peak, so dim spots (dark or oblique surfaces) and bright ones both separate
  // from their neighbours. The global Otsu level only caps that local level.
  // the floor rises with the sensor noise: the chroma of a noisy grey pixel is the spread of
  // three noisy channels, and most pixels are background, so the median chroma measures it
  int median = 0;
  for (int acc = 0; median < 255 && (acc += hist[median]) < W * H / 2;) ++median;
  const int floor_level = std::max(p.min_threshold, static_cast<int>(p.noise_floor_factor * median));
  out.threshold = std::max(floor_level, otsu(hist, W * H));
  cv::Mat local_max;
  cv::dilate(chroma, local_max, cv::getStructuringElement(cv::MORPH_RECT, {p.local_window_px, p.local_window_px}));
  cv::Mat level(H, W, CV_8U), mask(H, W, CV_8U);
  const int peak_ratio_256 = static_cast<int>(p.peak_ratio * 256);
  for (int v = 0; v < H; ++v) {
    const std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    const std::uint8_t* m = local_max.ptr<std::uint8_t>(v);
    std::uint8_t* l = level.ptr<std::uint8_t>(v);
    std::uint8_t* k = mask.ptr<std::uint8_t>(v);
    for (int u = 0; u < W; ++u) {
      const int t = std::min(out.threshold, std::max(floor_level, (m[u] * peak_ratio_256) >> 8));
      l[u] = static_cast<std::uint8_t>(t);
      k[u] = c[u] > t ? 255 : 0;
    }
  }
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);

  // palette colours as unit chroma vectors (colour minus its smallest channel)
  std::vector<std::array<double, 3>> palette(p.colours);
  for (int k = 0; k < p.colours; ++k) {
    const pattern::Rgb c = pattern::symbol_colour(k);
    const double lo = std::min({c.r, c.g, c.b});
    std::array<double, 3> x{c.r - lo, c.g - lo, c.b - lo};
    const double norm = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (double& e : x) e /= norm;
    palette[k] = x;
  }

  out.spots.reserve(static_cast<std::size_t>(n));
  for (int i = 1; i < n; ++i) {
    const int* s = stats.ptr<int>(i);
    const int x0 = s[cv::CC_STAT_LEFT], y0 = s[cv::CC_STAT_TOP], w = s[cv::CC_STAT_WIDTH], h = s[cv::CC_STAT_HEIGHT];
    const int area = s[cv::CC_STAT_AREA];
    const double elongation = static_cast<double>(std::max(w, h)) / std::min(w, h);
    if (area < p.min_area_px || area > p.max_area_px || elongation > p.max_elongation ||
        area < p.min_fill * w * h) {
      ++out.rejected;
      continue;
    }
    // centre of gravity of the chroma above threshold, and the blob's mean chroma vector
    double sw = 0, su = 0, sv = 0;
    std::array<double, 3> col{0, 0, 0};
    for (int v = y0; v < y0 + h; ++v) {
      const int* lab = labels.ptr<int>(v);
      const std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
      const std::uint8_t* in = rgb.ptr<std::uint8_t>(v);
      for (int u = x0; u < x0 + w; ++u) {
        if (lab[u] != i) continue;
        const double wgt = c[u] - level.ptr<std::uint8_t>(v)[u] + 1;
        sw += wgt;
        su += wgt * u;
        sv += wgt * v;
        const std::uint8_t* px = in + 3 * u;
        const int lo = std::min({px[0], px[1], px[2]});
        col[0] += px[0] - lo;
        col[1] += px[1] - lo;
        col[2] += px[2] - lo;
      }
    }
    const double norm = std::sqrt(col[0] * col[0] + col[1] * col[1] + col[2] * col[2]);
    int best = -1;
    double best_cos = -1;
    for (int k = 0; k < p.colours; ++k) {
      const double cosine = (col[0] * palette[k][0] + col[1] * palette[k][1] + col[2] * palette[k][2]) / norm;
      if (cosine > best_cos) {
        best_cos = cosine;
        best = k;
      }
    }
    if (best < 0 || best_cos < p.min_colour_match) {  // no dominant colour
      ++out.rejected;
      continue;
    }
    Spot spot;
    spot.u = su / sw;
    spot.v = sv / sw;
    spot.colour = best;
    spot.area_px = area;
    spot.strength = static_cast<float>(sw / area);
    spot.truncated = x0 == 0 || y0 == 0 || x0 + w == W || y0 + h == H;
    out.spots.push_back(spot);
  }
  return out;
}

}  // namespace vision
