// Control-law cost per iteration for 50, 400 and 4096 points, against the textbook
// computation of the same law (explicit SVD pseudo-inverse of the stacked matrix).
#include <benchmark/benchmark.h>

#include <random>

#include "servo/control/control_law.hpp"

namespace {

std::vector<control::MatchedPoint> points(int n) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-0.3, 0.3), z(0.7, 1.1), d(-0.01, 0.01);
  std::vector<control::MatchedPoint> p;
  for (int i = 0; i < n; ++i) {
    const double x = u(rng), y = u(rng);
    p.push_back({i / 64, i % 64, x + d(rng), y + d(rng), x, y, z(rng), z(rng)});
  }
  return p;
}

void BM_ControlLaw(benchmark::State& state) {
  const auto p = points(static_cast<int>(state.range(0)));
  control::ControlLawOptions params;
  params.model = control::InteractionModel::kMean;  // the costliest model: two matrices per point
  for (auto _ : state) benchmark::DoNotOptimize(control::compute_control(p, params).twist);
}

void BM_Textbook(benchmark::State& state) {
  const auto p = points(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    Eigen::VectorXd xy(2 * p.size()), xys(2 * p.size()), Z(p.size()), Zs(p.size()), e(2 * p.size());
    for (std::size_t i = 0; i < p.size(); ++i) {
      xy[2 * i] = p[i].x, xy[2 * i + 1] = p[i].y, xys[2 * i] = p[i].x_star, xys[2 * i + 1] = p[i].y_star;
      Z[i] = *p[i].z, Zs[i] = *p[i].z_star;
      e[2 * i] = p[i].x - p[i].x_star, e[2 * i + 1] = p[i].y - p[i].y_star;
    }
    const Eigen::MatrixXd L = 0.5 * (control::stacked_interaction_matrix(xy, Z) + control::stacked_interaction_matrix(xys, Zs));
    const Eigen::VectorXd v = -0.5 * (control::pseudo_inverse(L, 1e-6) * e);
    benchmark::DoNotOptimize(v.data());
  }
}

}  // namespace

BENCHMARK(BM_Textbook)->Name("control_50/baseline_svd_pinv")->Arg(50)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ControlLaw)->Name("control_50/ours")->Arg(50)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Textbook)->Name("control_400/baseline_svd_pinv")->Arg(400)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ControlLaw)->Name("control_400/ours")->Arg(400)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Textbook)->Name("control_4096/baseline_svd_pinv")->Arg(4096)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ControlLaw)->Name("control_4096/ours")->Arg(4096)->Unit(benchmark::kMicrosecond);
