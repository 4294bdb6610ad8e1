#include "fieldbus/canopen/eds.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/util/atomic_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::canopen {
namespace {

struct Section {
  std::string name;  // as written
  int line = 0;
  std::map<std::string, std::pair<std::string, int>> keys;  // lower-case key -> value, line
  const std::pair<std::string, int>* get(const std::string& key) const {
    const auto it = keys.find(key);
    return it == keys.end() ? nullptr : &it->second;
  }
};

std::optional<int64_t> parse_c_number(std::string_view s) noexcept {
  s = trim(s);
  if (s.empty()) return std::nullopt;
  bool neg = false;
  if (s[0] == '-' || s[0] == '+') {
    neg = s[0] == '-';
    s.remove_prefix(1);
  }
  if (s.empty()) return std::nullopt;
  int base = 10;
  if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
    base = 16;
    s.remove_prefix(2);
  } else if (s.size() > 1 && s[0] == '0') {
    base = 8;
    s.remove_prefix(1);
  }
  uint64_t v = 0;
  for (char c : s) {
    int d;
    if (c >= '0' && c <= '9') d = c - '0';
    else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    else return std::nullopt;
    if (d >= base) return std::nullopt;
    if (v > (UINT64_MAX - static_cast<uint64_t>(d)) / static_cast<uint64_t>(base)) return std::nullopt;
    v = v * static_cast<uint64_t>(base) + static_cast<uint64_t>(d);
  }
  return neg ? -static_cast<int64_t>(v) : static_cast<int64_t>(v);
}

bool parse_hex_u16(std::string_view s, uint16_t& out) noexcept {
  if (s.empty() || s.size() > 4) return false;
  uint32_t v = 0;
  for (char c : s) {
    int d;
    if (c >= '0' && c <= '9') d = c - '0';
    else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    else return false;
    v = v * 16 + static_cast<uint32_t>(d);
  }
  out = static_cast<uint16_t>(v);
  return true;
}

// "1018" -> index; "1018sub1" -> index + sub; other names -> false.
bool object_section(std::string_view name, uint16_t& index, std::optional<uint8_t>& sub, bool& other) {
  other = false;
  if (name.size() < 4) return false;
  uint16_t idx;
  if (!parse_hex_u16(name.substr(0, 4), idx)) return false;
  const std::string rest = to_lower(name.substr(4));
  if (rest.empty()) {
    index = idx;
    sub.reset();
    return true;
  }
  if (rest.rfind("sub", 0) == 0) {
    uint16_t s;
    if (!parse_hex_u16(rest.substr(3), s) || s > 0xFF) return false;
    index = idx;
    sub = static_cast<uint8_t>(s);
    return true;
  }
  if (rest == "name" || rest == "value" || rest == "denotation") other = true;  // compact-array helpers
  return false;
}

[[noreturn]] void fail(const std::string& file, int line, const std::string& what) { throw ConfigError(file, line, what); }

Access parse_access(const std::string& file, const std::pair<std::string, int>& v) {
  const std::string a = to_lower(trim(v.first));
  if (a == "ro") return Access::ReadOnly;
  if (a == "const") return Access::Const;
  if (a == "wo") return Access::WriteOnly;
  if (a == "rw" || a == "rwr" || a == "rww") return Access::ReadWrite;
  fail(file, v.second, "AccessType=" + v.first + ": expected ro, wo, rw, rwr, rww or const");
}

}  // namespace

std::optional<int64_t> eval_eds_number(std::string_view text, uint8_t node_id) noexcept {
  std::string s(trim(text));
  if (s.empty()) return std::nullopt;
  // Terms joined by '+', one of which may be $NODEID.
  int64_t sum = 0;
  std::size_t start = 0;
  bool any = false;
  for (std::size_t i = 0; i <= s.size(); ++i) {
    if (i < s.size() && !(s[i] == '+' && i > start)) continue;
    const std::string_view term = trim(std::string_view(s).substr(start, i - start));
    start = i + 1;
    if (term.empty()) return std::nullopt;
    if (iequals(term, "$NODEID")) {
      sum += node_id;
    } else {
      const auto v = parse_c_number(term);
      if (!v) return std::nullopt;
      sum += *v;
    }
    any = true;
  }
  if (!any) return std::nullopt;
  return sum;
}

const EdsEntry* DeviceDescription::find(ObjectAddress a) const noexcept {
  const auto it = std::lower_bound(entries.begin(), entries.end(), a,
                                   [](const EdsEntry& e, ObjectAddress x) { return e.addr < x; });
  return it != entries.end() && it->addr == a ? &*it : nullptr;
}

bool DeviceDescription::has_index(uint16_t index) const noexcept {
  const auto it = std::lower_bound(entries.begin(), entries.end(), ObjectAddress{index, 0},
                                   [](const EdsEntry& e, ObjectAddress x) { return e.addr < x; });
  return it != entries.end() && it->addr.index == index;
}

std::vector<uint8_t> DeviceDescription::value_bytes(const EdsEntry& e, uint8_t node_id, bool configured) const {
  const bool use_param = configured && !e.parameter_value.empty();
  const std::string& text = use_param ? e.parameter_value : e.default_value;
  const char* key = use_param ? "ParameterValue" : "DefaultValue";
  char where[16];
  auto bad = [&](const std::string& why) {
    fail(file, e.line, std::string("[") + format(e.addr, where, sizeof where) + "] " + key + "=" + text + ": " + why);
  };
  std::vector<uint8_t> out;
  if (e.type == DataType::VisibleString || e.type == DataType::UnicodeString) {
    out.assign(text.begin(), text.end());
    return out;
  }
  if (e.type == DataType::OctetString || e.type == DataType::Domain) {
    // Hex bytes, optionally separated by blanks.
    std::string hex;
    for (char c : text) {
      if (c != ' ' && c != '\t') hex += c;
    }
    if (hex.rfind("0x", 0) == 0 || hex.rfind("0X", 0) == 0) hex = hex.substr(2);
    if (hex.size() % 2) bad("expected hex bytes");
    for (std::size_t i = 0; i < hex.size(); i += 2) {
      uint16_t b;
      if (!parse_hex_u16(hex.substr(i, 2), b)) bad("expected hex bytes");
      out.push_back(static_cast<uint8_t>(b));
    }
    return out;
  }
  const std::size_t size = data_type_size(e.type);
  out.assign(size, 0);
  if (trim(text).empty()) return out;
  if (e.type == DataType::Real32 || e.type == DataType::Real64) {
    const auto d = parse_double(trim(text));
    if (!d) bad("expected a number");
    if (e.type == DataType::Real32) put_le<float>(out.data(), static_cast<float>(*d));
    else put_le<double>(out.data(), *d);
    return out;
  }
  const auto v = eval_eds_number(text, node_id);
  if (!v) bad("expected a number in C syntax (0x.., decimal, $NODEID+..)");
  if (size < 8) {
    const int64_t lo = is_signed(e.type) ? -(int64_t{1} << (8 * size - 1)) : 0;
    const int64_t hi = is_signed(e.type) ? (int64_t{1} << (8 * size - 1)) - 1 : (int64_t{1} << (8 * size)) - 1;
    if (*v < lo || *v > hi) bad(std::string("out of range for ") + to_string(e.type));
  }
  const uint64_t bits = static_cast<uint64_t>(*v);
  for (std::size_t i = 0; i < size; ++i) out[i] = static_cast<uint8_t>(bits >> (8 * i));
  return out;
}

void DeviceDescription::build_dictionary(ObjectDictionary& od, uint8_t node_id) const {
  for (const auto& e : entries) {
    const std::vector<uint8_t> value = value_bytes(e, node_id, true);
    if (is_fixed_size(e.type)) {
      uint64_t bits = 0;
      for (std::size_t i = 0; i < value.size() && i < 8; ++i) bits |= static_cast<uint64_t>(value[i]) << (8 * i);
      od.add(e.addr, e.type, e.access, bits, e.pdo_mapping, e.name);
      const auto lo = eval_eds_number(e.low_limit, node_id);
      const auto hi = eval_eds_number(e.high_limit, node_id);
      if (lo || hi) {
        od.set_limits(e.addr, lo.value_or(INT64_MIN), hi.value_or(INT64_MAX));
      }
    } else {
      // Strings and domains get room to grow: a description gives no maximum.
      od.add_bytes(e.addr, e.type, e.access, value, std::max<uint32_t>(static_cast<uint32_t>(value.size()), 4096), e.name);
    }
  }
}

DeviceDescription parse_eds(std::string_view text, const std::string& filename) {
  DeviceDescription d;
  d.file = filename;
  std::vector<Section> sections;
  std::map<std::string, std::size_t> by_name;  // lower-case
  int line_no = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t eol = text.find('\n', pos);
    std::string_view line = text.substr(pos, eol == std::string_view::npos ? std::string_view::npos : eol - pos);
    pos = eol == std::string_view::npos ? text.size() + 1 : eol + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    line = trim(line);
    if (line.empty() || line[0] == ';' || line[0] == '#') continue;
    if (line[0] == '[') {
      if (line.back() != ']') fail(filename, line_no, "section header without closing ']'");
      const std::string name(trim(line.substr(1, line.size() - 2)));
      if (name.empty()) fail(filename, line_no, "empty section name");
      const std::string key = to_lower(name);
      if (by_name.count(key)) fail(filename, line_no, "section [" + name + "] appears twice");
      by_name[key] = sections.size();
      sections.push_back(Section{name, line_no, {}});
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string_view::npos || eq == 0) fail(filename, line_no, "expected key=value or [section]");
    if (sections.empty()) fail(filename, line_no, "key outside any section");
    const std::string key = to_lower(trim(line.substr(0, eq)));
    std::string value(trim(line.substr(eq + 1)));
    // Trailing comments after a value are not part of CiA 306 but common.
    if (const auto sc = value.find(';'); sc != std::string::npos && key != "parametername") value = std::string(trim(std::string_view(value).substr(0, sc)));
    auto& keys = sections.back().keys;
    if (keys.count(key)) fail(filename, line_no, "key " + std::string(trim(line.substr(0, eq))) + " given twice in [" + sections.back().name + "]");
    keys[key] = {value, line_no};
  }

  auto section = [&](const std::string& name) -> const Section* {
    const auto it = by_name.find(to_lower(name));
    return it == by_name.end() ? nullptr : &sections[it->second];
  };
  auto number = [&](const std::pair<std::string, int>& v, const std::string& key) -> int64_t {
    const auto n = eval_eds_number(v.first, 0);
    if (!n) fail(filename, v.second, key + "=" + v.first + ": expected a number");
    return *n;
  };

  if (const Section* s = section("DeviceInfo")) {
    if (auto v = s->get("vendorname")) d.vendor_name = v->first;
    if (auto v = s->get("productname")) d.product_name = v->first;
    if (auto v = s->get("vendornumber"); v && !v->first.empty()) d.vendor_number = static_cast<uint32_t>(number(*v, "VendorNumber"));
    if (auto v = s->get("productnumber"); v && !v->first.empty()) d.product_number = static_cast<uint32_t>(number(*v, "ProductNumber"));
    if (auto v = s->get("revisionnumber"); v && !v->first.empty()) d.revision_number = static_cast<uint32_t>(number(*v, "RevisionNumber"));
    for (uint32_t rate : {10u, 20u, 50u, 125u, 250u, 500u, 800u, 1000u}) {
      if (auto v = s->get("baudrate_" + std::to_string(rate)); v && number(*v, "BaudRate_" + std::to_string(rate)) != 0) {
        d.baud_rates_kbit.push_back(rate);
      }
    }
  }
  const Section* comm = section("DeviceComissioning");
  if (!comm) comm = section("DeviceCommissioning");
  if (comm) {
    d.is_dcf = true;
    if (auto v = comm->get("nodeid"); v && !v->first.empty()) {
      const int64_t id = number(*v, "NodeID");
      if (!is_valid_node_id(static_cast<unsigned>(id)) || id > 127) fail(filename, v->second, "NodeID=" + v->first + ": expected 1..127");
      d.node_id = static_cast<uint8_t>(id);
    }
    if (auto v = comm->get("nodename")) d.node_name = v->first;
    if (auto v = comm->get("baudrate"); v && !v->first.empty()) d.baudrate_kbit = static_cast<uint32_t>(number(*v, "Baudrate"));
  }

  // Objects.
  struct Parent {
    uint8_t object_type;
    int sub_number;
    int line;
  };
  std::map<uint16_t, Parent> parents;
  auto make_entry = [&](const Section& s, ObjectAddress addr, uint8_t object_type, bool required_type) {
    EdsEntry e;
    e.addr = addr;
    e.object_type = object_type;
    e.line = s.line;
    if (auto v = s.get("parametername")) e.name = v->first;
    const auto* dt = s.get("datatype");
    if (!dt) {
      if (required_type) fail(filename, s.line, "[" + s.name + "]: DataType missing");
    } else {
      const int64_t code = number(*dt, "DataType");
      if (code < 0 || code > 0xFFFF || !is_known_data_type(static_cast<uint16_t>(code))) {
        fail(filename, dt->second, "DataType=" + dt->first + ": not a CiA 301 basic data type this stack supports");
      }
      e.type = static_cast<DataType>(code);
    }
    if (auto v = s.get("accesstype")) e.access = parse_access(filename, *v);
    else if (required_type) fail(filename, s.line, "[" + s.name + "]: AccessType missing");
    if (auto v = s.get("pdomapping")) {
      const int64_t m = number(*v, "PDOMapping");
      if (m != 0 && m != 1) fail(filename, v->second, "PDOMapping=" + v->first + ": expected 0 or 1");
      e.pdo_mapping = m == 1;
    }
    if (auto v = s.get("defaultvalue")) e.default_value = v->first;
    e.value_line = s.line;
    if (auto v = s.get("parametervalue")) {
      e.parameter_value = v->first;
      e.value_line = v->second;
    }
    if (auto v = s.get("lowlimit")) e.low_limit = v->first;
    if (auto v = s.get("highlimit")) e.high_limit = v->first;
    // Check the values now, so the error points at this file and line.
    for (const char* key : {"defaultvalue", "parametervalue", "lowlimit", "highlimit"}) {
      const auto* v = s.get(key);
      if (!v || v->first.empty() || !is_fixed_size(e.type)) continue;
      EdsEntry probe = e;
      probe.line = v->second;
      probe.default_value = v->first;
      probe.parameter_value.clear();
      d.value_bytes(probe, 1, false);
    }
    return e;
  };

  for (const Section& s : sections) {
    uint16_t index;
    std::optional<uint8_t> sub;
    bool other;
    if (!object_section(s.name, index, sub, other) || sub) continue;
    uint8_t object_type = 0x7;
    if (auto v = s.get("objecttype")) {
      const int64_t t = number(*v, "ObjectType");
      if (t != 0x2 && t != 0x5 && t != 0x6 && t != 0x7 && t != 0x8 && t != 0x9) {
        fail(filename, v->second, "ObjectType=" + v->first + ": expected 0x7 VAR, 0x8 ARRAY, 0x9 RECORD (or 0x2, 0x5, 0x6)");
      }
      object_type = static_cast<uint8_t>(t);
    }
    int sub_number = 0;
    if (auto v = s.get("subnumber")) sub_number = static_cast<int>(number(*v, "SubNumber"));
    parents[index] = Parent{object_type, sub_number, s.line};
    if (object_type == 0x7 || object_type == 0x2) {
      d.entries.push_back(make_entry(s, ObjectAddress{index, 0}, object_type, true));
    } else if (object_type == 0x8 || object_type == 0x9) {
      if (auto v = s.get("compactsubobj"); v && number(*v, "CompactSubObj") > 0) {
        const int64_t n = number(*v, "CompactSubObj");
        if (n > 254) fail(filename, v->second, "CompactSubObj=" + v->first + ": expected 1..254");
        EdsEntry count;
        count.addr = {index, 0};
        count.object_type = object_type;
        count.name = "Number of entries";
        count.type = DataType::Unsigned8;
        count.access = Access::ReadOnly;
        count.default_value = std::to_string(n);
        count.line = s.line;
        d.entries.push_back(count);
        EdsEntry proto = make_entry(s, ObjectAddress{index, 1}, object_type, true);
        for (int64_t k = 1; k <= n; ++k) {
          EdsEntry e = proto;
          e.addr.sub = static_cast<uint8_t>(k);
          d.entries.push_back(e);
        }
        parents[index].sub_number = -1;  // subs generated
      }
    }
  }
  std::map<uint16_t, int> subs_seen;
  for (const Section& s : sections) {
    uint16_t index;
    std::optional<uint8_t> sub;
    bool other;
    if (!object_section(s.name, index, sub, other) || !sub) continue;
    const auto p = parents.find(index);
    char buf[8];
    std::snprintf(buf, sizeof buf, "%04X", index);
    if (p == parents.end()) fail(filename, s.line, "[" + s.name + "] without its object section [" + buf + "]");
    if (p->second.object_type == 0x7) fail(filename, s.line, "[" + s.name + "]: object " + buf + " is a VAR and has no sub-indices");
    ++subs_seen[index];
    d.entries.push_back(make_entry(s, ObjectAddress{index, *sub}, p->second.object_type, true));
  }
  for (const auto& [index, p] : parents) {
    if ((p.object_type == 0x8 || p.object_type == 0x9) && p.sub_number >= 0 && subs_seen[index] != p.sub_number) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "%04X", index);
      fail(filename, p.line, "[" + std::string(buf) + "]: SubNumber=" + std::to_string(p.sub_number) + " but " +
                                 std::to_string(subs_seen[index]) + " sub-index sections follow");
    }
  }
  std::sort(d.entries.begin(), d.entries.end(), [](const EdsEntry& a, const EdsEntry& b) { return a.addr < b.addr; });
  for (std::size_t i = 1; i < d.entries.size(); ++i) {
    if (d.entries[i].addr == d.entries[i - 1].addr) {
      char a[16];
      fail(filename, d.entries[i].line, std::string("object ") + format(d.entries[i].addr, a, sizeof a) + " defined twice");
    }
  }
  // The object lists must name objects that exist.
  for (const char* list : {"MandatoryObjects", "OptionalObjects", "ManufacturerObjects"}) {
    const Section* s = section(list);
    if (!s) continue;
    int64_t count = 0;
    if (auto v = s->get("supportedobjects")) count = number(*v, "SupportedObjects");
    for (int64_t k = 1; k <= count; ++k) {
      const auto* v = s->get(std::to_string(k));
      if (!v) fail(filename, s->line, std::string("[") + list + "]: SupportedObjects=" + std::to_string(count) + " but entry " + std::to_string(k) + " is missing");
      const int64_t idx = number(*v, std::to_string(k));
      if (idx < 0 || idx > 0xFFFF || !parents.count(static_cast<uint16_t>(idx))) {
        fail(filename, v->second, std::string("[") + list + "] " + std::to_string(k) + "=" + v->first + ": no such object section");
      }
    }
  }
  return d;
}

DeviceDescription load_eds(const std::filesystem::path& path) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const FileError& e) {
    throw ConfigError(path.string(), 0, "cannot read the device description: " + e.reason());
  }
  return parse_eds(text, path.string());
}

}  // namespace cnc::canopen
