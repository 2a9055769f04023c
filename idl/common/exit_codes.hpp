// The exit codes of every command, one table (README.md, after the tools), so that a script or
// a Slurm job can tell how a run ended without reading its output.
#pragma once

namespace common::exit_code {

inline constexpr int kDone = 0;       // converged, or the command did what it was asked
inline constexpr int kRefused = 1;    // an input refused: a file, a value, a pose (one line says which)
inline constexpr int kUsage = 2;      // the command line itself: an unknown flag, a missing argument
inline constexpr int kWrongIds = 3;   // decode-sweep: the decoder named a spot wrongly
inline constexpr int kDiverged = 4;   // the run was stopped as diverging
inline constexpr int kCapped = 5;     // the iteration or frame cap came before convergence
inline constexpr int kStopped = 6;    // stopped before the end: a safe stop, a robot stop, a signal, cancelled
inline constexpr int kNotTaught = 7;  // the goal was never taught (no teach frame, teach refused)
inline constexpr int kNoneFound = 8;  // a search found nothing that meets its conditions (fig5-search)

}  // namespace common::exit_code
