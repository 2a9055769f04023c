#include "common/strict_yaml.hpp"

#include "common/regular_file.hpp"

#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <vector>

namespace common {

std::string printable(std::string_view text, std::size_t max_chars) {
  std::string out;
  for (const char ch : text) {
    if (out.size() >= max_chars) {
      out += "...";
      break;
    }
    const auto b = static_cast<unsigned char>(ch);
    if (b >= 0x20 && b < 0x7f) {
      out.push_back(ch);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", b);
      out += hex;
    }
  }
  return out;
}

namespace {

std::string quoted(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + printable(n.Scalar()) + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "nothing";
}

// Walks the whole tree once: counts nodes (aliases count every time they are reached) and
// rejects repeated keys, which yaml-cpp keeps without a word.
void check_tree(const std::filesystem::path& file, const YAML::Node& root) {
  struct Item {
    YAML::Node node;
    std::string path;
    int depth;
  };
  std::vector<Item> stack{{root, "", 0}};
  std::size_t visited = 0;
  while (!stack.empty()) {
    Item it = std::move(stack.back());
    stack.pop_back();
    if (++visited > kMaxYamlNodes)
      throw ConfigError(file.string() + ": more than " + std::to_string(kMaxYamlNodes) +
                        " YAML nodes (aliases expanding without bound?)");
    if (it.depth > 64)
      throw ConfigError(file.string() + ": " + printable(it.path, 60) + ": nested more than 64 levels deep");
    const auto child = [&](const std::string& key) { return it.path.empty() ? key : it.path + "." + key; };
    if (it.node.IsMap()) {
      std::set<std::string> seen;
      for (const auto& kv : it.node) {
        if (!kv.first.IsScalar())
          throw ConfigError(file.string() + ": " + (it.path.empty() ? "(top level)" : it.path) +
                            ": a key must be a plain word, got " + quoted(kv.first));
        const std::string key = kv.first.Scalar();
        if (!seen.insert(key).second)
          throw ConfigError(file.string() + ": " + child(printable(key)) + ": key given twice");
        stack.push_back({kv.second, child(printable(key)), it.depth + 1});
      }
    } else if (it.node.IsSequence()) {
      for (std::size_t i = 0; i < it.node.size(); ++i)
        stack.push_back({it.node[i], it.path + "[" + std::to_string(i) + "]", it.depth + 1});
    }
  }
}

}  // namespace

YAML::Node load_yaml_file(const std::filesystem::path& file, const std::string& what) {
  std::string text;
  try {
    text = read_regular_file(file, kMaxYamlBytes, what);
  } catch (const FileError& e) {
    throw ConfigError(e.what());
  }
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(file.string() + ": line " + std::to_string(e.mark.line + 1) + ": YAML syntax error: " +
                      printable(e.msg));
  }
  if (!root.IsMap()) throw ConfigError(file.string() + ": must be a mapping of keys (an empty or non-YAML file?)");
  check_tree(file, root);
  return root;
}

Reader::Reader(std::filesystem::path file, YAML::Node node, std::string path)
    : file_(std::move(file)), node_(std::move(node)), path_(std::move(path)) {}

void Reader::fail(const std::string& what) const {
  throw ConfigError(file_.string() + ": " + (path_.empty() ? "(top level)" : path_) + ": " + what);
}

std::string Reader::join(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

void Reader::child_fail(const std::string& key, const std::string& what) const {
  throw ConfigError(file_.string() + ": " + join(printable(key)) + ": " + what);
}

std::string Reader::spelling() const { return quoted(node_); }

void Reader::only_keys(std::initializer_list<const char*> allowed) const {
  only_keys(std::vector<std::string>(allowed.begin(), allowed.end()));
}

void Reader::only_keys(const std::vector<std::string>& allowed) const {
  if (!node_.IsMap()) fail("must be a mapping, got " + quoted(node_));
  const std::set<std::string> ok(allowed.begin(), allowed.end());
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) fail("a key must be a plain word, got " + quoted(kv.first));
    const std::string key = kv.first.Scalar();
    if (!ok.count(key)) {
      std::string list;
      for (const auto& k : ok) list += (list.empty() ? "" : ", ") + k;
      child_fail(key, "unknown key (expected one of: " + list + ")");
    }
  }
}

bool Reader::has(const char* key) const { return node_.IsMap() && node_[key]; }

Reader Reader::at(const char* key) const {
  if (!has(key)) child_fail(key, "missing");
  return Reader(file_, node_[key], join(key));
}

Reader Reader::at(std::size_t i) const { return Reader(file_, node_[i], path_ + "[" + std::to_string(i) + "]"); }

std::size_t Reader::size() const {
  if (!node_.IsSequence()) fail("must be a list, got " + quoted(node_));
  return node_.size();
}

std::size_t Reader::size_at_most(std::size_t max) const {
  const std::size_t n = size();
  if (n > max) fail("has " + std::to_string(n) + " entries, more than the limit of " + std::to_string(max));
  return n;
}

double Reader::number() const {
  if (!node_.IsScalar()) fail("must be a number, got " + quoted(node_));
  double v = 0;
  try {
    v = node_.as<double>();
  } catch (const YAML::Exception&) {
    fail("must be a number, got " + quoted(node_));
  }
  if (!std::isfinite(v)) fail("must be a finite number, got " + quoted(node_));
  return v;
}

double Reader::positive() const {
  const double v = number();
  if (!(v > 0)) fail("must be positive, got " + quoted(node_));
  return v;
}

double Reader::non_negative() const {
  const double v = number();
  if (v < 0) fail("must be >= 0, got " + quoted(node_));
  return v;
}

double Reader::in_range(double lo, double hi) const {
  const double v = number();
  if (v < lo || v > hi) {
    std::ostringstream s;
    s << "must be in [" << lo << ", " << hi << "], got " << quoted(node_);
    fail(s.str());
  }
  return v;
}

int Reader::integer_in(int lo, int hi) const {
  const double v = number();
  if (v != std::floor(v) || v < lo || v > hi)
    fail("must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got " + quoted(node_));
  return static_cast<int>(v);
}

std::uint64_t Reader::unsigned_integer() const {
  if (!node_.IsScalar()) fail("must be a non-negative integer, got " + quoted(node_));
  const std::string& s = node_.Scalar();
  if (s.empty() || s.size() > 20 || s.find_first_not_of("0123456789") != std::string::npos)
    fail("must be a non-negative integer, got " + quoted(node_));
  try {
    return std::stoull(s);
  } catch (const std::exception&) {
    fail("must be a non-negative integer below 2^64, got " + quoted(node_));
  }
}

bool Reader::boolean() const {
  if (!node_.IsScalar()) fail("must be true or false, got " + quoted(node_));
  const std::string& s = node_.Scalar();
  if (s == "true" || s == "True" || s == "yes") return true;
  if (s == "false" || s == "False" || s == "no") return false;
  fail("must be true or false, got " + quoted(node_));
}

std::string Reader::text(std::size_t max_chars) const {
  if (!node_.IsScalar()) fail("must be a string, got " + quoted(node_));
  const std::string& s = node_.Scalar();
  if (s.size() > max_chars) fail("is " + std::to_string(s.size()) + " characters, more than " + std::to_string(max_chars));
  for (const char ch : s)
    if (static_cast<unsigned char>(ch) < 0x20) fail("contains a control character: " + quoted(node_));
  return s;
}

std::filesystem::path Reader::existing_file() const {
  std::filesystem::path p = text();
  if (p.is_relative()) p = file_.parent_path() / p;
  p = p.lexically_normal();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec)) fail("file not found: " + printable(p.string(), 200));
  return p;
}

}  // namespace common
