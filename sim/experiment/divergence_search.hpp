// The seeded search behind the fig5 scenario (issue 13, item 1). The paper's Fig. 5 shows a
// cylinder, five spots and two camera poses for which L(s*, Z-hat = 0.9) diverges while
// L(s*, Z*) and L(s, Z) converge; its geometry cannot be read back from the figure. This
// draws configurations of the same kind (which five spots are lit, a quincunx on the
// object, and the initial offset) and keeps those where, with the simulator's true image
// positions:
//   - L(s*, Z-hat) stops "diverging" (|e| above twice its first value) while the camera
//     moves away from the desired pose (the translation error grew),
//   - L(s*, Z*) converges, and L(s, Z) converges in fewer iterations,
//   - the five spots are seen from both poses.
// The kept one with the smallest initial displacement is the least contrived.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "sim/experiment/experiment.hpp"

namespace experiment {

struct DivergenceSearchOptions {
  int tries = 200;
  std::uint64_t seed = 1;
  double z_hat_m = 0.9;
  double gain = 0.5;
  int max_iterations = 600;
  double max_translation_cm = 25;         // each axis of the offset in [-this, this]
  double max_tilt_deg = 20;               // about the camera's x and y axes
  double max_roll_deg = 150;              // about the optical axis
  bool vary_spots = true;                 // false: the scenario's only_spots
  int threads = 2;
  std::filesystem::path out_dir;          // candidates.csv, best.yaml (nothing when empty)
};

struct DivergenceCandidate {
  int index = 0;
  std::vector<std::array<int, 2>> spots;
  std::array<double, 6> offset{};         // tx ty tz (cm) rx ry rz (deg), the paper's convention
  ExperimentResult constant_depth, desired, current;  // traces dropped
  double initial_translation_m = 0;
  bool kept = false;
  double displacement = 0;                // |t| / 10 cm + |r| / 10 deg: the ranking of kept ones
  std::string why_not;                    // the first criterion it failed
};

struct DivergenceSearchResult {
  std::vector<DivergenceCandidate> candidates;
  int best = -1;                          // index into candidates, -1 when none was kept
};

DivergenceSearchResult search_divergence(const sim::Scenario& scenario, const DivergenceSearchOptions& options);

}  // namespace experiment
