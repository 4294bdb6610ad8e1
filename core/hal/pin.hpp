// Typed handles a component keeps for its pins and parameters. get/set are
// two loads or a load and a store: safe and cheap in the servo thread.
#pragma once

#include "core/hal/objects.hpp"

namespace cnc::hal {

template <class T>
class Pin {
 public:
  Pin() = default;
  explicit Pin(detail::PinObj* p) : p_(p) {}
  T get() const noexcept { return p_->cell.load(std::memory_order_relaxed)->template get<T>(); }
  void set(T v) const noexcept { p_->cell.load(std::memory_order_relaxed)->template set<T>(v); }
  bool valid() const noexcept { return p_ != nullptr; }
  const std::string& name() const noexcept { return p_->name; }
  // Whether the pin is linked to a signal now (realtime-safe).
  bool linked() const noexcept { return p_->cell.load(std::memory_order_relaxed) != &p_->own; }

 private:
  detail::PinObj* p_ = nullptr;
};

template <class T>
class Param {
 public:
  Param() = default;
  explicit Param(detail::ParamObj* p) : p_(p) {}
  T get() const noexcept { return p_->cell.template get<T>(); }
  void set(T v) const noexcept { p_->cell.template set<T>(v); }
  bool valid() const noexcept { return p_ != nullptr; }
  const std::string& name() const noexcept { return p_->name; }

 private:
  detail::ParamObj* p_ = nullptr;
};

using BitPin = Pin<bool>;
using FloatPin = Pin<double>;
using S32Pin = Pin<int32_t>;
using U32Pin = Pin<uint32_t>;
using S64Pin = Pin<int64_t>;
using U64Pin = Pin<uint64_t>;

}  // namespace cnc::hal
