#include "hmi/user_dialogs.hpp"

#include <set>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::hmi {
namespace {

void apply_type(UserMessage& m, std::string_view type) {
  for (const auto& w : split_blanks(to_lower(type))) {
    if (w == "okdialog") m.ok = true;
    else if (w == "yesnodialog") m.yesno = true;
    else if (w == "nonedialog") m.none = true;
    else if (w == "status") m.status = true;
  }
}

// Sets one field by its key suffix; false when the suffix is unknown.
bool set_field(UserMessage& m, const std::string& field, const std::string& value) {
  if (field == "TEXT") m.text = value;
  else if (field == "BOLDTEXT" || field == "TITLE") m.title = value;
  else if (field == "DETAILS") m.details = value;
  else if (field == "ICON") m.icon = value;
  else if (field == "TYPE") apply_type(m, value);
  else if (field == "PINNAME") m.pin = value;
  else return false;
  return true;
}

std::string where(const ini::Entry* e) { return e->file + ":" + std::to_string(e->line) + ": [DISPLAY]" + e->key + ": "; }

}  // namespace

const UserMessage* MultiMessage::find(int number) const {
  for (const auto& m : messages) {
    if (m.number == number) return &m;
  }
  return nullptr;
}

std::string hal_pin_word(std::string_view name, std::string* why) {
  std::string out;
  for (char c : trim(name)) {
    if (c == '_') c = '-';
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '.')) {
      if (why) *why = std::string("character '") + c + "' is not allowed in a HAL name";
      return {};
    }
    out += c;
  }
  if (out.empty() && why) *why = "empty name";
  return out;
}

UserDialogConfig UserDialogConfig::from_ini(const ini::IniFile& ini) {
  UserDialogConfig c;
  // MESSAGE_*: keys in file order; a key seen again starts the next message.
  std::set<std::string> seen;
  std::vector<std::pair<UserMessage, const ini::Entry*>> singles;
  std::vector<std::string> ids;
  for (const ini::Entry* e : ini.section_entries("DISPLAY")) {
    if (e->key.rfind("MESSAGE_", 0) == 0) {
      const std::string field = e->key.substr(8);
      if (singles.empty() || seen.count(field)) {
        singles.emplace_back(UserMessage{}, e);
        seen.clear();
      }
      seen.insert(field);
      if (!set_field(singles.back().first, field, std::string(trim(e->value)))) {
        c.warnings.push_back(where(e) + "unknown message key");
      }
    } else if (e->key == "MULTIMESSAGE_ID") {
      ids.emplace_back(trim(e->value));
    }
  }
  for (auto& [m, e] : singles) {
    std::string why;
    m.pin = hal_pin_word(m.pin, &why);
    if (m.pin.empty()) {
      c.warnings.push_back(where(e) + "message without a usable MESSAGE_PINNAME (" + why + "); not shown");
      continue;
    }
    if (!m.has_dialog() && !m.status) m.ok = true;  // no TYPE: an OK dialog
    c.messages.push_back(std::move(m));
  }
  // MULTIMESSAGE_<ID>_*: each _NUMBER starts a message; the other keys
  // belong to the last number above them.
  for (const auto& id : ids) {
    MultiMessage mm;
    mm.id = id;
    std::string why;
    mm.pin = hal_pin_word(id, &why);
    if (mm.pin.empty()) {
      c.warnings.push_back("[DISPLAY]MULTIMESSAGE_ID = " + id + ": " + why + "; not shown");
      continue;
    }
    const std::string prefix = "MULTIMESSAGE_" + id + "_";
    std::set<std::string> fields;
    for (const ini::Entry* e : ini.section_entries("DISPLAY")) {
      if (e->key.rfind(prefix, 0) != 0) continue;
      const std::string field = e->key.substr(prefix.size());
      if (field == "NUMBER") {
        const auto n = parse_int(trim(e->value));
        if (!n || *n == 0) {
          c.warnings.push_back(where(e) + "expected a non-zero message number");
          continue;
        }
        UserMessage m;
        m.number = static_cast<int>(*n);
        m.pin = mm.pin;
        mm.messages.push_back(m);
        fields.clear();
        continue;
      }
      if (mm.messages.empty()) {
        c.warnings.push_back(where(e) + "comes before any " + prefix + "NUMBER; ignored");
        continue;
      }
      if (fields.count(field)) continue;  // repeated within one number: the first counts
      fields.insert(field);
      if (!set_field(mm.messages.back(), field, std::string(trim(e->value)))) c.warnings.push_back(where(e) + "unknown key");
    }
    for (auto& m : mm.messages) {
      if (!m.has_dialog() && !m.status) m.ok = true;
    }
    if (!mm.messages.empty()) c.multi.push_back(std::move(mm));
  }
  return c;
}

std::map<std::string, std::string> parse_show_pin(std::string_view text) {
  // "Owner  Type  Dir  Value  Name [<== signal]"
  std::map<std::string, std::string> out;
  for (const auto& line : split(text, '\n', true)) {
    const auto w = split_blanks(line);
    if (w.size() < 5) continue;
    const std::string& type = w[1];
    if (type != "bit" && type != "float" && type != "s32" && type != "u32" && type != "s64" && type != "u64") continue;
    out[w[4]] = w[3];
  }
  return out;
}

UserDialogLogic::UserDialogLogic(UserDialogConfig config, std::string component)
    : config_(std::move(config)), component_(std::move(component)) {}

std::vector<std::string> UserDialogLogic::setup_commands() const {
  std::vector<std::string> out;
  out.push_back("newcomp " + component_);
  std::set<std::string> made;
  const auto pin = [&](const std::string& word, const char* type, const char* dir) {
    if (made.insert(word).second) out.push_back("newpin " + component_ + " " + full(word) + " " + type + " " + dir);
  };
  for (const auto& m : config_.messages) {
    pin(m.pin, "bit", "io");
    pin(m.pin + "-waiting", "bit", "out");
    if (m.yesno) pin(m.pin + "-response", "bit", "out");
  }
  for (const auto& mm : config_.multi) {
    pin(mm.pin, "s32", "io");
    pin(mm.pin + "-waiting", "bit", "out");
  }
  return out;
}

void UserDialogLogic::pop(const UserMessage* m, const std::string& trigger, const std::string& waiting,
                          std::vector<Action>& out) {
  if (m->status) out.push_back(Action{Action::Kind::Status, m, {}, {}});
  if (m->has_dialog()) {
    shown_[m] = true;
    out.push_back(Action{Action::Kind::Show, m, {}, {}});
    out.push_back(Action{Action::Kind::Set, m, waiting, "TRUE"});
  } else {
    // Status only: the event is taken, the trigger goes back.
    out.push_back(Action{Action::Kind::Set, m, trigger, m->number ? "0" : "FALSE"});
  }
}

std::vector<UserDialogLogic::Action> UserDialogLogic::update(const std::map<std::string, std::string>& pins) {
  std::vector<Action> out;
  for (const auto& m : config_.messages) {
    const auto it = pins.find(full(m.pin));
    if (it == pins.end()) continue;
    const bool on = it->second == "TRUE";
    const bool shown = shown_[&m];
    if (!on) awaiting_reset_.erase(&m);
    if (on && awaiting_reset_.count(&m)) continue;
    if (on && !shown) {
      pop(&m, full(m.pin), full(m.pin + "-waiting"), out);
      if (!m.has_dialog()) awaiting_reset_.insert(&m);
    } else if (!on && shown) {
      // The condition went away before anyone answered.
      shown_[&m] = false;
      out.push_back(Action{Action::Kind::Close, &m, {}, {}});
      out.push_back(Action{Action::Kind::Set, &m, full(m.pin + "-waiting"), "FALSE"});
    }
  }
  for (const auto& mm : config_.multi) {
    const auto it = pins.find(full(mm.pin));
    if (it == pins.end()) continue;
    const auto v = parse_int(it->second);
    const int number = v ? static_cast<int>(*v) : 0;
    const auto last = multi_number_.find(mm.id);
    const int before = last == multi_number_.end() ? 0 : last->second;
    if (last != multi_number_.end() && number == before) continue;
    multi_number_[mm.id] = number;
    if (const UserMessage* old = mm.find(before); old && shown_[old]) {
      shown_[old] = false;
      out.push_back(Action{Action::Kind::Close, old, {}, {}});
      out.push_back(Action{Action::Kind::Set, old, full(mm.pin + "-waiting"), "FALSE"});
    }
    if (number == 0) continue;
    const UserMessage* m = mm.find(number);
    if (!m) {
      out.push_back(Action{Action::Kind::Log, nullptr, {}, "HAL pin " + full(mm.pin) + " = " + std::to_string(number) +
                                                             ": no MULTIMESSAGE_" + mm.id + "_NUMBER = " + std::to_string(number)});
      continue;
    }
    pop(m, full(mm.pin), full(mm.pin + "-waiting"), out);
  }
  return out;
}

std::vector<UserDialogLogic::Action> UserDialogLogic::answer(const UserMessage* m, bool yes) {
  std::vector<Action> out;
  if (!m || !shown_[m]) return out;
  shown_[m] = false;
  out.push_back(Action{Action::Kind::Close, m, {}, {}});
  if (m->number != 0) {
    // The number stays recorded: a late poll still showing it must not pop
    // the dialog again; only a change of number does.
    out.push_back(Action{Action::Kind::Set, m, full(m->pin), "0"});
  } else {
    awaiting_reset_.insert(m);  // until a poll shows the pin FALSE
    if (m->yesno) out.push_back(Action{Action::Kind::Set, m, full(m->pin + "-response"), yes ? "TRUE" : "FALSE"});
    out.push_back(Action{Action::Kind::Set, m, full(m->pin), "FALSE"});
  }
  out.push_back(Action{Action::Kind::Set, m, full(m->pin + "-waiting"), "FALSE"});
  return out;
}

}  // namespace cnc::hmi
