// The EtherCAT master, cyclic side (servo thread): the process-data frame
// out and back.
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

// ---------------------------------------------------------------- cycle

void Master::cyclic_write(int64_t) noexcept {
  const BusPhase ph = phase_.load(std::memory_order_acquire);
  if (ph == BusPhase::Down) return;
  cyclic_index_ = static_cast<uint8_t>((cyclic_index_ + 1) & 0x7F);
  for (std::size_t off : {lrw_offset_, frmw_offset_, al_offset_, diff_offset_}) {
    if (off == 0) continue;
    DatagramRef d(tx_.data() + off - kDatagramHeader);
    tx_[off - kDatagramHeader + 1] = cyclic_index_;
    std::memset(d.data(), 0, d.length());
    d.set_wkc(0);
  }
  if (!outputs_.empty()) std::memcpy(tx_.data() + lrw_offset_, outputs_.data(), outputs_.size());
  if (cyclic_link_->send(tx_.data(), tx_size_)) {
    counters_.frames_sent.fetch_add(1, std::memory_order_relaxed);
    outstanding_ = true;
    sent_in_op_ = ph == BusPhase::Op;
    if (cfg_.spin_for_reply_ns > 0) spin_for_reply();
  } else {
    counters_.send_errors.fetch_add(1, std::memory_order_relaxed);
    outstanding_ = false;
  }
}

void Master::spin_for_reply() noexcept {
  const int64_t t0 = monotonic_ns();
  while (monotonic_ns() - t0 < cfg_.spin_for_reply_ns) {
    const std::size_t n = cyclic_link_->receive(held_.data(), 0);
    if (n == 0) continue;
    FrameView v;
    if (parse_frame(held_.data(), n, v) != ParseResult::Ok || v.datagrams[0].index() != cyclic_index_) continue;
    rtt_.add(monotonic_ns() - t0);
    held_size_ = n;
    return;
  }
}

void Master::cyclic_read(int64_t) noexcept {
  const BusPhase ph = phase_.load(std::memory_order_acquire);
  if (ph == BusPhase::Down) return;
  bool got = false, good = false;
  for (;;) {
    std::size_t n = 0;
    if (held_size_ > 0) {
      std::memcpy(rx_.data(), held_.data(), held_size_);
      n = held_size_;
      held_size_ = 0;
    } else {
      n = cyclic_link_->receive(rx_.data(), 0);
    }
    if (n == 0) break;
    FrameView v;
    if (parse_frame(rx_.data(), n, v) != ParseResult::Ok) continue;
    const uint8_t idx = v.datagrams[0].index();
    if (idx & 0x80) continue;  // the worker's
    if (!outstanding_ || idx != cyclic_index_ || got) {
      counters_.frames_late.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    got = true;
    const DatagramRef lrw(rx_.data() + lrw_offset_ - kDatagramHeader);
    const uint16_t wkc = lrw.wkc();
    counters_.last_wkc.store(wkc, std::memory_order_relaxed);
    good = wkc == expected_wkc_;
    if (good) {
      if (!inputs_.empty()) std::memcpy(inputs_.data(), lrw.data() + outputs_.size(), inputs_.size());
    } else {
      counters_.wkc_errors.fetch_add(1, std::memory_order_relaxed);
      bad_wkc_.store(static_cast<int32_t>(wkc), std::memory_order_relaxed);
    }
    if (frmw_offset_ && cfg_.dc_lock) {
      const DatagramRef f(rx_.data() + frmw_offset_ - kDatagramHeader);
      if (f.wkc() > 0) phase_adjust_.fetch_add(lock_.update(static_cast<int64_t>(get64(f.data()))), std::memory_order_relaxed);
    }
    if (diff_offset_) {
      const DatagramRef f(rx_.data() + diff_offset_ - kDatagramHeader);
      counters_.dc_sync_diff_ns.store(get32(f.data()) & 0x7FFFFFFF, std::memory_order_relaxed);
    }
    const DatagramRef al(rx_.data() + al_offset_ - kDatagramHeader);
    const uint16_t al_or = get16(al.data());
    counters_.al_status_or.store(al_or, std::memory_order_relaxed);
    if (ph == BusPhase::Op && sent_in_op_ && (al_or & 0x1F) != static_cast<uint8_t>(AlState::Op) && al.wkc() > 0) {
      al_changed_.store(true, std::memory_order_relaxed);
      good = false;
    }
  }
  if (!outstanding_ && !got) return;  // nothing was sent last cycle (first cycle, send error counted there)
  if (outstanding_ && !got) counters_.frames_lost.fetch_add(1, std::memory_order_relaxed);
  outstanding_ = false;
  counters_.inputs_fresh.store(good, std::memory_order_relaxed);
  counters_.cycles.fetch_add(1, std::memory_order_relaxed);
  if (good) {
    counters_.consecutive_bad.store(0, std::memory_order_relaxed);
    bad_wkc_.store(-1, std::memory_order_relaxed);
    good_cycles_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const uint32_t bad = counters_.consecutive_bad.fetch_add(1, std::memory_order_relaxed) + 1;
  const bool al_dropped = al_changed_.load(std::memory_order_relaxed);
  if ((ph == BusPhase::SafeOp || ph == BusPhase::Op) &&
      (al_dropped || (cfg_.miss_limit > 0 && bad >= cfg_.miss_limit))) {
    fault_wkc_.store(counters_.last_wkc.load(std::memory_order_relaxed), std::memory_order_relaxed);
    fault_bad_.store(bad, std::memory_order_relaxed);
    fault_lost_.store(!got, std::memory_order_relaxed);
    phase_.store(BusPhase::Fault, std::memory_order_release);  // the worker sees it within a millisecond
  }
}

}  // namespace cnc::ethercat
