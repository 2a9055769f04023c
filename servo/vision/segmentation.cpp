#include "servo/vision/segmentation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
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

Segmentation segment_spots(const cv::Mat& rgb, const SegmentationParams& p, SegmentationScratch* scratch) {
  if (rgb.empty()) throw std::invalid_argument("segment_spots: empty image");
  if (rgb.type() != CV_8UC3)
    throw std::invalid_argument("segment_spots: expected an 8-bit 3-channel RGB image, got type " +
                                std::to_string(rgb.type()) + " with " + std::to_string(rgb.channels()) + " channels");
  if (p.colours < 2 || p.colours > static_cast<int>(pattern::kPalette.size()))
    throw std::invalid_argument("segment_spots: colours must be in 2..10");
  Segmentation out;
  const int W = rgb.cols, H = rgb.rows;

  // chroma = max - min channel, with OpenCV's vectorised per-channel operations (a scalar
  // loop over interleaved RGB costs five times as much)
  SegmentationScratch local;
  SegmentationScratch& sc = scratch ? *scratch : local;
  cv::Mat* channels = sc.channels;
  cv::Mat &hi = sc.hi, &lo = sc.lo, &chroma = sc.chroma;
  cv::split(rgb, channels);
  cv::max(channels[0], channels[1], hi);
  cv::max(hi, channels[2], hi);
  cv::min(channels[0], channels[1], lo);
  cv::min(lo, channels[2], lo);
  cv::subtract(hi, lo, chroma);
  std::array<int, 256> hist{};
  for (int v = 0; v < H; v += 2) {  // every other row: plenty for a median and an Otsu level
    const std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    for (int u = 0; u < W; ++u) ++hist[c[u]];
  }
  const int sampled = ((H + 1) / 2) * W;

  // the floor rises with the sensor noise: the chroma of a noisy grey pixel is the spread of
  // three noisy channels, and most pixels are background, so the median chroma measures it
  int median = 0;
  for (int acc = 0; median < 255 && (acc += hist[median]) < sampled / 2;) ++median;
  const int floor_level = std::max(p.min_threshold, static_cast<int>(p.noise_floor_factor * median));
  out.threshold = std::max(floor_level, otsu(hist, sampled));

  // Each pixel is compared with the brightest chroma around it: a spot is cut at a fraction
  // of its own peak, so dim spots (dark or oblique surfaces) and bright ones both separate
  // from their neighbours. The global Otsu level caps that local level, the floor bounds it.
  cv::Mat &level = sc.level, &mask = sc.mask;
  cv::dilate(chroma, level, cv::getStructuringElement(cv::MORPH_RECT, {p.local_window_px, p.local_window_px}));
  level.convertTo(level, CV_8U, p.peak_ratio);
  cv::max(level, floor_level, level);
  cv::min(level, out.threshold, level);
  cv::compare(chroma, level, mask, cv::CMP_GT);

  // palette colours as unit chroma vectors (colour minus its smallest channel)
  std::vector<std::array<double, 3>> palette(p.colours);
  for (int k = 0; k < p.colours; ++k) {
    const pattern::Rgb c = pattern::symbol_colour(k);
    const double lo_c = std::min({c.r, c.g, c.b});
    std::array<double, 3> x{c.r - lo_c, c.g - lo_c, c.b - lo_c};
    const double norm = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (double& e : x) e /= norm;
    palette[k] = x;
  }

  // 8-connected components of the mask, grown from each foreground pixel met in a scan that
  // skips background eight bytes at a time (spots cover a tenth of the image): each blob's
  // area, bounding box, centre of gravity of the chroma above the local level and summed
  // chroma vector are gathered while it grows. Visited pixels are cleared from the mask.
  struct Blob {
    int area = 0, x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
    double sw = 0, su = 0, sv = 0;
    std::array<double, 3> col{0, 0, 0};
  };
  std::vector<Blob> blobs;
  std::vector<int> stack;
  std::uint8_t* mk = mask.ptr<std::uint8_t>(0);  // continuous (created by compare)
  const auto grow = [&](int seed) {
    Blob b;
    stack.clear();
    stack.push_back(seed);
    mk[seed] = 0;
    while (!stack.empty()) {
      const int idx = stack.back();
      stack.pop_back();
      const int v = idx / W, u = idx - v * W;
      ++b.area;
      b.x0 = std::min(b.x0, u), b.x1 = std::max(b.x1, u), b.y0 = std::min(b.y0, v), b.y1 = std::max(b.y1, v);
      const double wgt = chroma.data[idx] - level.data[idx] + 1;
      b.sw += wgt;
      b.su += wgt * u;
      b.sv += wgt * v;
      const std::uint8_t* px = rgb.ptr<std::uint8_t>(v) + 3 * u;
      const int low = lo.data[idx];
      b.col[0] += px[0] - low;
      b.col[1] += px[1] - low;
      b.col[2] += px[2] - low;
      for (int dv = -1; dv <= 1; ++dv) {
        const int vv = v + dv;
        if (vv < 0 || vv >= H) continue;
        for (int du = -1; du <= 1; ++du) {
          const int uu = u + du;
          if (uu < 0 || uu >= W) continue;
          const int j = vv * W + uu;
          if (mk[j]) {
            mk[j] = 0;
            stack.push_back(j);
          }
        }
      }
    }
    blobs.push_back(b);
  };
  for (int v = 0; v < H; ++v) {
    const std::uint8_t* m = mk + static_cast<std::ptrdiff_t>(v) * W;
    for (int u = 0; u < W; ++u) {
      if ((u & 7) == 0 && u + 8 <= W) {
        std::uint64_t chunk;
        std::memcpy(&chunk, m + u, 8);
        if (chunk == 0) {
          u += 7;
          continue;
        }
      }
      if (m[u]) grow(v * W + u);
    }
  }
  const int n = static_cast<int>(blobs.size()) + 1;  // (label 0 was the background)
  blobs.insert(blobs.begin(), Blob{});

  out.spots.reserve(static_cast<std::size_t>(n));
  for (int i = 1; i < n; ++i) {
    const Blob& b = blobs[static_cast<std::size_t>(i)];
    const int w = b.x1 - b.x0 + 1, h = b.y1 - b.y0 + 1;
    const double elongation = static_cast<double>(std::max(w, h)) / std::min(w, h);
    if (b.area < p.min_area_px || b.area > p.max_area_px || elongation > p.max_elongation ||
        b.area < p.min_fill * w * h) {
      ++out.rejected;
      continue;
    }
    const auto& col = b.col;
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
    spot.u = b.su / b.sw;
    spot.v = b.sv / b.sw;
    spot.colour = best;
    spot.area_px = b.area;
    spot.strength = static_cast<float>(b.sw / b.area);
    spot.truncated = b.x0 == 0 || b.y0 == 0 || b.x1 == W - 1 || b.y1 == H - 1;
    out.spots.push_back(spot);
  }
  return out;
}

}  // namespace vision
