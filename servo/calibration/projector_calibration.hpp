// The projector's calibration file, as `cellsim calibration` writes it and the servo reads it.
#pragma once

#include <filesystem>
#include <string>

#include "servo/calibration/projector_model.hpp"
#include "servo/pattern/marray.hpp"

namespace calibration {

// Reads the projector's calibration (YAML: fx, fy, cx, cy, spot_pitch_px, rows, cols,
// position_m [x, y, z], orientation_xyzw [x, y, z, w] in the world): what triangulation and
// the decoder's epipolar check need. Throws std::runtime_error naming the file and the key.
calibration::ProjectorModel load_projector_calibration(const std::filesystem::path& file);

// Writes `m` in the format load_projector_calibration reads, `comment` as its first line (a
// "# " line: where the calibration came from). Throws std::runtime_error naming the file when
// it cannot be written.
void write_projector_calibration(const calibration::ProjectorModel& m, const std::filesystem::path& file,
                                 const std::string& comment);

// A projector calibration is for one pattern: its rows and columns must match.
void check_projector_against_pattern(const calibration::ProjectorModel& m, const pattern::MArray& marray,
                                     const std::filesystem::path& pattern_file);

}  // namespace calibration
