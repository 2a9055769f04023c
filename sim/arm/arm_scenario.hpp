// The scenario a run uses: read from its file (sim/scenario), then its arm resolved from the
// URDF, the joint angles of the desired and initial camera poses by IK from home (or their
// poses by FK, when the file gives joint angles), and its workspace settled on those poses.
// Only what builds a cell needs this; a scenario's spec alone pulls in no URDF, KDL or Bullet.
#pragma once

#include <filesystem>

#include "sim/scenario/scenario.hpp"

namespace sim {

// Throws ScenarioError, one line naming the file and the key: every error read_scenario
// reports, a URDF that does not load, joint angles out of the arm's limits, a pose the arm
// cannot reach, a camera outside the workspace.
Scenario load_scenario(const std::filesystem::path& file);

// The arm of a scenario read with an arm: its model, chain and joint angles (ScenarioError
// naming the scenario's key when it cannot be).
void resolve_arm(Scenario& scenario);

}  // namespace sim
