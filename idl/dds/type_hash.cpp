#include "dds/type_hash.hpp"

#include <cctype>
#include <cstdint>
#include <cstdio>
#include <set>
#include <sstream>
#include <stdexcept>

namespace cell_dds {
namespace {

// ---- IDL tokens: identifiers (scoped names joined), numbers, punctuation
std::vector<std::string> tokenize(const std::string& text) {
  std::vector<std::string> toks;
  std::size_t i = 0;
  const std::size_t n = text.size();
  while (i < n) {
    const char c = text[i];
    if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
    } else if (c == '/' && i + 1 < n && text[i + 1] == '/') {
      while (i < n && text[i] != '\n') ++i;
    } else if (c == '/' && i + 1 < n && text[i + 1] == '*') {
      const std::size_t e = text.find("*/", i + 2);
      i = e == std::string::npos ? n : e + 2;
    } else if (c == '#') {
      while (i < n && text[i] != '\n') ++i;
    } else if (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '@') {
      std::size_t j = i;
      while (j < n && (std::isalnum(static_cast<unsigned char>(text[j])) || text[j] == '_' || text[j] == '@' ||
                       (text[j] == ':' && j + 1 < n && text[j + 1] == ':') || (text[j] == ':' && j > 0 && text[j - 1] == ':')))
        ++j;
      toks.push_back(text.substr(i, j - i));
      i = j;
    } else {
      toks.emplace_back(1, c);
      ++i;
    }
  }
  return toks;
}

int basic_type_id(const std::string& t) {
  static const std::map<std::string, int> ids{
      {"int8", 2},   {"uint8", 3},   {"int16", 4},  {"uint16", 5},   {"int32", 6},   {"uint32", 7},
      {"int64", 8},  {"uint64", 9},  {"float", 10}, {"double", 11},  {"char", 13},   {"wchar", 14},
      {"boolean", 15}, {"octet", 16}, {"string", 17}, {"wstring", 18}};
  const auto it = ids.find(t);
  return it == ids.end() ? 0 : it->second;
}

}  // namespace

std::string ros_type_name(const std::string& dds) {
  // a::msg::dds_::T_ -> a/msg/T
  std::string out;
  std::size_t start = 0;
  while (true) {
    const std::size_t e = dds.find("::", start);
    const std::string part = dds.substr(start, e == std::string::npos ? std::string::npos : e - start);
    if (part != "dds_") {
      if (!out.empty()) out += "/";
      out += part;
    }
    if (e == std::string::npos) break;
    start = e + 2;
  }
  if (!out.empty() && out.back() == '_') out.pop_back();
  return out;
}

// The subset of IDL fastddsgen's ROS 2 files use: modules, constants (skipped), annotations
// (skipped) and structs of basic, string, nested, array and sequence members.
class IdlParser {
 public:
  explicit IdlParser(const std::string& text) : t_(tokenize(text)) {}

  void parse(TypeDescriptions& out) {
    while (i_ < t_.size()) {
      if (t_[i_] == "module") {
        modules_.push_back(t_[i_ + 1]);
        i_ += 2;
        expect("{");
      } else if (t_[i_] == "}") {
        ++i_;
        if (i_ < t_.size() && t_[i_] == ";") ++i_;
        if (modules_.empty()) throw std::runtime_error("IDL: unbalanced '}'");
        modules_.pop_back();
      } else if (t_[i_] == "const") {
        while (i_ < t_.size() && t_[i_] != ";") ++i_;
        ++i_;
      } else if (t_[i_][0] == '@') {
        ++i_;
      } else if (t_[i_] == "struct") {
        parse_struct(out);
      } else {
        throw std::runtime_error("IDL: unexpected token '" + t_[i_] + "'");
      }
    }
  }

 private:
  void expect(const std::string& s) {
    if (i_ >= t_.size() || t_[i_] != s)
      throw std::runtime_error("IDL: expected '" + s + "' at token " + std::to_string(i_) + " ('" +
                               (i_ < t_.size() ? t_[i_] : "end") + "')");
    ++i_;
  }
  std::string scoped(const std::string& name) const {
    std::string s;
    for (const auto& m : modules_) s += m + "::";
    return s + name;
  }

  void parse_struct(TypeDescriptions& out) {
    const std::string name = ros_type_name(scoped(t_[i_ + 1]));
    i_ += 2;
    expect("{");
    std::vector<FieldDescription> fields;
    while (i_ < t_.size() && t_[i_] != "}") fields.push_back(parse_field());
    expect("}");
    expect(";");
    if (fields.empty()) fields.push_back({"structure_needs_at_least_one_member", 3, 0, 0, ""});
    out[name] = fields;
  }

  FieldDescription parse_field() {
    FieldDescription f;
    int suffix = 0;  // 48 array, 96 bounded sequence, 144 unbounded sequence
    std::string type;
    if (t_[i_] == "sequence") {
      i_ += 1;
      expect("<");
      type = t_[i_++];
      suffix = 144;
      if (t_[i_] == ",") {
        // a bounded sequence keeps its bound in the description, as rosidl's (capacity 8 for
        // sequence<string, 8>): without it SimStatus's hash was not ROS 2's
        f.capacity = std::stoi(t_[i_ + 1]);
        i_ += 2;
        suffix = 96;
      }
      expect(">");
    } else {
      type = t_[i_++];
      if ((type == "string" || type == "wstring") && t_[i_] == "<") {
        ++i_;
        f.string_capacity = std::stoi(t_[i_++]);
        expect(">");
      }
    }
    f.name = t_[i_++];
    if (t_[i_] == "[") {
      ++i_;
      f.capacity = std::stoi(t_[i_++]);
      expect("]");
      suffix = 48;
    }
    expect(";");
    int base = basic_type_id(type);
    if (base == 17 && f.string_capacity > 0) base = 21;
    if (base == 18 && f.string_capacity > 0) base = 22;
    if (base == 0) {
      if (type.find("::") == std::string::npos) throw std::runtime_error("IDL: unknown type '" + type + "'");
      base = 1;
      f.nested_type_name = ros_type_name(type);
    }
    f.type_id = base + suffix;
    return f;
  }

  std::vector<std::string> t_;
  std::vector<std::string> modules_;
  std::size_t i_ = 0;
};

void parse_idl_types(const std::string& text, TypeDescriptions& out) { IdlParser(text).parse(out); }

void parse_msg_type(const std::string& package, const std::string& type, const std::string& text,
                    TypeDescriptions& out) {
  // .msg spells some basic types otherwise than IDL
  static const std::map<std::string, std::string> msg_names{{"bool", "boolean"}, {"byte", "octet"},
                                                             {"float32", "float"}, {"float64", "double"}};
  std::vector<FieldDescription> fields;
  std::istringstream lines(text);
  int number = 0;
  for (std::string line; std::getline(lines, line);) {
    ++number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::string spelled, name;
    if (!(words >> spelled)) continue;
    const auto fail = [&](const std::string& why) {
      throw std::runtime_error(package + "/msg/" + type + ".msg:" + std::to_string(number) + ": " + why);
    };
    if (!(words >> name)) fail("a type without a field name");
    if (name.find('=') != std::string::npos || (words >> std::ws, words.peek() == '=')) continue;  // a constant
    FieldDescription f;
    f.name = name;
    int suffix = 0;
    std::string base_type = spelled;
    if (const auto bracket = spelled.find('['); bracket != std::string::npos) {
      base_type = spelled.substr(0, bracket);
      const std::string dims = spelled.substr(bracket);
      if (dims == "[]") suffix = 144;
      else if (dims.rfind("[<=", 0) == 0) {
        suffix = 96;  // bounded: its bound is the field's capacity, as rosidl hashes it
        f.capacity = std::stoi(dims.substr(3));
      } else {
        suffix = 48;
        f.capacity = std::stoi(dims.substr(1));
      }
    }
    if (const auto le = base_type.find("<="); le != std::string::npos) {
      f.string_capacity = std::stoi(base_type.substr(le + 2));
      base_type = base_type.substr(0, le);
    }
    const auto it = msg_names.find(base_type);
    int base = basic_type_id(it == msg_names.end() ? base_type : it->second);
    if (base == 17 && f.string_capacity > 0) base = 21;
    if (base == 18 && f.string_capacity > 0) base = 22;
    if (base == 0) {
      if (base_type == "char") fail("char is not supported");
      const auto slash = base_type.find('/');
      f.nested_type_name = slash == std::string::npos ? package + "/msg/" + base_type
                                                      : base_type.substr(0, slash) + "/msg/" + base_type.substr(slash + 1);
      base = 1;
    }
    f.type_id = base + suffix;
    fields.push_back(f);
  }
  if (fields.empty()) fields.push_back({"structure_needs_at_least_one_member", 3, 0, 0, ""});
  out[package + "/msg/" + type] = fields;
}

std::string hashable_json(const std::string& type_name, const TypeDescriptions& types) {
  const auto describe = [&](const std::string& name) {
    const auto it = types.find(name);
    if (it == types.end()) throw std::runtime_error("type hash: no description of " + name);
    std::string s = "{\"type_name\": \"" + name + "\", \"fields\": [";
    for (std::size_t k = 0; k < it->second.size(); ++k) {
      const FieldDescription& f = it->second[k];
      if (k) s += ", ";
      s += "{\"name\": \"" + f.name + "\", \"type\": {\"type_id\": " + std::to_string(f.type_id) +
           ", \"capacity\": " + std::to_string(f.capacity) + ", \"string_capacity\": " +
           std::to_string(f.string_capacity) + ", \"nested_type_name\": \"" + f.nested_type_name + "\"}}";
    }
    return s + "]}";
  };
  // every type reached from this one, sorted by name
  std::set<std::string> refs;
  std::vector<std::string> queue{type_name};
  while (!queue.empty()) {
    const std::string n = queue.back();
    queue.pop_back();
    const auto it = types.find(n);
    if (it == types.end()) throw std::runtime_error("type hash: no description of " + n);
    for (const auto& f : it->second)
      if (!f.nested_type_name.empty() && refs.insert(f.nested_type_name).second) queue.push_back(f.nested_type_name);
  }
  std::string s = "{\"type_description\": " + describe(type_name) + ", \"referenced_type_descriptions\": [";
  bool first = true;
  for (const auto& r : refs) {
    if (!first) s += ", ";
    first = false;
    s += describe(r);
  }
  return s + "]}";
}

std::string type_hash(const std::string& type_name, const TypeDescriptions& types) {
  return "RIHS01_" + sha256_hex(hashable_json(type_name, types));
}

std::vector<unsigned char> type_hash_user_data(const std::string& dds_type_name) {
  const auto& types = project_type_descriptions();
  const std::string name = ros_type_name(dds_type_name);
  if (!types.count(name)) return {};
  const std::string s = "typehash=" + type_hash(name, types) + ";";
  return {s.begin(), s.end()};
}

// ---- SHA-256 (FIPS 180-4)
std::string sha256_hex(const std::string& bytes) {
  static const std::uint32_t k[64] = {
      0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5, 0xd807aa98,
      0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786,
      0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8,
      0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13,
      0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819,
      0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a,
      0x5b9cca4f, 0x682e6ff3, 0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
      0xc67178f2};
  std::uint32_t h[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
  std::string m = bytes;
  const std::uint64_t bits = static_cast<std::uint64_t>(bytes.size()) * 8;
  m.push_back(static_cast<char>(0x80));
  while (m.size() % 64 != 56) m.push_back('\0');
  for (int s = 56; s >= 0; s -= 8) m.push_back(static_cast<char>((bits >> s) & 0xff));
  const auto rotr = [](std::uint32_t x, int n) { return (x >> n) | (x << (32 - n)); };
  for (std::size_t off = 0; off < m.size(); off += 64) {
    std::uint32_t w[64];
    for (int j = 0; j < 16; ++j)
      w[j] = static_cast<std::uint32_t>(static_cast<unsigned char>(m[off + 4 * j])) << 24 |
             static_cast<std::uint32_t>(static_cast<unsigned char>(m[off + 4 * j + 1])) << 16 |
             static_cast<std::uint32_t>(static_cast<unsigned char>(m[off + 4 * j + 2])) << 8 |
             static_cast<std::uint32_t>(static_cast<unsigned char>(m[off + 4 * j + 3]));
    for (int j = 16; j < 64; ++j) {
      const std::uint32_t s0 = rotr(w[j - 15], 7) ^ rotr(w[j - 15], 18) ^ (w[j - 15] >> 3);
      const std::uint32_t s1 = rotr(w[j - 2], 17) ^ rotr(w[j - 2], 19) ^ (w[j - 2] >> 10);
      w[j] = w[j - 16] + s0 + w[j - 7] + s1;
    }
    std::uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4], f = h[5], g = h[6], hh = h[7];
    for (int j = 0; j < 64; ++j) {
      const std::uint32_t t1 = hh + (rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25)) + ((e & f) ^ (~e & g)) + k[j] + w[j];
      const std::uint32_t t2 = (rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
      hh = g;
      g = f;
      f = e;
      e = d + t1;
      d = c;
      c = b;
      b = a;
      a = t1 + t2;
    }
    h[0] += a; h[1] += b; h[2] += c; h[3] += d; h[4] += e; h[5] += f; h[6] += g; h[7] += hh;
  }
  std::string hex;
  char buf[9];
  for (std::uint32_t v : h) {
    std::snprintf(buf, sizeof buf, "%08x", v);
    hex += buf;
  }
  return hex;
}

}  // namespace cell_dds
