#include "kinematics/trivkins.hpp"

#include "core/hal/types.hpp"
#include "core/util/strings.hpp"

namespace cnc::kin {

KinematicsType parse_kinstype(std::string_view text, const std::string& who) {
  const std::string t = to_lower(text);
  // LinuxCNC reads the first letter only; whole words are accepted too, and
  // "identity" must not read as I (inverse only).
  if (t == "1" || t == "identity") return KinematicsType::Identity;
  if (t == "b" || t == "both") return KinematicsType::Both;
  if (t == "f" || t == "forward" || t == "forward-only") return KinematicsType::ForwardOnly;
  if (t == "i" || t == "inverse" || t == "inverse-only") return KinematicsType::InverseOnly;
  throw hal::HalError(who + ": kinstype=" + std::string(text) +
                      ": expected 1 (identity), B (both), F (forward only) or I (inverse only)");
}

}  // namespace cnc::kin
