// The per-iteration trace's columns: `cellsim serve` and the in-process runner write the
// same, so the two-process lockstep trace can be compared with the in-process one.
#pragma once

namespace sim {

inline constexpr const char* kTraceHeader =
    "t,vx,vy,vz,wx,wy,wz,error_norm,decoded,matched,translation_error_m,rotation_error_deg,robot_limits";

}  // namespace sim
