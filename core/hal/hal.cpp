#include "core/hal/hal.hpp"

#include <algorithm>

#include "core/hal/component.hpp"

namespace cnc::hal {

using detail::ParamObj;
using detail::PinObj;
using detail::SignalObj;

Hal::Hal() = default;

Hal::~Hal() { clear(); }

void Hal::clear() {
  stop_threads();
  std::lock_guard lock(mutex_);
  components_.clear();
  threads_.clear();
  functions_.clear();
  signals_.clear();
  signal_storage_.clear();
  params_.clear();
  pins_.clear();
}

void Hal::remove_orphans() {
  std::lock_guard lock(mutex_);
  const auto orphan = [&](const Component* owner) {
    if (!owner) return false;
    for (const auto& c : components_) {
      if (c.get() == owner) return false;
    }
    return true;
  };
  for (auto it = functions_.begin(); it != functions_.end();) {
    Function* f = it->second.get();
    if (!orphan(f->owner)) {
      ++it;
      continue;
    }
    for (const auto& [name, t] : threads_) {
      std::vector<Function*> list = t->functions();
      const auto end = std::remove(list.begin(), list.end(), f);
      if (end != list.end()) {
        list.erase(end, list.end());
        t->set_functions(list);
      }
    }
    it = functions_.erase(it);
  }
  for (auto it = params_.begin(); it != params_.end();) {
    it = orphan(it->second->owner) ? params_.erase(it) : std::next(it);
  }
  for (auto it = pins_.begin(); it != pins_.end();) {
    if (!orphan(it->second->owner)) {
      ++it;
      continue;
    }
    unlink_locked(it->second.get());
    it = pins_.erase(it);
  }
}

void Hal::check_unique(const std::string& name) const {
  if (pins_.count(name) || params_.count(name)) {
    throw HalError("a pin or parameter named \"" + name + "\" already exists");
  }
}

PinObj* Hal::create_pin(Component* owner, const std::string& name, Type type, PinDir dir, uint64_t initial) {
  if (auto why = check_pin_name(name); !why.empty()) throw HalError("pin name: " + why);
  std::lock_guard lock(mutex_);
  check_unique(name);
  auto p = std::make_unique<PinObj>();
  p->name = name;
  p->type = type;
  p->dir = dir;
  p->owner = owner;
  p->own.set_raw(initial);
  p->cell.store(&p->own, std::memory_order_release);
  PinObj* raw = p.get();
  pins_.emplace(name, std::move(p));
  return raw;
}

ParamObj* Hal::create_param(Component* owner, const std::string& name, Type type, ParamDir dir, uint64_t initial) {
  if (auto why = check_pin_name(name); !why.empty()) throw HalError("parameter name: " + why);
  std::lock_guard lock(mutex_);
  check_unique(name);
  auto p = std::make_unique<ParamObj>();
  p->name = name;
  p->type = type;
  p->dir = dir;
  p->owner = owner;
  p->cell.set_raw(initial);
  ParamObj* raw = p.get();
  params_.emplace(name, std::move(p));
  return raw;
}

void Hal::export_function(Component* owner, const std::string& name, FunctionFn fn, void* arg, bool uses_fp) {
  if (auto why = check_name(name); !why.empty()) throw HalError("function name: " + why);
  ParamObj* time = create_param(owner, name + ".time", Type::S64, ParamDir::RO, 0);
  ParamObj* tmax = create_param(owner, name + ".tmax", Type::S64, ParamDir::RW, 0);
  ParamObj* overruns = create_param(owner, name + ".overruns", Type::U32, ParamDir::RO, 0);
  std::lock_guard lock(mutex_);
  if (functions_.count(name)) throw HalError("a function named \"" + name + "\" already exists");
  auto f = std::make_unique<Function>();
  f->name = name;
  f->fn = fn;
  f->arg = arg;
  f->owner = owner;
  f->uses_fp = uses_fp;
  f->time = time;
  f->tmax = tmax;
  f->overruns = overruns;
  functions_.emplace(name, std::move(f));
}

Thread& Hal::new_thread(const std::string& name, int64_t period_ns, bool uses_fp) {
  if (auto why = check_name(name); !why.empty()) throw HalError("thread name: " + why);
  if (period_ns < 10'000) throw HalError("thread " + name + ": period " + std::to_string(period_ns) + " ns is below 10000 ns");
  {
    std::lock_guard lock(mutex_);
    if (threads_.count(name)) throw HalError("a thread named \"" + name + "\" already exists");
  }
  ParamObj* time = create_param(nullptr, name + ".time", Type::S64, ParamDir::RO, 0);
  ParamObj* tmax = create_param(nullptr, name + ".tmax", Type::S64, ParamDir::RW, 0);
  std::lock_guard lock(mutex_);
  auto t = std::make_unique<Thread>(name, period_ns, uses_fp);
  t->set_params(time, tmax);
  t->set_overrun_limit(overrun_limit_);
  Thread& ref = *t;
  threads_.emplace(name, std::move(t));
  return ref;
}

void Hal::set_overrun_limit(uint32_t cycles) {
  std::lock_guard lock(mutex_);
  overrun_limit_ = cycles;
  for (auto& [name, t] : threads_) t->set_overrun_limit(cycles);
}

Component& Hal::add_component(std::unique_ptr<Component> c) {
  std::lock_guard lock(mutex_);
  for (const auto& existing : components_) {
    if (existing->name() == c->name()) throw HalError("component \"" + c->name() + "\" is already loaded");
  }
  components_.push_back(std::move(c));
  return *components_.back();
}

Component* Hal::find_component(const std::string& name) const {
  std::lock_guard lock(mutex_);
  for (const auto& c : components_) {
    if (c->name() == name) return c.get();
  }
  return nullptr;
}

std::vector<Component*> Hal::components() const {
  std::lock_guard lock(mutex_);
  std::vector<Component*> out;
  for (const auto& c : components_) out.push_back(c.get());
  return out;
}

const PinObj* Hal::find_pin(const std::string& name) const {
  std::lock_guard lock(mutex_);
  return pin_locked(name);
}

PinObj* Hal::pin_locked(const std::string& name) const {
  const auto it = pins_.find(name);
  if (it == pins_.end()) throw HalError("pin \"" + name + "\" does not exist");
  return it->second.get();
}

SignalObj* Hal::signal_locked(const std::string& name) const {
  const auto it = signals_.find(name);
  if (it == signals_.end()) throw HalError("signal \"" + name + "\" does not exist");
  return it->second;
}

Function* Hal::function_locked(const std::string& name) const {
  const auto it = functions_.find(name);
  if (it == functions_.end()) throw HalError("function \"" + name + "\" does not exist");
  return it->second.get();
}

Thread* Hal::thread_locked(const std::string& name) const {
  const auto it = threads_.find(name);
  if (it == threads_.end()) throw HalError("thread \"" + name + "\" does not exist");
  return it->second.get();
}

void Hal::new_signal(const std::string& name, Type type) {
  std::lock_guard lock(mutex_);
  new_signal_locked(name, type);
}

SignalObj* Hal::new_signal_locked(const std::string& name, Type type, bool named_after_pin) {
  if (auto why = check_signal_name(name); !why.empty()) throw HalError("signal name: " + why);
  if (signals_.count(name)) throw HalError("signal \"" + name + "\" already exists");
  if (!named_after_pin && pins_.count(name)) throw HalError("signal \"" + name + "\" would have the name of a pin");
  auto s = std::make_unique<SignalObj>();
  s->name = name;
  s->type = type;
  SignalObj* raw = s.get();
  signals_.emplace(name, raw);
  signal_storage_.push_back(std::move(s));
  return raw;
}

void Hal::delete_signal(const std::string& name) {
  std::lock_guard lock(mutex_);
  SignalObj* s = signal_locked(name);
  while (!s->pins.empty()) unlink_locked(s->pins.back());
  s->deleted = true;
  signals_.erase(name);
}

void Hal::link_locked(PinObj* pin, SignalObj* sig) {
  if (pin->signal == sig) return;
  if (pin->signal) {
    throw HalError("pin " + pin->name + " is already linked to signal " + pin->signal->name);
  }
  if (pin->type != sig->type) {
    throw HalError("pin " + pin->name + " is " + to_string(pin->type) + " but signal " + sig->name + " is " +
                   to_string(sig->type));
  }
  int writers = 0, bidirs = 0;
  for (const PinObj* p : sig->pins) {
    if (p->dir == PinDir::Out) ++writers;
    if (p->dir == PinDir::IO) ++bidirs;
  }
  if (pin->dir == PinDir::Out && (writers > 0 || bidirs > 0)) {
    throw HalError("signal " + sig->name + " already has a writer; cannot link output pin " + pin->name);
  }
  if (pin->dir == PinDir::IO && writers > 0) {
    throw HalError("signal " + sig->name + " has an output pin; cannot link I/O pin " + pin->name);
  }
  // A new writer brings its current value; a reader takes the signal's.
  if (pin->dir != PinDir::In && writers == 0 && bidirs == 0) sig->cell.set_raw(pin->own.raw());
  sig->pins.push_back(pin);
  pin->signal = sig;
  pin->cell.store(&sig->cell, std::memory_order_release);
}

void Hal::unlink_locked(PinObj* pin) {
  SignalObj* sig = pin->signal;
  if (!sig) return;
  pin->own.set_raw(sig->cell.raw());  // keep the last value, as LinuxCNC does
  pin->cell.store(&pin->own, std::memory_order_release);
  sig->pins.erase(std::remove(sig->pins.begin(), sig->pins.end(), pin), sig->pins.end());
  pin->signal = nullptr;
}

void Hal::net(const std::string& signal, const std::vector<std::string>& pin_names) {
  net_impl(signal, pin_names, false);
}

void Hal::net_impl(const std::string& signal, const std::vector<std::string>& pin_names, bool named_after_pin) {
  if (pin_names.empty()) throw HalError("net " + signal + ": no pins given");
  std::lock_guard lock(mutex_);
  if (!named_after_pin && pins_.count(signal)) throw HalError("net: \"" + signal + "\" is a pin; the first name after 'net' is the signal");
  const auto existing = signals_.find(signal);
  SignalObj* sig = existing == signals_.end() ? nullptr : existing->second;
  const Type type = sig ? sig->type : pin_locked(pin_names.front())->type;
  // Validate everything first so that a failing net changes nothing.
  int outs = 0, bidirs = 0;
  if (sig) {
    for (const PinObj* p : sig->pins) {
      outs += p->dir == PinDir::Out ? 1 : 0;
      bidirs += p->dir == PinDir::IO ? 1 : 0;
    }
  }
  std::vector<PinObj*> pins;
  for (const std::string& n : pin_names) {
    PinObj* p = pin_locked(n);
    if (p->signal && p->signal != sig) throw HalError("pin " + n + " is already linked to signal " + p->signal->name);
    if (p->type != type) {
      throw HalError("pin " + n + " is " + to_string(p->type) + " but signal " + signal + " is " + to_string(type));
    }
    if (p->signal != sig || !sig) {
      outs += p->dir == PinDir::Out ? 1 : 0;
      bidirs += p->dir == PinDir::IO ? 1 : 0;
    }
    pins.push_back(p);
  }
  if (outs > 1) throw HalError("signal " + signal + " would have more than one output pin writing it");
  if (outs == 1 && bidirs > 0) throw HalError("signal " + signal + " would have both an output pin and I/O pins");
  if (!sig) sig = new_signal_locked(signal, type, named_after_pin);
  for (PinObj* p : pins) link_locked(p, sig);
}

void Hal::link(const std::string& pin, const std::string& signal) {
  std::lock_guard lock(mutex_);
  link_locked(pin_locked(pin), signal_locked(signal));
}

void Hal::unlink(const std::string& pin) {
  std::lock_guard lock(mutex_);
  unlink_locked(pin_locked(pin));
}

void Hal::link_pins(const std::string& a, const std::string& b) {
  std::string writer = a;
  {
    std::lock_guard lock(mutex_);
    PinObj* pa = pin_locked(a);
    PinObj* pb = pin_locked(b);
    if (pb->dir == PinDir::Out && pa->dir != PinDir::Out) writer = b;
    if (pa->signal) writer = pa->signal->name;
  }
  net_impl(writer, {a, b}, true);
}

void Hal::add_function(const std::string& function, const std::string& thread, int position) {
  std::lock_guard lock(mutex_);
  Function* f = function_locked(function);
  Thread* t = thread_locked(thread);
  if (f->uses_fp && !t->uses_fp()) throw HalError("function " + function + " uses floating point but thread " + thread + " does not");
  std::vector<Function*> list = t->functions();
  if (std::find(list.begin(), list.end(), f) != list.end()) {
    throw HalError("function " + function + " is already in thread " + thread);
  }
  // A function keeps state between its calls (a motion controller, a bus
  // master): two threads calling it would race. As LinuxCNC: one thread.
  if (f->users > 0) {
    std::string other;
    for (const auto& [name, th] : threads_) {
      const auto fl = th->functions();
      if (std::find(fl.begin(), fl.end(), f) != fl.end()) other = name;
    }
    throw HalError("function " + function + " is already in thread " + other +
                   "; a function runs in one thread only (delf it there first)");
  }
  if (list.size() >= Thread::kMaxFunctions) throw HalError("thread " + thread + " is full");
  // LinuxCNC positions: 1 is first, -1 (default) last, -2 next to last...
  std::size_t at = list.size();
  if (position > 0) at = std::min<std::size_t>(static_cast<std::size_t>(position - 1), list.size());
  else if (position < -1) at = list.size() - std::min<std::size_t>(static_cast<std::size_t>(-position - 1), list.size());
  list.insert(list.begin() + static_cast<long>(at), f);
  t->set_functions(list);
  ++f->users;
}

void Hal::remove_function(const std::string& function, const std::string& thread) {
  std::lock_guard lock(mutex_);
  Function* f = function_locked(function);
  Thread* t = thread_locked(thread);
  std::vector<Function*> list = t->functions();
  const auto it = std::find(list.begin(), list.end(), f);
  if (it == list.end()) throw HalError("function " + function + " is not in thread " + thread);
  list.erase(it);
  t->set_functions(list);
  --f->users;
}

void Hal::set_value(const std::string& name, const std::string& text) {
  std::lock_guard lock(mutex_);
  if (const auto pit = pins_.find(name); pit != pins_.end()) {
    PinObj* p = pit->second.get();
    if (p->dir == PinDir::Out) throw HalError("pin " + name + " is an output; only inputs and parameters can be set");
    if (p->signal) throw HalError("pin " + name + " is connected to signal " + p->signal->name + "; use sets on the signal");
    const auto v = parse_value(p->type, text);
    if (!v) throw HalError("value \"" + text + "\" is not a valid " + to_string(p->type) + " for pin " + name);
    p->own.set_raw(*v);
    return;
  }
  if (const auto it = params_.find(name); it != params_.end()) {
    ParamObj* p = it->second.get();
    if (p->dir == ParamDir::RO) throw HalError("parameter " + name + " is read-only");
    const auto v = parse_value(p->type, text);
    if (!v) throw HalError("value \"" + text + "\" is not a valid " + to_string(p->type) + " for parameter " + name);
    p->cell.set_raw(*v);
    return;
  }
  throw HalError("pin or parameter \"" + name + "\" does not exist");
}

void Hal::set_owned_pin(const std::string& name, const std::string& text, bool (*is_owner)(const Component*)) {
  std::lock_guard lock(mutex_);
  PinObj* p = pin_locked(name);
  if (!is_owner(p->owner)) throw HalError("pin " + name + " does not belong to a component made with newcomp");
  if (p->dir == PinDir::In && p->signal) throw HalError("pin " + name + " is an input connected to signal " + p->signal->name);
  const auto v = parse_value(p->type, text);
  if (!v) throw HalError("value \"" + text + "\" is not a valid " + to_string(p->type) + " for pin " + name);
  p->cell.load(std::memory_order_acquire)->set_raw(*v);
}

std::string Hal::get_value(const std::string& name) const {
  std::lock_guard lock(mutex_);
  if (const auto pit = pins_.find(name); pit != pins_.end()) {
    const PinObj* p = pit->second.get();
    return format_value(p->type, p->cell.load(std::memory_order_acquire)->raw());
  }
  if (const auto it = params_.find(name); it != params_.end()) return format_value(it->second->type, it->second->cell.raw());
  throw HalError("pin or parameter \"" + name + "\" does not exist");
}

Type Hal::type_of_name(const std::string& name) const {
  std::lock_guard lock(mutex_);
  if (const auto pit = pins_.find(name); pit != pins_.end()) return pit->second->type;
  if (const auto it = params_.find(name); it != params_.end()) return it->second->type;
  throw HalError("pin or parameter \"" + name + "\" does not exist");
}

Type Hal::signal_type(const std::string& signal) const {
  std::lock_guard lock(mutex_);
  return signal_locked(signal)->type;
}

void Hal::set_signal(const std::string& signal, const std::string& text) {
  std::lock_guard lock(mutex_);
  SignalObj* s = signal_locked(signal);
  for (const PinObj* p : s->pins) {
    if (p->dir == PinDir::Out) throw HalError("signal " + signal + " is written by pin " + p->name + "; sets would be overwritten");
  }
  const auto v = parse_value(s->type, text);
  if (!v) throw HalError("value \"" + text + "\" is not a valid " + to_string(s->type) + " for signal " + signal);
  s->cell.set_raw(*v);
}

std::string Hal::get_signal(const std::string& signal) const {
  std::lock_guard lock(mutex_);
  const SignalObj* s = signal_locked(signal);
  return format_value(s->type, s->cell.raw());
}

void Hal::start_threads() {
  std::lock_guard lock(mutex_);
  for (auto& [name, t] : threads_) {
    if (!t->is_running()) t->start();
  }
}

void Hal::stop_threads() {
  std::vector<Thread*> list;
  {
    std::lock_guard lock(mutex_);
    for (auto& [name, t] : threads_) list.push_back(t.get());
  }
  for (Thread* t : list) t->stop();
}

bool Hal::threads_running() const {
  std::lock_guard lock(mutex_);
  for (const auto& [name, t] : threads_) {
    if (t->is_running()) return true;
  }
  return false;
}

Thread* Hal::find_thread(const std::string& name) {
  std::lock_guard lock(mutex_);
  const auto it = threads_.find(name);
  return it == threads_.end() ? nullptr : it->second.get();
}

std::vector<Thread*> Hal::threads() const {
  std::lock_guard lock(mutex_);
  std::vector<Thread*> out;
  for (const auto& [name, t] : threads_) out.push_back(t.get());
  return out;
}

bool Hal::has_pin(const std::string& name) const {
  std::lock_guard lock(mutex_);
  return pins_.count(name) != 0;
}

bool Hal::has_param(const std::string& name) const {
  std::lock_guard lock(mutex_);
  return params_.count(name) != 0;
}

namespace {
std::string owner_name(const Component* c) { return c ? c->name() : std::string("hal"); }
}  // namespace

std::vector<PinView> Hal::pins() const {
  std::lock_guard lock(mutex_);
  std::vector<PinView> out;
  for (const auto& [name, p] : pins_) {
    out.push_back(PinView{name, owner_name(p->owner), p->signal ? p->signal->name : std::string(), p->type, p->dir,
                          p->cell.load(std::memory_order_acquire)->raw()});
  }
  return out;
}

std::vector<ParamView> Hal::params() const {
  std::lock_guard lock(mutex_);
  std::vector<ParamView> out;
  for (const auto& [name, p] : params_) out.push_back(ParamView{name, owner_name(p->owner), p->type, p->dir, p->cell.raw()});
  return out;
}

std::vector<SignalView> Hal::signals() const {
  std::lock_guard lock(mutex_);
  std::vector<SignalView> out;
  for (const auto& [name, s] : signals_) {
    SignalView v{name, s->type, s->cell.raw(), {}, {}, {}};
    for (const PinObj* p : s->pins) {
      if (p->dir == PinDir::Out) v.writer = p->name;
      else if (p->dir == PinDir::In) v.readers.push_back(p->name);
      else v.bidirs.push_back(p->name);
    }
    out.push_back(std::move(v));
  }
  return out;
}

std::vector<FunctionView> Hal::functions() const {
  std::lock_guard lock(mutex_);
  std::vector<FunctionView> out;
  for (const auto& [name, f] : functions_) {
    out.push_back(FunctionView{name, owner_name(f->owner), f->uses_fp, f->users, f->time->cell.get<int64_t>(),
                               f->tmax->cell.get<int64_t>()});
  }
  return out;
}

std::vector<ThreadView> Hal::thread_views() const {
  std::lock_guard lock(mutex_);
  std::vector<ThreadView> out;
  for (const auto& [name, t] : threads_) {
    ThreadView v{name, t->period_ns(), t->uses_fp(), t->is_running(), 0, 0, {}};
    const auto time_it = params_.find(name + ".time");
    const auto tmax_it = params_.find(name + ".tmax");
    if (time_it != params_.end()) v.time_ns = time_it->second->cell.get<int64_t>();
    if (tmax_it != params_.end()) v.tmax_ns = tmax_it->second->cell.get<int64_t>();
    for (const Function* f : t->functions()) v.functions.push_back(f->name);
    out.push_back(std::move(v));
  }
  return out;
}

}  // namespace cnc::hal
