// --help as a user reads it (issue 43, item 4): an option's value as its kind and range,
// "--runs INT in [1, 1000000] (default 20)", not CLI11's validator chain
// ("INT:INT in [1 - 1000000]=20", "UINT:WHOLE", "FLOAT:finite in [0, 100]"). Header-only, for
// the apps' command lines; set on the app before its subcommands are added (they inherit it).
#pragma once

#include <CLI/CLI.hpp>

#include "common/progress.hpp"
#include <memory>
#include <regex>
#include <string>

namespace common {

// "INT:INT in [1 - 1000000]" -> "INT in [1, 1000000]"; "UINT:WHOLE" -> "UINT"; "INT:POSITIVE"
// -> "INT > 0"; "FLOAT:finite in [0, 100]" -> "FLOAT in [0, 100]"; "TEXT:FILE" -> "FILE"
inline std::string plain_type(const std::string& type) {
  const std::size_t colon = type.find(':');
  if (colon == std::string::npos) return type;
  std::string base = type.substr(0, colon), rest = type.substr(colon + 1);
  if (rest == "FILE" || rest == "DIR" || rest == "PATH(existing)" || rest == "PATH(non-existing)") return rest;
  if (rest == "WHOLE" || rest == "NONNEGATIVE") return base + (base == "UINT" ? "" : " >= 0");
  if (rest == "POSITIVE") return base + " > 0";
  static const std::regex range(R"(^(?:\w+ )?in \[(\S+) - (\S+)\]$)"), finite(R"(^finite in (\[.*\])$)");
  std::smatch m;
  if (std::regex_match(rest, m, range)) return base + " in [" + m[1].str() + ", " + m[2].str() + "]";
  if (std::regex_match(rest, m, finite)) return base + " in " + m[1].str();
  return base + " (" + rest + ")";
}

class PlainHelp : public CLI::Formatter {
 public:
  std::string make_option_opts(const CLI::Option* opt) const override {
    if (!opt->get_option_text().empty()) return " " + opt->get_option_text();
    std::string out;
    if (opt->get_type_size() != 0) {
      if (!opt->get_type_name().empty()) out += " " + plain_type(opt->get_type_name());
      if (opt->get_expected_max() == CLI::detail::expected_max_vector_size) out += " ...";
      else if (opt->get_expected_min() > 1) out += " x " + std::to_string(opt->get_expected());
      if (!opt->get_default_str().empty()) out += " (default " + opt->get_default_str() + ")";
      if (opt->get_required()) out += " REQUIRED";
    }
    return out;
  }
};

inline void plain_help(CLI::App& app) {
  app.formatter(std::make_shared<PlainHelp>());
  app.get_formatter()->column_width(34);
}

// -q/--quiet and -v/--verbose (common::verbosity), before or after the subcommand: set on the
// app before its subcommands are added (they inherit the fallthrough)
inline void verbosity_flags(CLI::App& app) {
  auto* q = app.add_flag_callback("-q,--quiet", [] { verbosity() = Verbosity::kQuiet; },
                                  "no progress lines: results, warnings and errors only");
  auto* v = app.add_flag_callback("-v,--verbose", [] { verbosity() = Verbosity::kVerbose; },
                                  "more: a line per run of a campaign or study");
  q->excludes(v);
  app.fallthrough();
}

}  // namespace common
