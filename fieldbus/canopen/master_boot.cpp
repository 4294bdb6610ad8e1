// The CANopen master, boot: NMT reset, the SDO steps that check and
// configure each node, start, and the reboot of one node.
#include "fieldbus/canopen/master_internal.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "core/util/messages.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {

using namespace master_detail;

// ------------------------------------------------------------ boot

void Master::begin_boot() {
  {
    std::lock_guard<std::mutex> lock(boot_mutex_);
    boot_error_.clear();
  }
  boot_state_.store(BootState::Running, std::memory_order_release);
  // A plan above its budget runs only with LOAD_OVERRIDE, and says so at
  // every boot, as an error message: TPDOs may arrive late.
  if (const std::string problem = config_.load_problem(); !problem.empty()) {
    message(true, config_.name, "LOAD_OVERRIDE: running a bus plan that does not fit: " + problem);
  }
  post([this](int64_t now) {
    booting_ = true;
    start_sent_ = false;
    boot_started_ns_ = now;
    cyclic_enabled_.store(false);
    for (const auto& n : nodes_) {
      n->sdo->cancel_all(abort_code::kGeneral, now);
      ++n->generation;
      n->rebooting = false;
      n->phase = config_.reset_nodes ? NodeRt::Phase::WaitBootUp : NodeRt::Phase::Steps;
      n->step = 0;
      n->step_active = false;
      n->boot_up_seen = false;
      n->deadline_ns = now + config_.boot_timeout_ns;
      n->error.clear();
      n->monitor = false;
      n->in_cycle.store(false);
      n->booted.store(false);
      n->fault.store(false);
      n->hb_lost.store(false);
      if (config_.reset_nodes) send_nmt(NmtCommand::ResetCommunication, n->cfg.id);
    }
  });
}

std::string Master::boot_error() const {
  std::lock_guard<std::mutex> lock(boot_mutex_);
  return boot_error_;
}

void Master::node_failed(NodeRt& n, const std::string& why) {
  n.phase = NodeRt::Phase::Failed;
  n.error = n.cfg.label() + ": " + why;
  n.sdo->cancel_all(abort_code::kGeneral, last_poll_ns_);
  ++n.generation;
  if (!n.cfg.mandatory) {
    n.fault.store(true);
    message(false, n.source, n.error + " (optional node: start-up continues without it)");
  }
}

void Master::boot_node(NodeRt& n, int64_t now_ns) {
  using Phase = NodeRt::Phase;
  switch (n.phase) {
    case Phase::WaitBootUp:
      if (n.boot_up_seen) {
        n.phase = Phase::Steps;
      } else if (now_ns > n.deadline_ns) {
        node_failed(n, "not found: no boot-up message within " + std::to_string(config_.boot_timeout_ns / 1'000'000) +
                           " ms after NMT reset communication (power, wiring, node-ID, bit rate?)");
        return;
      } else {
        return;
      }
      [[fallthrough]];
    case Phase::Steps: {
      if (n.step_active) return;
      if (n.step >= n.steps.size()) {
        n.phase = Phase::Ready;
        return;
      }
      const Step& s = n.steps[n.step];
      n.step_active = true;
      const uint64_t gen = n.generation;
      auto done = [this, &n, gen](const SdoResult& r) {
        if (n.generation != gen) return;
        n.step_active = false;
        const Step& st = n.steps[n.step];
        const std::string obj = addr_text(st.addr);
        if (!r.ok()) {
          if (st.kind != Step::Kind::Expect && st.may_be_missing &&
              (r.abort_code == abort_code::kNoObject || r.abort_code == abort_code::kNoSubIndex)) {
            ++n.step;
            return;
          }
          const std::string code = r.abort_text();
          if (n.step == 0 && r.abort_code == abort_code::kTimeout && r.aborted_by_client) {
            node_failed(n, "not found: no answer to SDO upload " + obj + " (device type) within " +
                               std::to_string(config_.sdo_timeout_ns / 1'000'000) + " ms");
          } else if (st.kind == Step::Kind::Write) {
            node_failed(n, "writing " + obj + " = " + hexbytes(st.data) + " (" + st.what + ") refused: " + code);
          } else {
            node_failed(n, "reading " + obj + " (" + st.what + ") failed: " + code);
          }
          return;
        }
        if (st.kind != Step::Kind::Write && !st.data.empty()) {
          // Values up to 4 bytes compare as numbers under the mask (the
          // identity as U32, COB-IDs without the RTR bit), longer ones bytewise.
          const bool same = st.data.size() <= 4 && r.data.size() <= 4
                                ? (as_u32(r.data) & st.mask) == (as_u32(st.data) & st.mask)
                                : r.data == st.data;
          if (!same) {
            if (st.kind == Step::Kind::Expect) {
              node_failed(n, (st.addr.index == 0x1018 ? "identity " : "") + obj + " " + st.what + " is " +
                                 hexbytes(r.data) + ", expected " + hexbytes(st.data) + " (wrong device at this node-ID?)");
            } else {
              node_failed(n, "verification of " + obj + " (" + st.what + ") failed: the device has " + hexbytes(r.data) +
                                 " after " + hexbytes(st.data) + " was written");
            }
            return;
          }
        }
        ++n.step;
      };
      if (s.kind == Step::Kind::Write) n.sdo->download(s.addr, s.data, done);
      else n.sdo->upload(s.addr, done);
      return;
    }
    case Phase::WaitOperational:
      if (n.cfg.heartbeat_ms == 0 || nmt_state_from_byte(n.state.load()) == NmtState::Operational) {
        n.phase = Phase::Done;
        n.booted.store(true);
      } else if (now_ns > n.deadline_ns) {
        node_failed(n, std::string("did not enter operational within ") + std::to_string(config_.boot_timeout_ns / 1'000'000) +
                           " ms after NMT start (its heartbeat says " + to_string(nmt_state_from_byte(n.state.load())) + ")");
      }
      return;
    default:
      return;
  }
}

void Master::run_boot(int64_t now_ns) {
  using Phase = NodeRt::Phase;
  for (const auto& n : nodes_) boot_node(*n, now_ns);
  // A mandatory node that failed stops the start-up.
  for (const auto& n : nodes_) {
    if (n->phase == Phase::Failed && n->cfg.mandatory) {
      booting_ = false;
      for (const auto& other : nodes_) {
        other->sdo->cancel_all(abort_code::kGeneral, now_ns);
        ++other->generation;
      }
      const std::string why = "start-up stopped: " + n->error;
      message(true, config_.name, why);
      {
        // Under the lock, so that boot() cannot miss the notification.
        std::lock_guard<std::mutex> lock(boot_mutex_);
        boot_error_ = config_.name + ": " + why;
        boot_state_.store(BootState::Failed, std::memory_order_release);
      }
      boot_cv_.notify_all();
      return;
    }
  }
  auto all = [&](std::initializer_list<Phase> phases) {
    return std::all_of(nodes_.begin(), nodes_.end(), [&](const auto& n) {
      return n->phase == Phase::Failed || std::find(phases.begin(), phases.end(), n->phase) != phases.end();
    });
  };
  if (!start_sent_ && all({Phase::Ready})) {
    start_sent_ = true;
    if (config_.start_all) send_nmt(NmtCommand::Start, 0);
    for (const auto& n : nodes_) {
      if (n->phase != Phase::Ready) continue;
      if (!config_.start_all) send_nmt(NmtCommand::Start, n->cfg.id);
      n->phase = Phase::WaitOperational;
      n->deadline_ns = now_ns + config_.boot_timeout_ns;
      n->in_cycle.store(true);
      n->monitor = n->cfg.heartbeat_ms > 0;
      n->last_hb_ns = now_ns;
    }
    return;
  }
  if (start_sent_ && all({Phase::Done})) {
    booting_ = false;
    std::size_t up = 0;
    for (const auto& n : nodes_) up += n->phase == Phase::Done;
    const can::BusLoad l = config_.load();
    char text[240];
    std::snprintf(text, sizeof text,
                  "%zu of %zu nodes operational in %.0f ms; planned bus load %.1f %% on average, busiest cycle %.1f %% "
                  "(worst case)",
                  up, nodes_.size(), static_cast<double>(now_ns - boot_started_ns_) / 1e6, l.worst_case() * 100,
                  l.worst_cycle() * 100);
    message(false, config_.name, text);
    cyclic_enabled_.store(true, std::memory_order_release);
    {
      std::lock_guard<std::mutex> lock(boot_mutex_);
      boot_state_.store(BootState::Succeeded, std::memory_order_release);
    }
    boot_cv_.notify_all();
  }
}

void Master::boot() {
  if (!thread_running()) start_thread();
  begin_boot();
  std::unique_lock<std::mutex> lock(boot_mutex_);
  boot_cv_.wait(lock, [&] { return boot_state() != BootState::Running; });
  if (boot_state() == BootState::Failed) throw std::runtime_error(boot_error_);
}

void Master::reboot_node(uint8_t node) {
  post([this, node](int64_t now) {
    NodeRt* n = find(node);
    if (!n || booting_) return;
    n->sdo->cancel_all(abort_code::kGeneral, now);
    ++n->generation;
    n->reboot_request.store(false);
    n->in_cycle.store(false);
    n->booted.store(false);
    n->monitor = false;
    n->fault.store(false);
    n->hb_lost.store(false);
    n->pdo_missed.store(0);
    n->step = 0;
    n->step_active = false;
    n->boot_up_seen = false;
    n->deadline_ns = now + config_.boot_timeout_ns;
    n->phase = config_.reset_nodes ? NodeRt::Phase::WaitBootUp : NodeRt::Phase::Steps;
    if (config_.reset_nodes) send_nmt(NmtCommand::ResetCommunication, n->cfg.id);
    message(false, n->source, n->cfg.label() + ": rebooting");
    n->rebooting = true;  // poll() carries it through the phases
  });
}

void Master::continue_reboot(NodeRt& n, int64_t now_ns) {
  boot_node(n, now_ns);
  if (n.phase == NodeRt::Phase::Ready) {
    send_nmt(NmtCommand::Start, n.cfg.id);
    n.phase = NodeRt::Phase::WaitOperational;
    n.deadline_ns = now_ns + config_.boot_timeout_ns;
    n.in_cycle.store(true);
    n.monitor = n.cfg.heartbeat_ms > 0;
    n.last_hb_ns = now_ns;
  }
  if (n.phase == NodeRt::Phase::Done) {
    n.rebooting = false;
    message(false, n.source, n.cfg.label() + ": back in operation");
  } else if (n.phase == NodeRt::Phase::Failed) {
    n.rebooting = false;
    n.fault.store(true);
    message(true, n.source, n.error);
  }
}

}  // namespace cnc::canopen
