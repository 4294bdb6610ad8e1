// The EtherCAT master, worker thread: requests from the servo thread, the
// way to OP, fault reports, emergencies and restarts.
#include "fieldbus/ethercat/master_internal.hpp"

#include <time.h>

#include <algorithm>
#include <cstdarg>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <future>

#include "core/util/messages.hpp"
#include "cia402/error_codes.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#ifdef CNC_ETHERCAT_ESI
#include "fieldbus/ethercat/esi.hpp"
#endif

namespace cnc::ethercat {

using namespace master_detail;

// ---------------------------------------------------------------- worker

void Master::start_worker() {
  if (worker_.joinable()) return;
  stop_.store(false);
  worker_ = std::thread([this] { worker_loop(); });
}

void Master::worker_rt_requests() {
  for (RtRequest& r : rt_) {
    if (r.state.load(std::memory_order_acquire) != 1) continue;
    SlaveInfo* s = find(r.position);
    SdoResult res;
    if (!s) res.abort_code = canopen::abort_code::kNoObject;
    else if (r.write) res = do_download(*s, r.index, r.sub, le(r.value, r.size ? r.size : 4));
    else res = do_upload(*s, r.index, r.sub);
    r.abort_code = res.ok ? 0 : (res.abort_code ? res.abort_code : canopen::abort_code::kTimeout);
    r.result = 0;
    for (std::size_t i = 0; i < res.data.size() && i < 4; ++i) r.result |= uint32_t{res.data[i]} << (8 * i);
    r.state.store(2, std::memory_order_release);
  }
}

void Master::worker_go_op() {
  try {
    for (SlaveInfo& s : slaves_) request_state(s, AlState::Op);
  } catch (const StartupError& e) {
    {
      std::lock_guard lock(fault_mutex_);
      fault_text_ = e.what();
    }
    phase_.store(BusPhase::Fault, std::memory_order_release);
    fault_reported_ = true;
    post(true, e.what());
    return;
  }
  counters_.consecutive_bad.store(0);
  BusPhase expected = BusPhase::SafeOp;
  if (phase_.compare_exchange_strong(expected, BusPhase::Op)) {
    post(false, fmt("%zu slave%s in OP, cycle %lld us", slaves_.size(), slaves_.size() == 1 ? "" : "s",
                    static_cast<long long>(cfg_.cycle_ns / 1000)));
  }
}

// ------------------------------------------------------------ ESC error counters

EscErrorCounters EscErrorCounters::decode(const uint8_t* r) noexcept {
  EscErrorCounters c;
  for (unsigned p = 0; p < 4; ++p) {
    c.invalid_frames[p] = r[2 * p];
    c.rx_errors[p] = r[2 * p + 1];
    c.forwarded[p] = r[0x08 + p];
    c.lost_links[p] = r[0x10 + p];
  }
  c.processing_unit = r[0x0C];
  c.pdi = r[0x0D];
  c.read = true;
  return c;
}

bool EscErrorCounters::any() const noexcept { return !text().empty(); }

namespace {

std::string counters_text(const EscErrorCounters& now, const EscErrorCounters* before) {
  auto grown = [&](uint8_t a, uint8_t b) -> unsigned { return a >= b ? a - b : a; };  // cleared since: all new
  std::string out;
  for (unsigned p = 0; p < 4; ++p) {
    std::string port;
    auto add = [&](unsigned n, const char* one, const char* many) {
      if (n == 0) return;
      port += (port.empty() ? "" : ", ") + std::to_string(n) + " " + (n == 1 ? one : many);
    };
    add(grown(now.invalid_frames[p], before ? before->invalid_frames[p] : 0), "invalid frame", "invalid frames");
    add(grown(now.rx_errors[p], before ? before->rx_errors[p] : 0), "RX error", "RX errors");
    add(grown(now.forwarded[p], before ? before->forwarded[p] : 0), "forwarded error", "forwarded errors");
    add(grown(now.lost_links[p], before ? before->lost_links[p] : 0), "lost link", "lost links");
    if (!port.empty()) out += (out.empty() ? "" : "; ") + ("port " + std::to_string(p) + ": ") + port;
  }
  const unsigned pu = grown(now.processing_unit, before ? before->processing_unit : 0);
  const unsigned pdi = grown(now.pdi, before ? before->pdi : 0);
  if (pu) out += (out.empty() ? "" : "; ") + std::to_string(pu) + " processing-unit error" + (pu == 1 ? "" : "s");
  if (pdi) out += (out.empty() ? "" : "; ") + std::to_string(pdi) + " PDI error" + (pdi == 1 ? "" : "s");
  return out;
}

}  // namespace

std::string EscErrorCounters::text() const { return counters_text(*this, nullptr); }
std::string EscErrorCounters::growth_since(const EscErrorCounters& before) const {
  return counters_text(*this, before.read ? &before : nullptr);
}

std::vector<EscErrorCounters> Master::error_counters() const {
  std::lock_guard lock(error_counters_mutex_);
  return error_counters_;
}

std::vector<EscErrorCounters> Master::read_error_counters() {
  (void)run_on_worker([this] {
    update_error_counters();
    return SdoResult{true, 0, {}, {}};
  });
  return error_counters();
}

void Master::update_error_counters(std::size_t up_to) {
  std::vector<std::pair<unsigned, EscErrorCounters>> now;
  for (const SlaveInfo& s : slaves_) {
    if (s.position > up_to) break;
    uint8_t r[EscErrorCounters::kBytes] = {};
    if (fprd(s, reg::kRxErrors, r, sizeof r) != 1) continue;
    now.emplace_back(s.position, EscErrorCounters::decode(r));
  }
  std::vector<std::string> grew;
  {
    std::lock_guard lock(error_counters_mutex_);
    error_counters_.resize(slaves_.size());
    for (const auto& [position, c] : now) {
      EscErrorCounters& stored = error_counters_[position - 1];
      const std::string g = c.growth_since(stored);
      if (!g.empty()) grew.push_back(slave_label(position) + ": " + g);
      stored = c;
      {
        for (unsigned p = 0; p < 4; ++p) {
          state_[position - 1].port_rx_errors[p].store(static_cast<uint16_t>(c.invalid_frames[p] + c.rx_errors[p]));
          state_[position - 1].port_lost_links[p].store(c.lost_links[p]);
        }
      }
    }
  }
  for (const std::string& g : grew) {
    post(false, "error counters " + g +
                    " (an invalid frame or RX error counts at the port it entered: the cable or connector there, "
                    "or the slave before it)");
  }
}

void Master::clear_error_counters() {
  const uint8_t zero[EscErrorCounters::kBytes] = {};
  for (const SlaveInfo& s : slaves_) {
    (void)fpwr(s, reg::kRxErrors, zero, 0x0E);         // 0x0300-0x030D
    (void)fpwr(s, reg::kRxErrors + 0x10, zero, 4);     // lost-link counters 0x0310-0x0313
  }
  for (std::size_t i = 0; i < slaves_.size(); ++i) {
    for (unsigned p = 0; p < 4; ++p) {
      state_[i].port_rx_errors[p].store(0);
      state_[i].port_lost_links[p].store(0);
    }
  }
  std::lock_guard lock(error_counters_mutex_);
  error_counters_.assign(slaves_.size(), EscErrorCounters{});
}

void Master::worker_report_fault() {
  fault_reported_ = true;
  const bool al = al_changed_.load();
  std::string text = "safe stop: ";
  if (al) {
    text += "a slave left OP";
  } else {
    std::string last = fault_lost_.load() ? std::string("last frame lost")
                                          : fmt("last working counter %u, expected %u", fault_wkc_.load(), expected_wkc_);
    if (fault_lost_.load() && bad_wkc_.load() >= 0) {
      last += fmt(", last wrong working counter %d, expected %u", bad_wkc_.load(), expected_wkc_);
    }
    text += fmt("%u consecutive cycles without valid process data (%s; frames lost %llu, "
                "late %llu, working-counter errors %llu)",
                fault_bad_.load(), last.c_str(),
                static_cast<unsigned long long>(counters_.frames_lost.load()),
                static_cast<unsigned long long>(counters_.frames_late.load()),
                static_cast<unsigned long long>(counters_.wkc_errors.load()));
  }
  uint8_t b[2] = {};
  const auto count = transact(Command::BRD, 0, b, 2);
  if (!count) {
    text += "; no frame comes back at all (cable to the first slave, interface down?)";
  } else if (*count < slaves_.size()) {
    text += fmt("; only %u of %zu slaves answer: link lost after %s (cable break or power?)", *count, slaves_.size(),
                *count == 0 ? "the master" : slave_label(*count).c_str());
  }
  for (SlaveInfo& s : slaves_) {
    if (!count || s.position > *count) break;  // unreachable: do not wait for each of them
    uint8_t st[6] = {};
    if (fprd(s, reg::kAlStatus, st, 6) != 1) continue;
    state_[s.position - 1].al_state.store(st[0] & 0x0F);
    state_[s.position - 1].al_code.store(get16(st + 4));
    if ((st[0] & 0x0F) != static_cast<uint8_t>(AlState::Op) || (st[0] & kAlErrorFlag)) {
      text += fmt("; %s is in %s%s", slave_label(s.position).c_str(), al_state_name(st[0]),
                  (st[0] & kAlErrorFlag) ? "" : "");
      if (st[0] & kAlErrorFlag) {
        text += fmt(" with AL status code 0x%04X %s", get16(st + 4), al_status_text(get16(st + 4)));
      }
    }
  }
  // Where frames were corrupted, if the slaves' counters saw it.
  if (count && *count > 0) update_error_counters(*count);
  const std::vector<EscErrorCounters> counters = error_counters();
  for (std::size_t k = 0; k < counters.size(); ++k) {
    if (!counters[k].any()) continue;
    text += fmt("; %s error counters: %s", slave_label(static_cast<unsigned>(k + 1)).c_str(), counters[k].text().c_str());
  }
  {
    std::lock_guard lock(fault_mutex_);
    fault_text_ = cfg_.name + ": " + text;
  }
  post(true, text);
}

void Master::worker_poll_emergencies() {
  for (SlaveInfo& s : slaves_) {
    if (!s.sii.has_coe()) continue;
    uint8_t st[1] = {};
    if (fprd(s, reg::kSm0 + 8 + 5, st, 1) != 1 || !(st[0] & sm::kStatusFull)) continue;
    std::vector<uint8_t> in;
    std::string error;
    if (!mailbox_read(s, in, 0, error)) continue;
    const MailboxHeader h = MailboxHeader::decode(in.data());
    if (h.type == MailboxType::CoE && h.length >= 10 &&
        coe_service(get16(in.data() + kMailboxHeader)) == CoeService::Emergency) {
      handle_emergency(s, in.data() + kMailboxHeader + 2);
    }
  }
}

void Master::worker_restart() {
  // The servo thread stops touching the frame and the image first.
  phase_.store(BusPhase::Down, std::memory_order_release);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const std::vector<SlaveInfo> before = slaves_;
  const std::size_t out = outputs_.size(), in = inputs_.size();
  try {
    scanned_ = planned_ = false;
    scan();  // refuses another slave count
    // The drives hold slots into the image: the bus must come back as it was.
    for (std::size_t i = 0; i < slaves_.size(); ++i) {
      if (slaves_[i].sii.vendor_id != before[i].sii.vendor_id || slaves_[i].sii.product_code != before[i].sii.product_code ||
          slaves_[i].sii.serial != before[i].sii.serial) {
        fail_slave(slaves_[i], "restart: another device than before at this position");
      }
    }
    plan();
    if (outputs_.size() != out || inputs_.size() != in) fail("restart: the process image changed");
    outstanding_ = false;
    held_size_ = 0;
    lock_.reset();
    al_changed_.store(false);
    counters_.consecutive_bad.store(0);
    start_up();  // ends in SAFEOP; OP follows once the cycle is good
    fault_reported_ = false;
    {
      std::lock_guard lock(fault_mutex_);
      fault_text_.clear();
    }
    post(false, "restarted after the fault: every slave found again");
  } catch (const std::exception& e) {
    for (std::size_t i = 0; i < slaves_.size() && i < before.size(); ++i) slaves_[i] = before[i];
    scanned_ = planned_ = true;
    {
      std::lock_guard lock(fault_mutex_);
      fault_text_ = e.what();
    }
    fault_reported_ = true;
    phase_.store(BusPhase::Fault, std::memory_order_release);
    post(true, e.what());
  }
}

void Master::run_queued_jobs() {
  for (;;) {
    std::function<void()> job;
    {
      std::lock_guard lock(jobs_mutex_);
      if (jobs_.empty()) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job();
  }
}

void Master::worker_loop() {
  worker_id_ = std::this_thread::get_id();
  int64_t next_emcy = 0, next_counters = 0;
  bool op_tried = false;
  while (!stop_.load()) {
    run_queued_jobs();
    worker_rt_requests();
    // Every reply reaches both sockets on a raw link: drop the cyclic ones
    // this socket collected, so that its buffer never fills.
    drain(*acyclic_link_);
    const BusPhase ph = phase();
    if (restart_requested_.exchange(false)) {
      worker_restart();
      op_tried = false;
      continue;
    }
    if (ph == BusPhase::SafeOp && !op_tried && good_cycles_.load() >= cfg_.op_after_good_cycles) {
      op_tried = true;
      worker_go_op();
    }
    if (phase() == BusPhase::Fault && !fault_reported_) worker_report_fault();
    const int64_t now = monotonic_ns();
    if (now >= next_emcy && (ph == BusPhase::SafeOp || ph == BusPhase::Op)) {
      next_emcy = now + 20'000'000;
      worker_poll_emergencies();
    }
    if (now >= next_counters && (ph == BusPhase::SafeOp || ph == BusPhase::Op)) {
      next_counters = now + 1'000'000'000;
      update_error_counters();
    }
    std::unique_lock lock(jobs_mutex_);
    jobs_cv_.wait_for(lock, std::chrono::milliseconds(1), [this] { return !jobs_.empty() || stop_.load(); });
  }
}

}  // namespace cnc::ethercat
