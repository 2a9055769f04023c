// The cell compiler: what a run renders from, built once from a resolved scenario, and the
// robot the scenario names. Apart from the renderer (sim/render), which links no arm.
#pragma once

#include <filesystem>
#include <memory>

#include "sim/render/cell.hpp"
#include "sim/robot/robot.hpp"
#include "sim/scenario/scenario.hpp"

namespace sim {

// The spec resolved: its arm (when it has one: sim::resolve_arm) and its workspace. Throws
// ScenarioError, one line naming the file and the key: a URDF that does not load, joint angles
// out of the arm's limits, a pose the arm cannot reach, a camera outside the workspace.
ResolvedScenario resolve(Scenario spec);

// read_scenario, then resolve: every error either reports.
ResolvedScenario load_scenario(const std::filesystem::path& file);

// Loads meshes and the pattern named by the scenario. Throws MeshError or
// pattern::PatternFileError (one line naming the file) when one is unusable.
std::unique_ptr<Cell> build_cell(const ResolvedScenario& scenario);

// The robot the scenario names, at the desired pose: the free-flying camera, or the arm
// (its desired and initial poses pinned to the joint angles resolved at load), believing
// `belief` when given (a run that drew its own errors), else what the scenario's calibration
// errors make its controller believe (scenario_errors).
std::unique_ptr<Robot> make_robot(const Cell& cell, const RobotBelief* belief = nullptr);

}  // namespace sim
