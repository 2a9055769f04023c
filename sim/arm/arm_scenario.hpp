// A scenario's arm resolved (for sim::resolve, sim/cell): its model from the
// URDF, the joint angles of the desired and initial camera poses by IK from home (or their
// poses by FK, when the file gives joint angles), and its workspace settled on those poses.
// Only what builds a cell needs this; a scenario's spec alone pulls in no URDF, KDL or Bullet.
#pragma once

#include <filesystem>

#include "sim/scenario/scenario.hpp"

namespace sim {

// The arm of a scenario read with an arm: its model, chain and joint angles (ScenarioError
// naming the scenario's key when it cannot be).
void resolve_arm(Scenario& scenario);

}  // namespace sim
