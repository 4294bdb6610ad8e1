#include "core/interp/recording_canon.hpp"

namespace cnc::interp {

std::string RecordingCanon::text() const {
  std::string out;
  for (const auto& c : calls) {
    out += c;
    out += '\n';
  }
  return out;
}

std::vector<std::string> RecordingCanon::calls_starting(const std::string& prefix) const {
  std::vector<std::string> out;
  for (const auto& c : calls) {
    if (c.compare(0, prefix.size(), prefix) == 0) out.push_back(c);
  }
  return out;
}

}  // namespace cnc::interp
