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
  int sampled = 0;
  for (int v = 0; v < H; v += 4) {  // every fourth row: plenty for a median and an Otsu level
    const std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    for (int u = 0; u < W; ++u) ++hist[c[u]];
    sampled += W;
  }

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
  std::vector<std::pair<int, int>> stack;  // (u, v): no division to recover them from an index
  std::uint8_t* mk = mask.ptr<std::uint8_t>(0);  // continuous (created by compare)
  const std::uint8_t* chroma_px = chroma.ptr<std::uint8_t>(0);
  const std::uint8_t* level_px = level.ptr<std::uint8_t>(0);
  const std::uint8_t* lo_px = lo.ptr<std::uint8_t>(0);
  // scanline fill: each popped seed takes its whole run of the row at once, and seeds one
  // pixel per run in the rows above and below (from one left of the run to one right of it:
  // 8-connectivity)
  const auto grow = [&](int u0, int v0) {
    Blob b;
    stack.clear();
    stack.emplace_back(u0, v0);
    while (!stack.empty()) {
      const auto [us, v] = stack.back();
      stack.pop_back();
      std::uint8_t* row = mk + static_cast<std::ptrdiff_t>(v) * W;
      if (!row[us]) continue;
      int xl = us, xr = us;
      while (xl > 0 && row[xl - 1]) --xl;
      while (xr + 1 < W && row[xr + 1]) ++xr;
      std::memset(row + xl, 0, static_cast<std::size_t>(xr - xl + 1));
      const std::ptrdiff_t base = static_cast<std::ptrdiff_t>(v) * W;
      const std::uint8_t* px = rgb.ptr<std::uint8_t>(v);
      b.area += xr - xl + 1;
      b.x0 = std::min(b.x0, xl), b.x1 = std::max(b.x1, xr), b.y0 = std::min(b.y0, v), b.y1 = std::max(b.y1, v);
      double sw = 0, su = 0, r = 0, g = 0, bl = 0;
      for (int u = xl; u <= xr; ++u) {
        const double wgt = chroma_px[base + u] - level_px[base + u] + 1;
        sw += wgt;
        su += wgt * u;
        const int low = lo_px[base + u];
        r += px[3 * u] - low;
        g += px[3 * u + 1] - low;
        bl += px[3 * u + 2] - low;
      }
      b.sw += sw;
      b.su += su;
      b.sv += sw * v;
      b.col[0] += r;
      b.col[1] += g;
      b.col[2] += bl;
      for (const int vv : {v - 1, v + 1}) {
        if (vv < 0 || vv >= H) continue;
        const std::uint8_t* nrow = mk + static_cast<std::ptrdiff_t>(vv) * W;
        const int a = std::max(xl - 1, 0), z = std::min(xr + 1, W - 1);
        for (int u = a; u <= z; ++u)
          if (nrow[u] && (u == a || !nrow[u - 1])) stack.emplace_back(u, vv);  // one seed per run
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
      if (m[u]) grow(u, v);
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
