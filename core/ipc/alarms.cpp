#include "core/ipc/alarms.hpp"

#include <cctype>

namespace cnc::ipc {

std::string AlarmTable::cause_of(std::string_view text) {
  for (std::string_view word : {std::string_view("joint "), std::string_view("spindle ")}) {
    for (std::size_t at = text.find(word); at != std::string_view::npos; at = text.find(word, at + 1)) {
      const bool starts = at == 0 || !std::isalnum(static_cast<unsigned char>(text[at - 1]));
      std::size_t end = at + word.size();
      while (end < text.size() && std::isdigit(static_cast<unsigned char>(text[end]))) ++end;
      if (starts && end > at + word.size()) return std::string(text.substr(at, end - at));
    }
  }
  return "";
}

AlarmEntry* AlarmTable::find_active(std::string_view cause) {
  for (AlarmEntry& e : s_.list) {
    if (e.id != 0 && !e.acknowledged && e.cause.view() == cause) return &e;
  }
  return nullptr;
}

// A free slot at the end (the list stays oldest first): the oldest
// acknowledged alarm goes first, the oldest active one only when all are.
AlarmEntry& AlarmTable::new_slot() {
  int used = 0;
  while (used < kMaxAlarms && s_.list[used].id != 0) ++used;
  if (used == kMaxAlarms) {
    int drop = 0;
    for (int i = 0; i < kMaxAlarms; ++i) {
      if (s_.list[i].acknowledged) {
        drop = i;
        break;
      }
    }
    for (int i = drop; i + 1 < kMaxAlarms; ++i) s_.list[i] = s_.list[i + 1];
    ++s_.dropped;
    used = kMaxAlarms - 1;
  }
  s_.list[used] = AlarmEntry{};
  return s_.list[used];
}

void AlarmTable::count_active() {
  uint32_t n = 0;
  for (const AlarmEntry& e : s_.list) n += e.id != 0 && !e.acknowledged ? 1 : 0;
  s_.active = n;
  ++s_.revision;
}

void AlarmTable::post(const Message& m) {
  if (m.kind != MessageKind::Error) return;
  std::string cause = cause_of(m.text.view());
  if (cause.empty()) cause = std::string(m.source.view()) + ": " + std::string(m.text.view());
  if (AlarmEntry* e = find_active(FixedString<48>(cause).view())) {
    ++e->count;
    e->last_ns = m.time_ns;
    if (m.text.view().size() > e->text.view().size()) {
      e->text = m.text;
      e->source = m.source;
    }
  } else {
    AlarmEntry& n = new_slot();
    n.id = next_id_++;
    n.count = 1;
    n.first_ns = n.last_ns = m.time_ns;
    n.source = m.source;
    n.cause.assign(cause);
    n.text = m.text;
  }
  count_active();
}

int AlarmTable::acknowledge(uint32_t id, int64_t now_ns) {
  int n = 0;
  for (AlarmEntry& e : s_.list) {
    if (e.id == 0 || e.acknowledged || (id != 0 && e.id != id)) continue;
    e.acknowledged = true;
    e.acknowledged_ns = now_ns;
    ++n;
  }
  if (n) count_active();
  return n;
}

}  // namespace cnc::ipc
