// The object dictionary of a CANopen device (slave side): typed entries by
// index and sub-index with access rights, PDO mappability, value limits,
// default values for NMT resets, and application hooks. Built once
// (non-realtime; from code or an EDS file), then read and written without
// allocation, so a simulated device may run inside the servo thread.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fieldbus/canopen/types.hpp"

namespace cnc::canopen {

struct OdEntry {
  ObjectAddress addr;
  DataType type = DataType::Unsigned8;
  Access access = Access::ReadWrite;
  bool pdo_mappable = false;
  bool has_low = false, has_high = false;
  int64_t low = 0, high = 0;     // for unsigned types compared as uint64_t bit patterns
  uint32_t offset = 0;           // into the value storage
  uint32_t default_offset = 0;   // into the default storage
  uint32_t capacity = 0;         // bytes reserved (= type size for fixed types)
  uint32_t size = 0;             // current length (strings, domains)
  uint32_t default_size = 0;
  std::string name;
};

class ObjectDictionary {
 public:
  // Returns an abort code (0 = accept) before an SDO write lands.
  using WriteCheck = std::function<uint32_t(const OdEntry&, const uint8_t* data, std::size_t n)>;
  // After a value changed (SDO write, or set() with notify).
  using AfterWrite = std::function<void(const OdEntry&)>;
  // Before an SDO read or TPDO sampling: refresh the value; abort code or 0.
  using BeforeRead = std::function<uint32_t(const OdEntry&)>;

  ObjectDictionary() = default;
  ObjectDictionary(const ObjectDictionary&) = delete;
  ObjectDictionary& operator=(const ObjectDictionary&) = delete;

  // --- building (non-realtime; throws std::invalid_argument) ---
  // Fixed-size entry with its default value given as raw little-endian bits.
  OdEntry& add(ObjectAddress a, DataType type, Access access, uint64_t default_bits, bool pdo_mappable = false,
               std::string name = {});
  // String or domain with a capacity in bytes.
  OdEntry& add_bytes(ObjectAddress a, DataType type, Access access, std::span<const uint8_t> value, uint32_t capacity,
                     std::string name = {});
  OdEntry& add_string(ObjectAddress a, Access access, std::string_view value, uint32_t capacity = 0,
                      std::string name = {});
  void set_limits(ObjectAddress a, int64_t low, int64_t high);
  void set_write_check(ObjectAddress a, WriteCheck f);
  void set_after_write(ObjectAddress a, AfterWrite f);
  void set_before_read(ObjectAddress a, BeforeRead f);
  // The same hooks for every sub-index of an index present now.
  void set_write_check(uint16_t index, const WriteCheck& f);
  void set_after_write(uint16_t index, const AfterWrite& f);

  // --- lookup ---
  const OdEntry* find(ObjectAddress a) const noexcept;
  bool has_index(uint16_t index) const noexcept;
  const std::vector<OdEntry>& entries() const noexcept { return entries_; }
  std::size_t max_capacity() const noexcept { return max_capacity_; }

  // --- access (realtime-safe; return an SDO abort code, 0 = done) ---
  // With `remote` the access rights, limits and hooks apply (an SDO or a
  // remote request); without, the application reads/writes its own values.
  uint32_t read(ObjectAddress a, uint8_t* out, std::size_t capacity, std::size_t& n, bool remote) noexcept;
  uint32_t write(ObjectAddress a, const uint8_t* data, std::size_t n, bool remote) noexcept;
  // Raw value bytes of an entry (current length in e.size).
  uint8_t* data(const OdEntry& e) noexcept { return storage_.data() + e.offset; }
  const uint8_t* data(const OdEntry& e) const noexcept { return storage_.data() + e.offset; }
  // Runs the before-read hook of an entry (TPDO sampling), 0 when none.
  uint32_t refresh(const OdEntry& e) noexcept;
  void notify_written(const OdEntry& e) noexcept;

  // Typed local access; a missing entry reads 0 and ignores writes.
  template <class T>
  T get(ObjectAddress a) const noexcept {
    const OdEntry* e = find(a);
    if (!e || e->capacity < sizeof(T)) return T{};
    return get_le<T>(data(*e));
  }
  template <class T>
  bool set(ObjectAddress a, T v) noexcept {
    const OdEntry* e = find(a);
    if (!e || e->capacity < sizeof(T)) return false;
    put_le<T>(data(*e), v);
    return true;
  }
  uint64_t get_bits(const OdEntry& e) const noexcept;

  // A cached handle to one fixed-size value: no lookup per access.
  template <class T>
  class Var {
   public:
    Var() = default;
    Var(ObjectDictionary* od, uint32_t offset) : od_(od), offset_(offset) {}
    T get() const noexcept { return get_le<T>(od_->storage_.data() + offset_); }
    void set(T v) const noexcept { put_le<T>(od_->storage_.data() + offset_, v); }
    bool valid() const noexcept { return od_ != nullptr; }

   private:
    ObjectDictionary* od_ = nullptr;
    uint32_t offset_ = 0;
  };
  // Throws std::invalid_argument if the entry is missing or too small for T.
  template <class T>
  Var<T> var(ObjectAddress a) {
    const OdEntry* e = find(a);
    if (!e || e->capacity < sizeof(T)) throw_bad_var(a, sizeof(T));
    return Var<T>(this, e->offset);
  }

  // Restores default values of the entries with index in [first, last]
  // (NMT reset communication: 0x1000-0x1FFF; reset node: everything).
  void restore_defaults(uint16_t first, uint16_t last) noexcept;
  // Replaces the default value of a fixed-size entry (the identifiers that
  // derive from a node-ID LSS changed); false when the entry is missing.
  bool set_default_bits(ObjectAddress a, uint64_t bits) noexcept;
  uint64_t default_bits(const OdEntry& e) const noexcept;

 private:
  struct Hooks {
    WriteCheck check;
    AfterWrite after;
    BeforeRead before;
  };
  OdEntry& insert(OdEntry e, std::span<const uint8_t> value);
  std::size_t position(ObjectAddress a) const noexcept;
  Hooks& hooks_for(ObjectAddress a);
  uint32_t check_limits(const OdEntry& e, const uint8_t* data) const noexcept;
  [[noreturn]] static void throw_bad_var(ObjectAddress a, std::size_t size);

  std::vector<OdEntry> entries_;
  std::vector<Hooks> hooks_;   // parallel to entries_
  std::vector<uint8_t> storage_;
  std::vector<uint8_t> defaults_;
  std::size_t max_capacity_ = 8;
};

}  // namespace cnc::canopen
