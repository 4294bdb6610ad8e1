#include "fieldbus/canopen/object_dictionary.hpp"

#include <algorithm>
#include <stdexcept>

#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {
namespace {

std::string address_text(ObjectAddress a) {
  char buf[16];
  return format(a, buf, sizeof buf);
}

int64_t sign_extend(uint64_t bits, std::size_t bytes) noexcept {
  if (bytes >= 8) return static_cast<int64_t>(bits);
  const unsigned shift = static_cast<unsigned>(64 - 8 * bytes);
  return static_cast<int64_t>(bits << shift) >> shift;
}

}  // namespace

OdEntry& ObjectDictionary::insert(OdEntry e, std::span<const uint8_t> value) {
  if (find(e.addr)) throw std::invalid_argument("object dictionary: " + address_text(e.addr) + " defined twice");
  e.offset = static_cast<uint32_t>(storage_.size());
  e.default_offset = static_cast<uint32_t>(defaults_.size());
  storage_.resize(storage_.size() + e.capacity, 0);
  defaults_.resize(defaults_.size() + e.capacity, 0);
  const std::size_t n = std::min<std::size_t>(value.size(), e.capacity);
  std::copy_n(value.data(), n, storage_.data() + e.offset);
  std::copy_n(value.data(), n, defaults_.data() + e.default_offset);
  e.size = e.default_size = is_fixed_size(e.type) ? e.capacity : static_cast<uint32_t>(n);
  max_capacity_ = std::max<std::size_t>(max_capacity_, e.capacity);
  const std::size_t pos = position(e.addr);
  entries_.insert(entries_.begin() + static_cast<std::ptrdiff_t>(pos), std::move(e));
  hooks_.insert(hooks_.begin() + static_cast<std::ptrdiff_t>(pos), Hooks{});
  return entries_[pos];
}

OdEntry& ObjectDictionary::add(ObjectAddress a, DataType type, Access access, uint64_t default_bits, bool pdo_mappable,
                               std::string name) {
  const std::size_t size = data_type_size(type);
  if (size == 0) throw std::invalid_argument("object dictionary: " + address_text(a) + ": " + to_string(type) + " is not a fixed-size type");
  OdEntry e;
  e.addr = a;
  e.type = type;
  e.access = access;
  e.pdo_mappable = pdo_mappable;
  e.capacity = static_cast<uint32_t>(size);
  e.name = std::move(name);
  uint8_t bytes[8];
  put_le<uint64_t>(bytes, default_bits);
  return insert(std::move(e), std::span<const uint8_t>(bytes, size));
}

OdEntry& ObjectDictionary::add_bytes(ObjectAddress a, DataType type, Access access, std::span<const uint8_t> value,
                                     uint32_t capacity, std::string name) {
  if (is_fixed_size(type)) throw std::invalid_argument("object dictionary: " + address_text(a) + ": use add() for " + to_string(type));
  OdEntry e;
  e.addr = a;
  e.type = type;
  e.access = access;
  e.capacity = std::max<uint32_t>(capacity, static_cast<uint32_t>(value.size()));
  e.name = std::move(name);
  return insert(std::move(e), value);
}

OdEntry& ObjectDictionary::add_string(ObjectAddress a, Access access, std::string_view value, uint32_t capacity,
                                      std::string name) {
  return add_bytes(a, DataType::VisibleString, access,
                   std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(value.data()), value.size()), capacity,
                   std::move(name));
}

std::size_t ObjectDictionary::position(ObjectAddress a) const noexcept {
  const auto it = std::lower_bound(entries_.begin(), entries_.end(), a,
                                   [](const OdEntry& e, ObjectAddress x) { return e.addr < x; });
  return static_cast<std::size_t>(it - entries_.begin());
}

const OdEntry* ObjectDictionary::find(ObjectAddress a) const noexcept {
  const std::size_t pos = position(a);
  return pos < entries_.size() && entries_[pos].addr == a ? &entries_[pos] : nullptr;
}

bool ObjectDictionary::has_index(uint16_t index) const noexcept {
  const std::size_t pos = position(ObjectAddress{index, 0});
  return pos < entries_.size() && entries_[pos].addr.index == index;
}

ObjectDictionary::Hooks& ObjectDictionary::hooks_for(ObjectAddress a) {
  const std::size_t pos = position(a);
  if (pos >= entries_.size() || !(entries_[pos].addr == a)) {
    throw std::invalid_argument("object dictionary: no entry " + address_text(a));
  }
  return hooks_[pos];
}

void ObjectDictionary::set_limits(ObjectAddress a, int64_t low, int64_t high) {
  const std::size_t pos = position(a);
  if (pos >= entries_.size() || !(entries_[pos].addr == a)) throw std::invalid_argument("object dictionary: no entry " + address_text(a));
  OdEntry& e = entries_[pos];
  e.has_low = e.has_high = true;
  e.low = low;
  e.high = high;
}

void ObjectDictionary::set_write_check(ObjectAddress a, WriteCheck f) { hooks_for(a).check = std::move(f); }
void ObjectDictionary::set_after_write(ObjectAddress a, AfterWrite f) { hooks_for(a).after = std::move(f); }
void ObjectDictionary::set_before_read(ObjectAddress a, BeforeRead f) { hooks_for(a).before = std::move(f); }

void ObjectDictionary::set_write_check(uint16_t index, const WriteCheck& f) {
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (entries_[i].addr.index == index) hooks_[i].check = f;
  }
}
void ObjectDictionary::set_after_write(uint16_t index, const AfterWrite& f) {
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (entries_[i].addr.index == index) hooks_[i].after = f;
  }
}

void ObjectDictionary::throw_bad_var(ObjectAddress a, std::size_t size) {
  throw std::invalid_argument("object dictionary: " + address_text(a) + " missing or smaller than " +
                              std::to_string(size) + " bytes");
}

uint64_t ObjectDictionary::get_bits(const OdEntry& e) const noexcept {
  uint64_t v = 0;
  const uint8_t* p = data(e);
  for (std::size_t i = 0; i < e.capacity && i < 8; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}

uint32_t ObjectDictionary::check_limits(const OdEntry& e, const uint8_t* data) const noexcept {
  if (!(e.has_low || e.has_high) || !is_fixed_size(e.type)) return 0;
  uint64_t bits = 0;
  for (std::size_t i = 0; i < e.capacity && i < 8; ++i) bits |= static_cast<uint64_t>(data[i]) << (8 * i);
  if (is_signed(e.type)) {
    const int64_t v = sign_extend(bits, e.capacity);
    if (e.has_high && v > e.high) return abort_code::kValueTooHigh;
    if (e.has_low && v < e.low) return abort_code::kValueTooLow;
  } else if (e.type != DataType::Real32 && e.type != DataType::Real64) {
    if (e.has_high && bits > static_cast<uint64_t>(e.high)) return abort_code::kValueTooHigh;
    if (e.has_low && bits < static_cast<uint64_t>(e.low)) return abort_code::kValueTooLow;
  }
  return 0;
}

uint32_t ObjectDictionary::refresh(const OdEntry& e) noexcept {
  const Hooks& h = hooks_[static_cast<std::size_t>(&e - entries_.data())];
  return h.before ? h.before(e) : 0;
}

void ObjectDictionary::notify_written(const OdEntry& e) noexcept {
  const Hooks& h = hooks_[static_cast<std::size_t>(&e - entries_.data())];
  if (h.after) h.after(e);
}

uint32_t ObjectDictionary::read(ObjectAddress a, uint8_t* out, std::size_t capacity, std::size_t& n,
                                bool remote) noexcept {
  n = 0;
  const OdEntry* e = find(a);
  if (!e) return has_index(a.index) ? abort_code::kNoSubIndex : abort_code::kNoObject;
  if (remote) {
    if (!is_readable(e->access)) return abort_code::kWriteOnly;
    if (const uint32_t code = refresh(*e)) return code;
  }
  if (e->size > capacity) return abort_code::kOutOfMemory;
  std::copy_n(data(*e), e->size, out);
  n = e->size;
  return 0;
}

uint32_t ObjectDictionary::write(ObjectAddress a, const uint8_t* in, std::size_t n, bool remote) noexcept {
  const std::size_t pos = position(a);
  if (pos >= entries_.size() || !(entries_[pos].addr == a)) {
    return has_index(a.index) ? abort_code::kNoSubIndex : abort_code::kNoObject;
  }
  OdEntry& e = entries_[pos];
  if (remote && !is_writable(e.access)) return abort_code::kReadOnly;
  if (is_fixed_size(e.type)) {
    if (n > e.capacity) return abort_code::kLengthTooHigh;
    if (n < e.capacity) return abort_code::kLengthTooLow;
  } else if (n > e.capacity) {
    return abort_code::kLengthTooHigh;
  }
  if (remote) {
    if (const uint32_t code = check_limits(e, in)) return code;
    if (hooks_[pos].check) {
      if (const uint32_t code = hooks_[pos].check(e, in, n)) return code;
    }
  }
  std::copy_n(in, n, storage_.data() + e.offset);
  if (!is_fixed_size(e.type)) e.size = static_cast<uint32_t>(n);
  if (remote && hooks_[pos].after) hooks_[pos].after(e);
  return 0;
}

void ObjectDictionary::restore_defaults(uint16_t first, uint16_t last) noexcept {
  for (auto& e : entries_) {
    if (e.addr.index < first || e.addr.index > last) continue;
    std::copy_n(defaults_.data() + e.default_offset, e.capacity, storage_.data() + e.offset);
    e.size = e.default_size;
  }
}

uint64_t ObjectDictionary::default_bits(const OdEntry& e) const noexcept {
  uint64_t v = 0;
  for (std::size_t i = 0; i < e.capacity && i < 8; ++i) v |= static_cast<uint64_t>(defaults_[e.default_offset + i]) << (8 * i);
  return v;
}

bool ObjectDictionary::set_default_bits(ObjectAddress a, uint64_t bits) noexcept {
  const OdEntry* e = find(a);
  if (!e || e->capacity > 8) return false;
  for (uint32_t i = 0; i < e->capacity; ++i) defaults_[e->default_offset + i] = static_cast<uint8_t>(bits >> (8 * i));
  return true;
}

}  // namespace cnc::canopen
