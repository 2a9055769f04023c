#include "servo/vision/segmentation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <opencv2/core/hal/intrin.hpp>
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

// chroma = max - min channel, and the min channel, in one pass over the interleaved RGB
// with OpenCV's universal intrinsics (16 pixels at a time; split + 5 whole-image operations
// cost three times as much)
void chroma_and_min(const cv::Mat& rgb, cv::Mat& lo, cv::Mat& chroma) {
  const int W = rgb.cols, H = rgb.rows;
  lo.create(H, W, CV_8U);
  chroma.create(H, W, CV_8U);
  for (int v = 0; v < H; ++v) {
    const std::uint8_t* px = rgb.ptr<std::uint8_t>(v);
    std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    std::uint8_t* l = lo.ptr<std::uint8_t>(v);
    int u = 0;
#if CV_SIMD128
    for (; u + 16 <= W; u += 16) {
      cv::v_uint8x16 r, g, b;
      cv::v_load_deinterleave(px + 3 * u, r, g, b);
      const cv::v_uint8x16 mn = cv::v_min(cv::v_min(r, g), b);
      cv::v_store(l + u, mn);
      cv::v_store(c + u, cv::v_max(cv::v_max(r, g), b) - mn);
    }
#endif
    for (; u < W; ++u) {
      const std::uint8_t r = px[3 * u], g = px[3 * u + 1], b = px[3 * u + 2];
      const std::uint8_t mn = std::min({r, g, b});
      l[u] = mn;
      c[u] = static_cast<std::uint8_t>(std::max({r, g, b}) - mn);
    }
  }
}

}  // namespace

// (x / 9 as (x + 4) 7282 >> 16: exact for x <= 9 x 255.) Separable: each row's horizontal sums
// of three once, in a ring of three rows.
void mean_3x3(const cv::Mat& rgb, cv::Mat& out, std::vector<std::uint16_t>& ring) {
  const int W = rgb.cols, H = rgb.rows, n = 3 * W;
  out.create(H, W, CV_8UC3);
  ring.resize(3 * static_cast<std::size_t>(n));
  const auto row_sum = [&](int v, std::uint16_t* s) {
    const std::uint8_t* p = rgb.ptr<std::uint8_t>(std::clamp(v, 0, H - 1));
    if (W == 1) {
      for (int c = 0; c < 3; ++c) s[c] = static_cast<std::uint16_t>(3 * p[c]);
      return;
    }
    for (int c = 0; c < 3; ++c) {
      s[c] = static_cast<std::uint16_t>(2 * p[c] + p[3 + c]);
      s[n - 3 + c] = static_cast<std::uint16_t>(p[n - 6 + c] + 2 * p[n - 3 + c]);
    }
    int i = 3;
#if CV_SIMD128
    for (; i + 19 <= n; i += 16) {
      cv::v_uint16x8 a0, a1, b0, b1, c0, c1;
      cv::v_expand(cv::v_load(p + i - 3), a0, a1);
      cv::v_expand(cv::v_load(p + i), b0, b1);
      cv::v_expand(cv::v_load(p + i + 3), c0, c1);
      cv::v_store(s + i, a0 + b0 + c0);
      cv::v_store(s + i + 8, a1 + b1 + c1);
    }
#endif
    for (; i < n - 3; ++i) s[i] = static_cast<std::uint16_t>(p[i - 3] + p[i] + p[i + 3]);
  };
  std::uint16_t* rows[3] = {ring.data(), ring.data() + n, ring.data() + 2 * static_cast<std::size_t>(n)};
  row_sum(-1, rows[0]);
  row_sum(0, rows[1]);
  for (int v = 0; v < H; ++v) {
    row_sum(v + 1, rows[2]);
    std::uint8_t* o = out.ptr<std::uint8_t>(v);
    int i = 0;
#if CV_SIMD128
    const cv::v_uint16x8 four = cv::v_setall_u16(4), ninth = cv::v_setall_u16(7282);
    for (; i + 16 <= n; i += 16) {
      const cv::v_uint16x8 lo = cv::v_mul_hi(cv::v_load(rows[0] + i) + cv::v_load(rows[1] + i) + cv::v_load(rows[2] + i) + four, ninth);
      const cv::v_uint16x8 hi =
          cv::v_mul_hi(cv::v_load(rows[0] + i + 8) + cv::v_load(rows[1] + i + 8) + cv::v_load(rows[2] + i + 8) + four, ninth);
      cv::v_store(o + i, cv::v_pack(lo, hi));
    }
#endif
    for (; i < n; ++i)
      o[i] = static_cast<std::uint8_t>(((rows[0][i] + rows[1][i] + rows[2][i] + 4u) * 7282u) >> 16);
    std::rotate(rows, rows + 1, rows + 3);
  }
}

namespace {

struct ChromaLevels {
  int floor = 0;      // no pixel at or below it is foreground
  int threshold = 0;  // the global (Otsu) level, above the floor
  bool noisy = false;  // the sensor's noise sets the floor, not min_threshold
};

ChromaLevels chroma_levels(const cv::Mat& chroma, const SegmentationOptions& p) {
  const int W = chroma.cols, H = chroma.rows;
  std::array<int, 256> hist{};
  int sampled = 0;
  // four partial histograms: a run of equal bytes (most of the background) would otherwise
  // chain every increment on the one before it
  std::array<std::array<int, 256>, 4> part{};
  // every fourth row up to 480 rows, about 120 rows beyond: plenty for a median and an Otsu level
  const int row_step = std::max(4, H / 120);
  for (int v = 0; v < H; v += row_step) {
    const std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    int u = 0;
    for (; u + 4 <= W; u += 4) ++part[0][c[u]], ++part[1][c[u + 1]], ++part[2][c[u + 2]], ++part[3][c[u + 3]];
    for (; u < W; ++u) ++part[0][c[u]];
    sampled += W;
  }
  for (int i = 0; i < 256; ++i) hist[i] = part[0][i] + part[1][i] + part[2][i] + part[3][i];
  // the floor rises with the sensor noise: the chroma of a noisy grey pixel is the spread of
  // three noisy channels, and most pixels are background, so the median chroma measures it
  int median = 0;
  for (int acc = 0; median < 255 && (acc += hist[median]) < sampled / 2;) ++median;
  ChromaLevels l;
  l.noisy = static_cast<int>(p.noise_floor_factor * median) > p.min_peak;
  l.floor = std::max(p.min_threshold, static_cast<int>(p.noise_floor_factor * median));
  l.threshold = std::max(l.floor, otsu(hist, sampled));
  return l;
}

// The mask holds each foreground pixel's weight in its blob's centroid, chroma - level + 1
// (>= 1; at most 256 - floor: a byte), 0 for background; the runs of foreground of each row
// are collected in the same pass. No pixel at or below the floor is foreground, and most are
// (spots cover a tenth of the image): 16 pixels are tested against the floor at once, and
// the table is read only in the chunks that pass.
void foreground_runs(const cv::Mat& chroma, const cv::Mat& peak, const std::array<std::uint8_t, 256>& level_of,
                     int floor_level, SegmentationScratch& sc) {
  const int W = chroma.cols, H = chroma.rows;
  cv::Mat& mask = sc.mask;
  mask.create(H, W, CV_8U);
  std::vector<SegmentationScratch::RowRun>& row_runs = sc.row_runs;
  row_runs.clear();
  std::vector<int>& row_start = sc.row_start;  // index of each row's first run
  row_start.assign(static_cast<std::size_t>(H) + 1, 0);
  for (int v = 0; v < H; ++v) {
    row_start[v] = static_cast<int>(row_runs.size());
    const std::uint8_t* c = chroma.ptr<std::uint8_t>(v);
    const std::uint8_t* lv = peak.ptr<std::uint8_t>(v);
    std::uint8_t* m = mask.ptr<std::uint8_t>(v);
    int open = -1;  // first pixel of the run being read, -1 outside a run
    const auto exact = [&](int a, int z) {
      for (int k = a; k < z; ++k) {
        const int l = level_of[lv[k]];
        const bool fg = c[k] > l;
        m[k] = fg ? static_cast<std::uint8_t>(std::min(255, c[k] - l + 1)) : 0;
        if (fg && open < 0) open = k;
        if (!fg && open >= 0) {
          row_runs.push_back({v, open, k - 1});
          open = -1;
        }
      }
    };
    int u = 0;
#if CV_SIMD128
    const cv::v_uint8x16 fl = cv::v_setall_u8(static_cast<std::uint8_t>(std::min(floor_level, 255)));
    for (; u + 16 <= W; u += 16) {
      if (!cv::v_check_any(cv::v_load(c + u) > fl)) {
        cv::v_store(m + u, cv::v_setzero_u8());
        if (open >= 0) {
          row_runs.push_back({v, open, u - 1});
          open = -1;
        }
        continue;
      }
      // every pixel at once: its level from the table, its weight, and the run edges from the
      // foreground's bit mask (a per-pixel branch mispredicts at every run's edge). The levels
      // are gathered in two registers: through memory, two 8-byte stores read back as one
      // 16-byte load stall the store forwarding, a tenth of the segmentation.
      std::uint64_t lo = 0, hi = 0;
      for (int k = 7; k >= 0; --k) lo = lo << 8 | level_of[lv[u + k]];
      for (int k = 15; k >= 8; --k) hi = hi << 8 | level_of[lv[u + k]];
      const cv::v_uint8x16 px = cv::v_load(c + u), l = cv::v_reinterpret_as_u8(cv::v_uint64x2(lo, hi));
      const cv::v_uint8x16 fg = px > l;
      // c - l + 1 saturated at 255 (the u8 operators saturate), 0 in the background
      cv::v_store(m + u, ((px - l) + cv::v_setall_u8(1)) & fg);
      const unsigned bits = static_cast<unsigned>(cv::v_signmask(fg));
      const unsigned before = (bits << 1) | (open >= 0 ? 1u : 0u);  // each pixel's left neighbour
      for (unsigned edges = (bits ^ before) & 0xFFFFu; edges != 0; edges &= edges - 1) {
        const int k = __builtin_ctz(edges);
        if (bits >> k & 1u) {
          open = u + k;
        } else {
          row_runs.push_back({v, open, u + k - 1});
          open = -1;
        }
      }
    }
#endif
    exact(u, W);
    if (open >= 0) row_runs.push_back({v, open, W - 1});
  }
  row_start[H] = static_cast<int>(row_runs.size());
}

// palette colours as unit chroma vectors (colour minus its smallest channel)
std::vector<std::array<double, 3>> palette_directions(int colours) {
  std::vector<std::array<double, 3>> palette(colours);
  for (int k = 0; k < colours; ++k) {
    const pattern::Rgb c = pattern::symbol_colour(k);
    const double lo_c = std::min({c.r, c.g, c.b});
    std::array<double, 3> x{c.r - lo_c, c.g - lo_c, c.b - lo_c};
    const double norm = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (double& e : x) e /= norm;
    palette[k] = x;
  }
  return palette;
}

struct Blob {
  int area = 0, x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  int peak = 0;  // its largest chroma
  double sw = 0, su = 0, sv = 0;
  std::array<double, 3> col{0, 0, 0};
  bool covered = false;  // a pixel of the other pass's spots (SegmentationScratch::covered)
};

// Which roots of the runs' union-find have a run with a pixel in `covered`.
template <class Find>
std::vector<char> roots_touching(const cv::Mat& covered, const std::vector<SegmentationScratch::RowRun>& row_runs,
                                 Find& find) {
  std::vector<char> touches(row_runs.size(), 0);
  for (std::size_t i = 0; i < row_runs.size(); ++i) {
    const int root = find(static_cast<int>(i));
    const auto [v, xl, xr] = row_runs[i];
    const std::uint8_t* other = covered.ptr<std::uint8_t>(v);
    for (int u = xl; u <= xr && !touches[root]; ++u) touches[root] = other[u] != 0;
  }
  return touches;
}

// 8-connected components of the mask as runs: each row's runs of foreground carry their sums,
// and a run joins every run of the row above that it touches, diagonals included (union-find).
// Every foreground pixel is read once, in a loop without branches on the pixel; a flood fill
// reads each pixel's rows above and below as well, and mispredicts at every run's edge.
// The blobs come in the order of their first pixel (raster order, as a scan would meet them).
std::vector<Blob> connected_blobs(const cv::Mat& rgb, const cv::Mat* covered, SegmentationScratch& sc) {
  const int W = rgb.cols, H = rgb.rows;
  const std::vector<SegmentationScratch::RowRun>& row_runs = sc.row_runs;
  const std::vector<int>& row_start = sc.row_start;
  const int n_runs = static_cast<int>(row_runs.size());
  std::vector<int>& parent = sc.parent;
  parent.resize(static_cast<std::size_t>(n_runs));
  for (int i = 0; i < n_runs; ++i) parent[i] = i;
  const auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (int v = 1; v < H; ++v) {
    int j = row_start[v - 1];
    const int j_end = row_start[v];
    for (int i = row_start[v]; i < row_start[v + 1]; ++i) {
      const SegmentationScratch::RowRun& r = row_runs[i];
      while (j < j_end && row_runs[j].xr < r.xl - 1) ++j;  // runs above that end before this one's reach
      for (int k = j; k < j_end && row_runs[k].xl <= r.xr + 1; ++k) {
        const int a = find(i), b = find(k);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);  // the root is the raster-first run
      }
    }
  }
  std::vector<Blob> blobs;
  std::vector<int>& blob_of = sc.blob_of;
  blob_of.assign(static_cast<std::size_t>(n_runs), -1);
  const std::uint8_t* weight_px = sc.mask.ptr<std::uint8_t>(0);  // continuous (created above)
  const std::uint8_t* lo_px = sc.lo.ptr<std::uint8_t>(0);
  const std::uint8_t* chroma_px = sc.chroma.ptr<std::uint8_t>(0);
  // a blob touching the other pass's spots is only marked: most of them do, and their sums
  // would be read for nothing
  const std::vector<char> touches = covered ? roots_touching(*covered, row_runs, find) : std::vector<char>();
  for (int i = 0; i < n_runs; ++i) {
    const int root = parent[i] = find(i);  // each run straight to its root (paint_kept reads it)
    if (blob_of[root] < 0) {
      blob_of[root] = static_cast<int>(blobs.size());
      blobs.emplace_back();
    }
    Blob& b = blobs[static_cast<std::size_t>(blob_of[root])];
    if (covered && touches[root]) {
      b.covered = true;
      continue;
    }
    const auto [v, xl, xr] = row_runs[i];
    const std::ptrdiff_t base = static_cast<std::ptrdiff_t>(v) * W;
    const std::uint8_t* px = rgb.ptr<std::uint8_t>(v);
    // integer sums: exact, as the doubles they feed, in any order of the runs
    std::int64_t sw = 0, su = 0, r = 0, g = 0, bl = 0;
    int peak = b.peak;
    for (int u = xl; u <= xr; ++u) {
      const int wgt = weight_px[base + u];
      peak = std::max(peak, static_cast<int>(chroma_px[base + u]));
      sw += wgt;
      su += wgt * u;
      const int low = lo_px[base + u];
      r += px[3 * u] - low;
      g += px[3 * u + 1] - low;
      bl += px[3 * u + 2] - low;
    }
    b.area += xr - xl + 1;
    b.peak = peak;
    b.x0 = std::min(b.x0, xl), b.x1 = std::max(b.x1, xr), b.y0 = std::min(b.y0, v), b.y1 = std::max(b.y1, v);
    b.sw += static_cast<double>(sw);
    b.su += static_cast<double>(su);
    b.sv += static_cast<double>(sw * v);
    b.col[0] += static_cast<double>(r);
    b.col[1] += static_cast<double>(g);
    b.col[2] += static_cast<double>(bl);
  }
  return blobs;
}

// The blobs that are spots: their size, shape and fill, and a dominant palette colour.
// Returns which blobs are spots.
std::vector<char> spots_of(const std::vector<Blob>& blobs, const SegmentationOptions& p, bool smoothed, int W, int H,
                           Segmentation& out) {
  std::vector<char> kept(blobs.size(), 0);
  const std::vector<std::array<double, 3>> palette = palette_directions(p.colours);
  out.spots.reserve(blobs.size() + 1);
  std::vector<Spot> slivers;
  for (std::size_t i = 0; i < blobs.size(); ++i) {
    const Blob& b = blobs[i];
    if (b.covered) continue;
    const int w = b.x1 - b.x0 + 1, h = b.y1 - b.y0 + 1;
    // the shape less what the 3 x 3 mean spread it by (a pixel each side): a sliver 1 px wide
    // is 3 px wide after it
    const int spread = smoothed ? 2 : 0;
    const int we = std::max(1, w - spread), he = std::max(1, h - spread);
    const double elongation = static_cast<double>(std::max(we, he)) / std::min(we, he);
    const bool sliver = elongation > p.max_elongation;
    if (b.area < p.min_area_px || b.area > p.max_area_px ||
        b.area < p.min_fill * w * h || b.peak < p.min_peak) {
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
    // Cut by the border: it touches the border and reaches less far from its centroid towards
    // it than away from it. A spot that only grazes the border (its faint rim cut, the weights
    // there are near 0) keeps its centroid: in 1000 cylinder poses those spots' centroids are
    // 0.37 px from the truth on average, and reporting them names 0.5 points more of the readable
    // spots. Every spot touching the border counted as cut before.
    // A sliver whose centre lies beyond the border can reach as far both ways (two rows of a
    // spot): the reach towards the border must also be a spot's half-width's worth.
    const double left = spot.u - b.x0, right = b.x1 - spot.u, top = spot.v - b.y0, bottom = b.y1 - spot.v;
    // (the mean spread the blob a pixel away from the border, not into it: that pixel is given
    // back to its reach towards the border)
    const auto cut = [&p, spread](double towards, double away) {
      return towards + 0.5 * spread < away - p.border_cut_px || towards < p.border_reach_px;
    };
    spot.truncated = (b.x0 == 0 && cut(left, right)) || (b.x1 == W - 1 && cut(right, left)) ||
                     (b.y0 == 0 && cut(top, bottom)) || (b.y1 == H - 1 && cut(bottom, top));
    spot.sliver = sliver;
    (sliver ? slivers : out.spots).push_back(spot);
    kept[i] = 1;
  }
  out.spots.insert(out.spots.end(), slivers.begin(), slivers.end());
  return kept;
}

// The pixels of the kept blobs (the runs of the last pass, each run's parent its root), 1 in
// `covered`, 0 elsewhere.
void paint_kept(const std::vector<char>& kept, SegmentationScratch& sc) {
  sc.covered.create(sc.mask.size(), CV_8U);
  sc.covered.setTo(0);
  for (std::size_t i = 0; i < sc.row_runs.size(); ++i) {
    if (!kept[static_cast<std::size_t>(sc.blob_of[static_cast<std::size_t>(sc.parent[i])])]) continue;
    const auto [v, xl, xr] = sc.row_runs[i];
    std::fill_n(sc.covered.ptr<std::uint8_t>(v) + xl, xr - xl + 1, std::uint8_t{1});
  }
}

// One image's foreground at its levels, and its blobs that are spots appended to `out`; with
// `covered`, the blobs with a pixel in that mask are left out. Returns which blobs are spots.
std::vector<char> segment_pass(const cv::Mat& image, bool smoothed, const ChromaLevels& levels,
                               const SegmentationOptions& p, const cv::Mat* covered, SegmentationScratch& sc,
                               Segmentation& out) {
  // Each pixel is compared with the brightest chroma around it: a spot is cut at a fraction
  // of its own peak, so dim spots (dark or oblique surfaces) and bright ones both separate
  // from their neighbours. The global Otsu level caps that local level, the floor bounds it.
  cv::dilate(sc.chroma, sc.peak, cv::getStructuringElement(cv::MORPH_RECT, {p.local_window_px, p.local_window_px}));
  // the local level of a local peak x: clamp(round(peak_ratio x), floor, Otsu), tabulated
  std::array<std::uint8_t, 256> level_of{};
  for (int x = 0; x < 256; ++x)
    level_of[x] = static_cast<std::uint8_t>(std::min(
        levels.threshold, std::max(levels.floor, static_cast<int>(cv::saturate_cast<std::uint8_t>(x * p.peak_ratio)))));
  foreground_runs(sc.chroma, sc.peak, level_of, levels.floor, sc);
  return spots_of(connected_blobs(image, covered, sc), p, smoothed, image.cols, image.rows, out);
}

}  // namespace

SegmentationOptions at_crosstalk(const SegmentationOptions& given) {
  if (!(given.crosstalk >= 0 && given.crosstalk <= kMaxCrosstalk)) {
    char m[128];
    std::snprintf(m, sizeof m, "segmentation: the camera's crosstalk must be in [0, %g], got %g", kMaxCrosstalk,
                  given.crosstalk);
    throw std::invalid_argument(m);
  }
  // a primary's chroma is (1 - 3x) of its light (SegmentationOptions::crosstalk); exactly 1 at
  // the crosstalk the levels were set at
  const double gain = (1 - 3 * given.crosstalk) / (1 - 3 * kLevelsCrosstalk);
  SegmentationOptions p = given;
  p.min_threshold = static_cast<int>(std::lround(given.min_threshold * gain));
  p.min_peak = static_cast<int>(std::lround(given.min_peak * gain));
  return p;
}

Segmentation segment_spots(const cv::Mat& rgb, const SegmentationOptions& given, SegmentationScratch* scratch) {
  if (rgb.empty()) throw std::invalid_argument("segment_spots: empty image");
  if (rgb.type() != CV_8UC3)
    throw std::invalid_argument("segment_spots: expected an 8-bit 3-channel RGB image, got type " +
                                std::to_string(rgb.type()) + " with " + std::to_string(rgb.channels()) + " channels");
  if (given.colours < 2 || given.colours > static_cast<int>(pattern::kPalette.size()))
    throw std::invalid_argument("segment_spots: colours must be in 2..10");
  const SegmentationOptions p = at_crosstalk(given);
  Segmentation out;
  SegmentationScratch local;
  SegmentationScratch& sc = scratch ? *scratch : local;
  chroma_and_min(rgb, sc.lo, sc.chroma);
  const ChromaLevels raw = chroma_levels(sc.chroma, p);
  if (!p.smoothing || !raw.noisy) {
    out.threshold = raw.threshold;
    segment_pass(rgb, false, raw, p, nullptr, sc, out);
    return out;
  }
  cv::swap(sc.chroma, sc.own_chroma);  // the image's, kept for its own pass
  cv::swap(sc.lo, sc.own_lo);
  mean_3x3(rgb, sc.smooth, sc.box_rows);
  chroma_and_min(sc.smooth, sc.lo, sc.chroma);
  const ChromaLevels smoothed = chroma_levels(sc.chroma, p);
  out.threshold = smoothed.threshold;
  const std::vector<char> kept = segment_pass(sc.smooth, true, smoothed, p, nullptr, sc, out);
  if (!p.own_spots) return out;
  paint_kept(kept, sc);
  // The mean dims a spot 1-2 px wide (the last column before a silhouette, seen edge-on) to a
  // half or less, under the local level its brighter neighbours set; the image itself, at its
  // own noise floor, keeps it. The image's spots that touch none of the mean's join them (issue
  // 41: with the mean alone the paper pattern's cylinder under noise sigma 3-6 named 2-3 % fewer
  // spots than without it).
  cv::swap(sc.chroma, sc.own_chroma);
  cv::swap(sc.lo, sc.own_lo);
  Segmentation own;
  segment_pass(rgb, false, raw, p, &sc.covered, sc, own);
  out.rejected += own.rejected;
  out.spots.insert(out.spots.end(), own.spots.begin(), own.spots.end());
  std::stable_partition(out.spots.begin(), out.spots.end(), [](const Spot& s) { return !s.sliver; });
  return out;
}

}  // namespace vision
