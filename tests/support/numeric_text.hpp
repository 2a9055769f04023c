// Comparing stored results across machines: bit-reproducibility is promised on one machine,
// not across CPUs (another SIMD width or libm rounds the last digit differently: an EPYC with
// AVX-512 gave ...837 where the golden file says ...836). Text is compared token by token:
// words exactly, numbers within a stated tolerance.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

namespace cell_test {

// The tolerance every cross-machine comparison of the project states: 1e-6 relative, or
// 1e-9 absolute near zero (the traces' nine significant digits differ in the last one).
inline constexpr double kCrossMachineRelative = 1e-6, kCrossMachineAbsolute = 1e-9;

inline std::vector<std::string> numeric_tokens(const std::string& text) {
  std::vector<std::string> out;
  std::string cur;
  for (char ch : text) {
    const bool sep = ch == ',' || ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r' || ch == ':' || ch == '[' ||
                     ch == ']' || ch == '{' || ch == '}' || ch == '"';
    if (sep) {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
      if (ch == '\n') out.push_back("\n");  // rows must line up too
    } else {
      cur += ch;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

inline bool as_number(const std::string& t, double& v) {
  char* end = nullptr;
  v = std::strtod(t.c_str(), &end);
  return !t.empty() && end == t.c_str() + t.size();
}

// "" when `a` and `b` hold the same words and numbers within the tolerance; otherwise the
// first difference, with its token index.
inline std::string numeric_difference(const std::string& a, const std::string& b,
                                      double rel = kCrossMachineRelative, double abs = kCrossMachineAbsolute) {
  const auto ta = numeric_tokens(a), tb = numeric_tokens(b);
  if (ta.size() != tb.size())
    return std::to_string(ta.size()) + " tokens against " + std::to_string(tb.size());
  std::size_t row = 1;
  for (std::size_t i = 0; i < ta.size(); ++i) {
    if (ta[i] == "\n") ++row;
    if (ta[i] == tb[i]) continue;
    double x = 0, y = 0;
    if (as_number(ta[i], x) && as_number(tb[i], y) && std::abs(x - y) <= std::max(abs, rel * std::max(std::abs(x), std::abs(y))))
      continue;
    return "row " + std::to_string(row) + ": '" + ta[i] + "' against '" + tb[i] + "'";
  }
  return "";
}

// A large text of numbers (features.jsonl, 2 MB) kept small: per line, how many numbers it
// holds, their sum and the sum of their magnitudes (17 digits), one line each.
inline std::string numeric_digest(const std::string& text) {
  std::ostringstream out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::size_t n = 0;
    double sum = 0, mag = 0, v = 0;
    for (const auto& t : numeric_tokens(line))
      if (as_number(t, v)) {
        ++n;
        sum += v;
        mag += std::abs(v);
      }
    char buf[96];
    std::snprintf(buf, sizeof buf, "%zu,%.17g,%.17g\n", n, sum, mag);
    out << buf;
  }
  return out.str();
}

// Two digests within the tolerance: equal counts, and sums within `rel` of the magnitudes
// (a sum that cancels near zero is judged against the size of what it adds up).
inline std::string digest_difference(const std::string& a, const std::string& b, double rel = kCrossMachineRelative) {
  std::istringstream ia(a), ib(b);
  std::string la, lb;
  for (std::size_t row = 1;; ++row) {
    const bool ga = static_cast<bool>(std::getline(ia, la)), gb = static_cast<bool>(std::getline(ib, lb));
    if (!ga && !gb) return "";
    if (ga != gb) return "row " + std::to_string(row) + ": one digest is longer";
    unsigned long na = 0, nb = 0;
    double sa = 0, sb = 0, ma = 0, mb = 0;
    if (std::sscanf(la.c_str(), "%lu,%lf,%lf", &na, &sa, &ma) != 3 || std::sscanf(lb.c_str(), "%lu,%lf,%lf", &nb, &sb, &mb) != 3)
      return "row " + std::to_string(row) + ": not a digest line";
    const double scale = std::max({1.0, ma, mb});
    if (na != nb || std::abs(sa - sb) > rel * scale || std::abs(ma - mb) > rel * scale)
      return "row " + std::to_string(row) + ": '" + la + "' against '" + lb + "'";
  }
}

}  // namespace cell_test
