// Strict reading of the project's YAML files (scenarios, servo configurations, projector
// calibrations): every value is checked at load, and every failure is one line that names
// the file, the key, the value and what was expected. A leaf library (std + yaml-cpp): the
// sim and the servo both use it, so a user meets the same rules in every file.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <optional>
#include <string_view>

namespace common {

// A malformed file. what() is one line: "<file>: <key>: <what is wrong>".
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Bytes from an untrusted source made safe for a one-line message: printable ASCII kept,
// everything else as \xNN, cut to `max_chars` with "..." so a megabyte of garbage stays short.
std::string printable(std::string_view text, std::size_t max_chars = 80);

// Limits that hold for every YAML file before its values are read: its size, and the number
// of nodes a walk visits (an alias bomb expands to billions of nodes from a few kB).
inline constexpr std::uintmax_t kMaxYamlBytes = 1 << 20;
inline constexpr std::size_t kMaxYamlNodes = 100000;

// Parses `file` and checks the limits and that no mapping repeats a key. Throws ConfigError.
YAML::Node load_yaml_file(const std::filesystem::path& file, const std::string& what = "file");

// A node with the key path that leads to it.
class Reader {
 public:
  Reader(std::filesystem::path file, YAML::Node node, std::string path = "");

  [[noreturn]] void fail(const std::string& what) const;

  // Rejects keys not in `allowed`: a misspelt key must not be silently ignored.
  void only_keys(std::initializer_list<const char*> allowed) const;
  void only_keys(const std::vector<std::string>& allowed) const;
  bool has(const char* key) const;
  Reader at(const char* key) const;       // throws when missing
  Reader at(std::size_t i) const;
  std::size_t size() const;               // a list's length; throws when not a list
  std::size_t size_at_most(std::size_t max) const;

  double number() const;                  // finite
  double positive() const;
  double non_negative() const;
  double in_range(double lo, double hi) const;
  int integer_in(int lo, int hi) const;   // an integer value (2, 2.0) in [lo, hi]
  std::uint64_t unsigned_integer() const;
  bool boolean() const;
  std::string text(std::size_t max_chars = 4096) const;
  template <std::size_t N>
  std::array<double, N> numbers() const {
    if (!node_.IsSequence() || node_.size() != N) fail("must be a list of " + std::to_string(N) + " numbers");
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) out[i] = at(i).number();
    return out;
  }
  template <std::size_t N>
  std::array<double, N> numbers_in(double lo, double hi) const {
    if (!node_.IsSequence() || node_.size() != N) fail("must be a list of " + std::to_string(N) + " numbers");
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) out[i] = at(i).in_range(lo, hi);
    return out;
  }
  // A file path, resolved against the folder of the file being read, that must exist.
  std::filesystem::path existing_file() const;

  const std::string& path() const { return path_; }
  const std::filesystem::path& file() const { return file_; }
  const YAML::Node& node() const { return node_; }
  // the value as the file spells it, safe to print
  std::string spelling() const;

 private:
  std::string join(const std::string& key) const;
  [[noreturn]] void child_fail(const std::string& key, const std::string& what) const;

  std::filesystem::path file_;
  YAML::Node node_;
  std::string path_;
};

}  // namespace common
