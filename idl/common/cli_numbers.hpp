// Numbers from the command line are checked like numbers from a file (issue 18, item 16):
// CLI11 reads "nan", "inf" and 1e300 as doubles and its Range check lets NaN through (every
// comparison with NaN is false), so `--gain nan` once reached a worker thread and aborted a
// campaign. Header-only, for the apps' command lines (CLI11).
#pragma once

#include "common/exit_codes.hpp"

#include <stdexcept>
#include <vector>
#include <utility>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>

#include "common/decimal_number.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace common {

// The bound every number of every command line stays within, unless its own range is tighter.
inline constexpr double kMaxCliMagnitude = 1e9;

// A finite number in [lo, hi].
inline CLI::Validator finite_in(double lo, double hi) {
  char desc[96];
  std::snprintf(desc, sizeof desc, "finite in [%g, %g]", lo, hi);
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        const std::optional<double> parsed = decimal_number(text);  // not strtod's "0x10" or "inf"
        const double v = parsed.value_or(0);
        if (!parsed || v < lo || v > hi) {
          char why[160];
          std::snprintf(why, sizeof why, "'%.40s' is not a finite number in [%g, %g]", text.c_str(), lo, hi);
          return why;
        }
        return "";
      },
      desc);
}

// A whole number in [0, 2^64): digits only. CLI11 reads "-1" into an unsigned flag as 2^64 - 1
// and "0x10" as 16; a seed given so is a typo, not a draw.
inline CLI::Validator whole_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const bool digits = !text.empty() && text.size() <= 20 && text.find_first_not_of("0123456789") == std::string::npos;
        if (!digits || (text.size() == 20 && text > "18446744073709551615"))
          return "'" + text.substr(0, 40) + "' is not a whole number from 0 to 18446744073709551615";
        return "";
      },
      "WHOLE");
}

// A flag's value checked after parsing (flags are untrusted input like any file: NaN and
// absurd values are refused with the flag's name).
inline void require_within(const char* flag, double v, double lo, double hi) {
  if (!(v >= lo && v <= hi))
    throw std::invalid_argument(std::string(flag) + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                                "], got " + std::to_string(v));
}

// Every floating-point option of `app` and of its subcommands, at any depth, gets the finite check
// with the common bound (a tighter range given at the option still holds): no number escapes
// the check because its option was added without one.
inline void require_finite_numbers(CLI::App& app) {
  for (CLI::Option* o : app.get_options()) {
    const std::string t = o->get_type_name();
    // integers need no such check: CLI11 refuses "nan", "inf" and 1e300 for them, and a seed
    // may use all 64 bits
    // (named in no --help: the option's own range says more, and the common bound on every
    // number of every command only made the help text noisy)
    if (t.rfind("FLOAT", 0) == 0) o->check(finite_in(-kMaxCliMagnitude, kMaxCliMagnitude).description(""));
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) require_finite_numbers(*sub);
}

// Parses like CLI11_PARSE, but a bad command line is one line ("<program>: <what>; see --help").
inline int parse_command_line(CLI::App& app, int argc, char** argv, const char* program) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string what = e.what();
    for (char& ch : what)
      if (ch == '\n') ch = ' ';
    std::fprintf(stderr, "%s: %s (see --help)\n", program, what.c_str());
    return exit_code::kUsage;
  }
  return -1;  // parsed: go on
}

// A CLI's subcommands: each with what it runs once the command line is parsed.
using Subcommands = std::vector<std::pair<CLI::App*, std::function<int()>>>;

// Runs the subcommand the command line chose; an error it throws is one line,
// "<program>: <what>", and exit code 1 (exit_code::kRefused).
inline int run_subcommand(const Subcommands& commands, const char* program) {
  try {
    for (const auto& [sub, run] : commands)
      if (*sub) return run();
  } catch (const std::exception& e) {
    std::string what = e.what();
    for (char& ch : what)
      if (ch == '\n' || ch == '\r') ch = ' ';
    std::fprintf(stderr, "%s: %s\n", program, what.c_str());
    return exit_code::kRefused;
  }
  return exit_code::kDone;
}

}  // namespace common
