#include "core/hal/component.hpp"

#include <algorithm>

#include "core/util/strings.hpp"

namespace cnc::hal {

std::optional<std::string> LoadArgs::get(const std::string& key) const {
  for (const auto& [k, v] : values_) {
    if (k == key) return v;
  }
  return std::nullopt;
}

std::string LoadArgs::get_string(const std::string& key, const std::string& def) const {
  return get(key).value_or(def);
}

int64_t LoadArgs::get_int(const std::string& key, int64_t def, int64_t min, int64_t max) const {
  const auto v = get(key);
  if (!v) return def;
  const auto n = parse_int(*v);
  if (!n || *n < min || *n > max) {
    throw HalError(component_ + ": " + key + "=" + *v + ": expected an integer from " + std::to_string(min) + " to " +
                   std::to_string(max));
  }
  return *n;
}

double LoadArgs::get_double(const std::string& key, double def) const {
  const auto v = get(key);
  if (!v) return def;
  const auto d = parse_double(*v);
  if (!d) throw HalError(component_ + ": " + key + "=" + *v + ": expected a number");
  return *d;
}

std::vector<std::string> LoadArgs::instance_names(const std::string& prefix, int default_count, int max_count,
                                                  const std::string& count_key) const {
  const auto names = get("names");
  if (names && get(count_key)) throw HalError(component_ + ": give " + count_key + "= or names=, not both");
  std::vector<std::string> out;
  if (names) {
    out = split(*names, ',', true);
    if (out.empty()) throw HalError(component_ + ": names= is empty");
    for (const auto& n : out) {
      if (auto why = check_name(n); !why.empty()) throw HalError(component_ + ": names=: " + why);
    }
    return out;
  }
  const auto count = get_int(count_key, default_count, 1, max_count);
  for (int64_t i = 0; i < count; ++i) out.push_back(prefix + "." + std::to_string(i));
  return out;
}

void LoadArgs::allow_only(const std::vector<std::string>& known) const {
  for (const auto& [k, v] : values_) {
    if (std::find(known.begin(), known.end(), k) == known.end()) {
      std::string list;
      for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
      throw HalError(component_ + ": unknown argument \"" + k + "\"" + (list.empty() ? " (it takes none)" : "; it takes " + list));
    }
  }
}

void ComponentRegistry::add(const std::string& name, const std::string& help, ComponentFactory factory) {
  entries_[name] = Entry{name, help, std::move(factory)};
}

const ComponentRegistry::Entry* ComponentRegistry::find(const std::string& name) const {
  const auto it = entries_.find(name);
  return it == entries_.end() ? nullptr : &it->second;
}

std::vector<const ComponentRegistry::Entry*> ComponentRegistry::entries() const {
  std::vector<const Entry*> out;
  for (const auto& [n, e] : entries_) out.push_back(&e);
  return out;
}

}  // namespace cnc::hal
