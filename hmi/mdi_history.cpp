#include "hmi/mdi_history.hpp"

#include <algorithm>
#include <cctype>
#include <system_error>

#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::hmi {

MdiHistory::MdiHistory(std::filesystem::path file, std::size_t max_entries) : file_(std::move(file)), max_(max_entries) {}

std::string MdiHistory::key(std::string_view command) {
  std::string k;
  int depth = 0;
  for (char c : trim(command)) {
    if (c == '(') ++depth;
    if (c == ')' && depth > 0) --depth;
    if (depth == 0 && (c == ' ' || c == '\t')) continue;
    k += depth > 0 ? c : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return k;
}

bool MdiHistory::load() {
  entries_.clear();
  error_.clear();
  if (file_.empty()) return true;
  std::error_code ec;
  if (!std::filesystem::exists(file_, ec)) return true;
  try {
    const std::string text = read_file(file_);
    for (const auto& line : split(text, '\n', true)) {
      const std::string_view t = trim(line);
      if (t.empty()) continue;
      const std::string k = key(t);
      entries_.erase(std::remove_if(entries_.begin(), entries_.end(), [&](const std::string& e) { return key(e) == k; }),
                     entries_.end());
      entries_.emplace_back(t);
    }
  } catch (const std::exception& e) {
    error_ = e.what();
    return false;
  }
  if (entries_.size() > max_) entries_.erase(entries_.begin(), entries_.end() - static_cast<long>(max_));
  return true;
}

bool MdiHistory::add(std::string_view command) {
  const std::string_view t = trim(command);
  if (t.empty()) return true;
  const std::string k = key(t);
  entries_.erase(std::remove_if(entries_.begin(), entries_.end(), [&](const std::string& e) { return key(e) == k; }),
                 entries_.end());
  entries_.emplace_back(t);
  if (entries_.size() > max_) entries_.erase(entries_.begin());
  return save();
}

bool MdiHistory::clear() {
  entries_.clear();
  return save();
}

bool MdiHistory::save() {
  error_.clear();
  if (file_.empty()) return true;
  std::string text;
  for (const auto& e : entries_) text += e + "\n";
  try {
    std::error_code ec;
    if (file_.has_parent_path()) std::filesystem::create_directories(file_.parent_path(), ec);
    write_file_atomically(file_, text);
  } catch (const std::exception& e) {
    error_ = e.what();
    return false;
  }
  return true;
}

}  // namespace cnc::hmi
