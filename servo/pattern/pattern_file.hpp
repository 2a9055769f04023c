// The pattern file: one line per row, one digit (the colour index) per spot, no separators.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

#include "servo/pattern/marray.hpp"

namespace pattern {

// A malformed pattern file. what() is one line: "<file>: <what is wrong>".
class PatternFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The largest pattern any tool reads: 1024 x 1024 spots (about 1 MB of file).
inline constexpr int kMaxPatternSide = 1024;

// Parses the text of a pattern file. `source` names it in errors. When `colours` > 0 every
// digit must be below it; otherwise k is the largest digit + 1 (at least 2).
MArray parse_marray(const std::string& text, const std::string& source, int colours = 0);

// Reads and parses a pattern file and, with a window, also checks the window property:
// a repeated window is an error, since the decoder could not tell its two places apart.
MArray read_marray(const std::filesystem::path& path, int colours = 0);
MArray load_pattern(const std::filesystem::path& path, WindowShape window, int colours = 0);

std::string format_marray(const MArray& array);
void write_marray(const std::filesystem::path& path, const MArray& array);

}  // namespace pattern
