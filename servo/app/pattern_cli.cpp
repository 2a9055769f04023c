// `pattern`: generate, check and draw M-array pattern files.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/cli_help.hpp"
#include "common/output_image.hpp"
#include "common/cli_numbers.hpp"
#include "servo/pattern/marray.hpp"
#include "servo/pattern/palette.hpp"
#include "servo/pattern/pattern_file.hpp"

namespace {

int run_generate(const pattern::GenerationOptions& p, const std::string& out) {
  const pattern::GenerationResult res = pattern::generate_marray(p);
  if (!res.array) {
    std::cerr << "pattern generate: " << res.failure << "\n";
    return 1;
  }
  pattern::write_marray(out, *res.array);
  const auto rep = pattern::check_window_property(*res.array, p.window);
  std::printf("wrote %s: %d x %d, k = %d, window %d x %d, seed %llu, min Hamming %d (asked >= %d), "
              "%d windows, generated in %.1f ms (%llu restarts, %llu backtracks)\n",
              out.c_str(), p.rows, p.cols, p.colours, p.window.rows, p.window.cols,
              static_cast<unsigned long long>(p.seed), rep.min_hamming, p.min_hamming, rep.total_windows, res.seconds * 1e3,
              static_cast<unsigned long long>(res.restarts), static_cast<unsigned long long>(res.backtracks));
  return 0;
}

int run_check(const std::string& file, pattern::WindowShape w, int colours) {
  const pattern::MArray a = pattern::read_marray(file, colours);
  const auto rep = pattern::check_window_property(a, w);
  std::printf("%s: %d x %d, k = %d, window %d x %d\n", file.c_str(), a.rows, a.cols, a.colours, w.rows, w.cols);
  std::printf("window property: %s\n", rep.holds ? "holds" : "FAILS");
  std::printf("distinct windows: %d of %d\n", rep.distinct_windows, rep.total_windows);
  if (rep.pairs_at_min > 0)
    std::printf("min Hamming distance: %d (%llu window pairs at that distance)\n", rep.min_hamming,
                static_cast<unsigned long long>(rep.pairs_at_min));
  else
    std::printf("min Hamming distance: %d\n", rep.min_hamming);
  // what the distance buys a decoder: d - 1 wrong colours detected, (d - 1) / 2 corrected,
  // d - 1 missing spots of a window filled in by the one code that fits
  if (rep.holds && rep.min_hamming >= 2)
    std::printf("a window read with up to %d wrong colour%s is corrected; up to %d missing spots are completed\n",
                (rep.min_hamming - 1) / 2, (rep.min_hamming - 1) / 2 == 1 ? "" : "s", rep.min_hamming - 1);
  if (rep.repeat) {
    const auto& [p, q] = *rep.repeat;
    std::printf("repeated window: top-left (%d, %d) and (%d, %d)\n", p.first, p.second, q.first, q.second);
  }
  return rep.holds ? 0 : 1;
}

// Draws the pattern as the projector shows it: coloured discs on black, like the paper's Fig. 2.
int run_render(const std::string& file, const std::string& out, int pitch) {
  const pattern::MArray a = pattern::read_marray(file);
  // the image is allocated whole: bound it before asking for it
  constexpr long long kMaxRenderPixels = 64LL << 20;
  const long long pixels = static_cast<long long>(a.rows) * pitch * a.cols * pitch;
  if (pixels > kMaxRenderPixels) {
    std::cerr << "pattern render: " << file << ": " << a.rows << " x " << a.cols << " spots at pitch " << pitch << " make "
              << a.cols * pitch << " x " << a.rows * pitch << " px, more than the limit of " << kMaxRenderPixels
              << " pixels (use a smaller --pitch)\n";
    return 2;
  }
  cv::Mat img(a.rows * pitch, a.cols * pitch, CV_8UC3, cv::Scalar(0, 0, 0));
  for (int r = 0; r < a.rows; ++r)
    for (int c = 0; c < a.cols; ++c) {
      const pattern::Rgb rgb = pattern::symbol_colour(a.at(r, c));
      cv::circle(img, {c * pitch + pitch / 2, r * pitch + pitch / 2}, pitch * 3 / 10, cv::Scalar(rgb.b, rgb.g, rgb.r),
                 cv::FILLED, cv::LINE_AA);
    }
  try {
    common::write_output_image(out, img);
  } catch (const common::FileError& e) {
    std::cerr << "pattern render: " << e.what() << "\n";
    return 1;
  }
  std::printf("wrote %s (%d x %d px)\n", out.c_str(), img.cols, img.rows);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"M-array patterns of coloured spots (Morano et al. perfect submaps)"};
  common::plain_help(app);
  app.require_subcommand(1);

  pattern::GenerationOptions gp;
  int window = 3;
  std::string out;
  auto* gen = app.add_subcommand("generate", "generate a perfect submap by brute force");
  gen->add_option("--rows", gp.rows, "rows")->required()->check(CLI::PositiveNumber);
  gen->add_option("--cols", gp.cols, "columns")->required()->check(CLI::PositiveNumber);
  gen->add_option("--colours,--colors", gp.colours, "alphabet size k")->required();
  gen->add_option("--window", window, "window size n (n x n)")->capture_default_str();
  gen->add_option("--min-distance,--min-hamming", gp.min_hamming,
                  "minimum Hamming distance between windows: 1 (the paper's), 2, or 3 (3 colours, 3 x 3 windows: the "
                  "algebraic GF(3^6) array, up to 20 x 20)")
      ->capture_default_str();
  gen->add_option("--seed", gp.seed, "random seed")->required()->check(common::whole_number());
  gen->add_option("--time-budget", gp.time_budget_s, "give up after this many CPU seconds")->capture_default_str();
  gen->add_option("-o,--output", out, "pattern file to write")->required();

  std::string file;
  int check_colours = 0;
  auto* chk = app.add_subcommand("check", "verify the window property of a pattern file");
  chk->add_option("file", file, "pattern file")->required();
  chk->add_option("--window", window, "window size n (n x n)")->capture_default_str();
  chk->add_option("--colours,--colors", check_colours, "alphabet size (default: largest digit + 1)");

  int pitch = 24;
  auto* ren = app.add_subcommand("render", "draw a pattern file as a PNG of coloured spots");
  ren->add_option("file", file, "pattern file")->required();
  ren->add_option("-o,--output", out, "PNG to write")->required();
  ren->add_option("--pitch", pitch, "pixels between spots")->check(CLI::Range(4, 200));

  common::require_finite_numbers(app);
  if (const int rc = common::parse_command_line(app, argc, argv, "pattern"); rc >= 0) return rc;
  try {
    if (*gen) {
      gp.window = {window, window};
      return run_generate(gp, out);
    }
    if (*chk) return run_check(file, {window, window}, check_colours);
    if (*ren) return run_render(file, out, pitch);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 2;
  }
  return 0;
}
