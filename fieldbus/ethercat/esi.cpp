#include "fieldbus/ethercat/esi.hpp"

#include <expat.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/util/atomic_file.hpp"

namespace cnc::ethercat {
namespace {

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

uint8_t data_type_code(const std::string& t) {
  if (t == "BOOL" || t == "BIT") return 0x01;
  if (t == "SINT") return 0x02;
  if (t == "INT") return 0x03;
  if (t == "DINT") return 0x04;
  if (t == "USINT" || t == "BYTE") return 0x05;
  if (t == "UINT" || t == "WORD") return 0x06;
  if (t == "UDINT" || t == "DWORD") return 0x07;
  if (t == "REAL") return 0x08;
  if (t == "LINT") return 0x15;
  if (t == "ULINT") return 0x1B;
  return 0;
}

struct Parser {
  std::string file;
  XML_Parser xml = nullptr;
  EsiFile out;
  std::vector<std::string> path;
  std::string text;
  EsiDevice* device = nullptr;
  SiiPdo* pdo = nullptr;
  bool pdo_assigned = false;
  SiiPdoEntry entry;
  bool in_opmode = false, opmode_done = false;
  std::string error;

  int line() const { return static_cast<int>(XML_GetCurrentLineNumber(xml)); }
  void fail(const std::string& why) {
    if (error.empty()) error = file + ":" + std::to_string(line()) + ": " + why;
    XML_StopParser(xml, XML_FALSE);
  }
  uint64_t number(const std::string& what) {
    uint64_t v = 0;
    if (!parse_esi_number(text, v)) fail(what + ": \"" + text + "\" is not a number (#x... or decimal)");
    return v;
  }
  bool parent_is(const char* name) const { return path.size() >= 2 && path[path.size() - 2] == name; }

  void start(const std::string& el, const char** attrs) {
    path.push_back(el);
    text.clear();
    auto attr = [&](const char* key) -> const char* {
      for (int i = 0; attrs[i]; i += 2) {
        if (std::string(attrs[i]) == key) return attrs[i + 1];
      }
      return nullptr;
    };
    if (el == "Device" && parent_is("Devices")) {
      out.devices.emplace_back();
      device = &out.devices.back();
      device->line = line();
    } else if (device && (el == "RxPdo" || el == "TxPdo") && parent_is("Device")) {
      auto& list = el == "RxPdo" ? device->rx_pdos : device->tx_pdos;
      list.emplace_back();
      pdo = &list.back();
      pdo_assigned = attr("Sm") != nullptr;
      if (pdo_assigned) {
        uint64_t sm = 0;
        text = attr("Sm");
        sm = number("Sm");
        pdo->sm = static_cast<uint8_t>(sm);
        text.clear();
      }
    } else if (pdo && el == "Entry") {
      entry = SiiPdoEntry{};
    } else if (device && el == "Type" && parent_is("Device")) {
      uint64_t v = 0;
      if (const char* pc = attr("ProductCode")) {
        text = pc;
        v = number("ProductCode");
        device->product_code = static_cast<uint32_t>(v);
      }
      if (const char* rv = attr("RevisionNo")) {
        text = rv;
        v = number("RevisionNo");
        device->revision = static_cast<uint32_t>(v);
      }
      text.clear();
    } else if (device && el == "OpMode" && parent_is("Dc")) {
      device->has_dc = true;
      in_opmode = !opmode_done;
    }
  }

  void end(const std::string& el) {
    const std::string t = trimmed(text);
    if (el == "Id" && parent_is("Vendor")) {
      out.vendor_id = static_cast<uint32_t>(number("Vendor Id"));
    } else if (el == "Name" && parent_is("Vendor")) {
      out.vendor_name = t;
    } else if (device && el == "Type" && parent_is("Device")) {
      device->type = t;
    } else if (device && el == "Name" && parent_is("Device") && device->name.empty()) {
      device->name = t;
    } else if (pdo && el == "Index" && (parent_is("RxPdo") || parent_is("TxPdo"))) {
      pdo->index = static_cast<uint16_t>(number("PDO Index"));
    } else if (pdo && el == "Name" && (parent_is("RxPdo") || parent_is("TxPdo"))) {
      pdo->name = t;
    } else if (pdo && parent_is("Entry")) {
      if (el == "Index") entry.index = static_cast<uint16_t>(number("Entry Index"));
      else if (el == "SubIndex") entry.sub = static_cast<uint8_t>(number("SubIndex"));
      else if (el == "BitLen") entry.bits = static_cast<uint8_t>(number("BitLen"));
      else if (el == "Name") entry.name = t;
      else if (el == "DataType") entry.data_type = data_type_code(t);
    } else if (pdo && el == "Entry") {
      if (entry.bits == 0) fail("PDO entry without BitLen");
      pdo->entries.push_back(entry);
    } else if (device && (el == "RxPdo" || el == "TxPdo") && parent_is("Device")) {
      if (!pdo_assigned) {  // optional PDO: not part of the default mapping
        auto& list = el == "RxPdo" ? device->rx_pdos : device->tx_pdos;
        list.pop_back();
      }
      pdo = nullptr;
    } else if (device && in_opmode && el == "AssignActivate") {
      device->assign_activate = static_cast<uint16_t>(number("AssignActivate"));
    } else if (device && el == "OpMode") {
      if (in_opmode) opmode_done = true;
      in_opmode = false;
    } else if (el == "Device" && parent_is("Devices")) {
      device = nullptr;
      opmode_done = false;
    }
    path.pop_back();
    text.clear();
  }
};

void XMLCALL on_start(void* p, const XML_Char* el, const XML_Char** attrs) { static_cast<Parser*>(p)->start(el, attrs); }
void XMLCALL on_end(void* p, const XML_Char* el) { static_cast<Parser*>(p)->end(el); }
void XMLCALL on_text(void* p, const XML_Char* s, int n) {
  static_cast<Parser*>(p)->text.append(s, static_cast<std::size_t>(n));  // trimmed when used
}


}  // namespace

bool parse_esi_number(const std::string& raw, uint64_t& out) noexcept {
  const std::string t = trimmed(raw);
  if (t.empty()) return false;
  try {
    std::size_t used = 0;
    if (t.size() > 2 && t[0] == '#' && (t[1] == 'x' || t[1] == 'X')) {
      out = std::stoull(t.substr(2), &used, 16);
      return used == t.size() - 2;
    }
    out = std::stoull(t, &used, 10);
    return used == t.size();
  } catch (...) {
    return false;
  }
}

const EsiDevice* EsiFile::find(uint32_t product_code, uint32_t revision) const noexcept {
  const EsiDevice* best = nullptr;
  for (const EsiDevice& d : devices) {
    if (d.product_code != product_code) continue;
    if (d.revision == revision) return &d;
    if (!best || d.revision > best->revision) best = &d;
  }
  return best;
}

EsiFile parse_esi(const std::string& xml, const std::string& filename) {
  Parser p;
  p.file = filename;
  p.out.path = filename;
  p.xml = XML_ParserCreate(nullptr);
  XML_SetUserData(p.xml, &p);
  XML_SetElementHandler(p.xml, on_start, on_end);
  XML_SetCharacterDataHandler(p.xml, on_text);
  const XML_Status st = XML_Parse(p.xml, xml.data(), static_cast<int>(xml.size()), XML_TRUE);
  std::string error = p.error;
  if (st == XML_STATUS_ERROR && error.empty()) {
    error = filename + ":" + std::to_string(XML_GetCurrentLineNumber(p.xml)) + ": " +
            XML_ErrorString(XML_GetErrorCode(p.xml));
  }
  XML_ParserFree(p.xml);
  if (!error.empty()) throw std::runtime_error(error);
  if (p.out.devices.empty()) throw std::runtime_error(filename + ": no <Device> under <Descriptions><Devices>");
  return p.out;
}

EsiFile load_esi(const std::filesystem::path& path) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const FileError& e) {
    throw std::runtime_error(path.string() + ": cannot read the ESI file: " + e.reason());
  }
  return parse_esi(text, path.string());
}

}  // namespace cnc::ethercat
