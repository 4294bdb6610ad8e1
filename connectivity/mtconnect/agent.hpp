// The MTConnect agent's model (docs/connectivity.md): the device model of
// the machine, the sequence buffer of observations, and the XML documents
// of MTConnect 1.3 (probe, current, sample, assets, errors). No HTTP and no
// controller here: update() takes a status block (or none: the controller
// is unavailable), which makes the model testable on its own.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"

namespace cnc::mtconnect {

inline constexpr const char* kVersion = "1.3.0";

struct AgentOptions {
  std::string device_name = "cnc";
  std::string uuid = "cnc-001";
  std::string sender = "cnc-mtconnect";
  std::size_t buffer_size = 4096;  // observations kept for /sample
  uint32_t axis_mask = 0x7;        // axes in the model (bit 0 = X .. 8 = W)
};

enum class Category { Sample, Event, Condition };

struct Component {
  std::string element;  // Controller, Path, Axes, Linear, Rotary
  std::string id;
  std::string name;
  int parent = -1;      // index; -1: the device
};

struct DataItem {
  std::string id;
  Category category;
  std::string type;     // POSITION, EXECUTION, SYSTEM, ...
  std::string element;  // the Streams element: Position, Execution, ... (conditions: their level)
  std::string sub_type;
  std::string units;
  std::string coordinate_system;
  int component = -1;   // -1: the device itself
};

struct Observation {
  uint64_t sequence = 0;
  int64_t time_ns = 0;
  int item = 0;
  std::string value;        // UNAVAILABLE when not known
  std::string level;        // conditions: Normal, Warning, Fault, Unavailable
  std::string native_code;  // conditions: the message's source
};

class Agent {
 public:
  explicit Agent(AgentOptions options);

  // One look at the controller: adds an observation for every data item
  // whose value changed. `s` null: the controller is not reachable (every
  // item UNAVAILABLE).
  void update(const ipc::Status* s, int64_t now_ns);
  // A message of the controller's error channel: errors become a Fault of
  // the SYSTEM condition (LOGIC_PROGRAM when from the interpreter), texts
  // and displays the MESSAGE event.
  void message(const Message& m, int64_t now_ns);

  std::string probe(int64_t now_ns) const;
  std::string current(int64_t now_ns) const;
  // Observations from sequence `from` (0: the first held), at most `count`.
  // Out of range: an MTConnectError document and `http_status` 400.
  std::string sample(uint64_t from, uint64_t count, int64_t now_ns, int& http_status) const;
  std::string assets(int64_t now_ns) const;
  std::string error(const std::string& code, const std::string& text, int64_t now_ns) const;

  uint64_t next_sequence() const noexcept { return next_seq_; }
  uint64_t first_sequence() const noexcept { return buffer_.empty() ? next_seq_ : buffer_.front().sequence; }
  const std::vector<DataItem>& items() const noexcept { return items_; }

 private:
  int add_component(std::string element, std::string id, std::string name, int parent);
  int add_item(DataItem item);
  void set(int item, const std::string& value, int64_t now_ns);
  void set_condition(int item, const std::string& level, const std::string& text, const std::string& code,
                     int64_t now_ns);
  std::string header(const char* kind, int64_t now_ns) const;
  std::string streams(const std::vector<const Observation*>& obs, int64_t now_ns) const;
  std::string observation_xml(const Observation& o) const;

  AgentOptions options_;
  uint64_t instance_id_;
  std::vector<Component> components_;
  std::vector<DataItem> items_;
  std::vector<Observation> latest_;  // by item
  std::deque<Observation> buffer_;
  uint64_t next_seq_ = 1;
  // Data item indices.
  int avail_ = -1, estop_ = -1, mode_ = -1, system_ = -1, execution_ = -1, program_ = -1, line_ = -1,
      feedrate_ = -1, feed_ovr_ = -1, rapid_ovr_ = -1, tool_ = -1, message_ = -1, logic_ = -1, spindle_speed_ = -1,
      spindle_cmd_ = -1, spindle_load_ = -1, spindle_ovr_ = -1;
  int position_[kNumAxes];
  int load_[kNumAxes];
  int last_task_state_ = 0;
};

// Text for XML: &, <, >, " escaped.
std::string xml_escape(const std::string& s);
// 2026-11-26T21:00:00.123456Z
std::string iso_time(int64_t realtime_ns);

}  // namespace cnc::mtconnect
