#include "servo/pattern/pattern_file.hpp"

#include "common/output_file.hpp"
#include "common/regular_file.hpp"

#include <cstdio>
#include <sstream>

namespace pattern {

namespace {

// a byte of an untrusted file, safe to print
std::string shown_byte(char ch) {
  const auto b = static_cast<unsigned char>(ch);
  if (b >= 0x20 && b < 0x7f) return std::string("'") + ch + "'";
  char hex[8];
  std::snprintf(hex, sizeof hex, "\\x%02x", b);
  return hex;
}

}  // namespace

MArray parse_marray(const std::string& text, const std::string& source, int colours) {
  const auto fail = [&](int line, const std::string& what) {
    throw PatternFileError(source + (line > 0 ? ":" + std::to_string(line) : "") + ": " + what);
  };
  MArray a;
  std::istringstream in(text);
  std::string row;
  int line = 0;
  int max_digit = 0;
  while (std::getline(in, row)) {
    ++line;
    if (!row.empty() && row.back() == '\r') row.pop_back();
    if (row.empty()) {
      // trailing blank lines are tolerated; a blank line inside the array is not
      std::string rest;
      while (std::getline(in, rest))
        if (rest.find_first_not_of(" \t\r") != std::string::npos) fail(line, "blank line inside the array");
      break;
    }
    if (row.size() > static_cast<std::size_t>(kMaxPatternSide))
      fail(line, "row of " + std::to_string(row.size()) + " spots, more than the limit of " + std::to_string(kMaxPatternSide));
    if (a.rows >= kMaxPatternSide) fail(line, "more than " + std::to_string(kMaxPatternSide) + " rows (the limit)");
    if (a.rows == 0) a.cols = static_cast<int>(row.size());
    if (static_cast<int>(row.size()) != a.cols)
      fail(line, "ragged rows: this row has " + std::to_string(row.size()) + " spots, the first has " +
                     std::to_string(a.cols));
    for (std::size_t i = 0; i < row.size(); ++i) {
      const char ch = row[i];
      if (ch < '0' || ch > '9')
        fail(line, "wrong digit " + shown_byte(ch) + " at column " + std::to_string(i + 1) +
                       " (expected a colour index 0-9, no separators)");
      const int d = ch - '0';
      if (colours > 0 && d >= colours)
        fail(line, "wrong digit '" + std::string(1, ch) + "' at column " + std::to_string(i + 1) + ": the pattern has " +
                       std::to_string(colours) + " colours (0.." + std::to_string(colours - 1) + ")");
      max_digit = std::max(max_digit, d);
      a.cells.push_back(static_cast<std::uint8_t>(d));
    }
    ++a.rows;
  }
  if (a.rows == 0) fail(0, "empty pattern file");
  a.colours = colours > 0 ? colours : std::max(2, max_digit + 1);
  return a;
}

MArray read_marray(const std::filesystem::path& path, int colours) {
  // rows of kMaxPatternSide digits and their line ends, plus room for comments
  const std::uintmax_t limit = static_cast<std::uintmax_t>(kMaxPatternSide) * (kMaxPatternSide + 2) + 4096;
  std::string text;
  try {
    text = common::read_regular_file(path, limit, "pattern file");
  } catch (const common::FileError& e) {
    throw PatternFileError(e.what());
  }
  return parse_marray(text, path.string(), colours);
}

MArray load_pattern(const std::filesystem::path& path, WindowShape window, int colours) {
  MArray a = read_marray(path, colours);
  if (a.rows < window.rows || a.cols < window.cols)
    throw PatternFileError(path.string() + ": array " + std::to_string(a.rows) + " x " + std::to_string(a.cols) +
                           " is smaller than its " + std::to_string(window.rows) + " x " +
                           std::to_string(window.cols) + " window");
  const WindowPropertyReport rep = check_window_property(a, window);
  if (!rep.holds) {
    const auto& [p, q] = *rep.repeat;
    throw PatternFileError(path.string() + ": repeated window: the " + std::to_string(window.rows) + " x " +
                           std::to_string(window.cols) + " windows centred at (" +
                           std::to_string(p.first + window.rows / 2) + ", " + std::to_string(p.second + window.cols / 2) +
                           ") and (" + std::to_string(q.first + window.rows / 2) + ", " +
                           std::to_string(q.second + window.cols / 2) + ") are equal, so spots cannot be decoded");
  }
  return a;
}

std::string format_marray(const MArray& a) {
  std::string out;
  out.reserve(static_cast<std::size_t>(a.rows) * (a.cols + 1));
  for (int r = 0; r < a.rows; ++r) {
    for (int c = 0; c < a.cols; ++c) out.push_back(static_cast<char>('0' + a.at(r, c)));
    out.push_back('\n');
  }
  return out;
}

void write_marray(const std::filesystem::path& path, const MArray& a) {
  try {
    common::write_output_file(path, format_marray(a), "pattern");
  } catch (const common::FileError& e) {
    throw PatternFileError(e.what());
  }
}

}  // namespace pattern
