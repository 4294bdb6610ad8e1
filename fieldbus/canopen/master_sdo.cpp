// The CANopen master, SDO access: client transfers for tools and the
// drive layer, and the servo thread's non-blocking SDO slots.
#include "fieldbus/canopen/master_internal.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <future>
#include <stdexcept>

#include "core/util/messages.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {

using namespace master_detail;

// ------------------------------------------------------------ SDO access

void Master::sdo_upload(uint8_t node, ObjectAddress a, SdoClient::Done done, SdoMode mode) {
  post([this, node, a, done = std::move(done), mode](int64_t) mutable {
    NodeRt* n = find(node);
    if (!n) {
      SdoResult r;
      r.addr = a;
      r.upload = true;
      r.abort_code = abort_code::kResourceNotAvailable;
      r.aborted_by_client = true;
      if (done) done(r);
      return;
    }
    n->sdo->upload(a, std::move(done), mode);
  });
}

void Master::sdo_download(uint8_t node, ObjectAddress a, std::vector<uint8_t> data, SdoClient::Done done, SdoMode mode) {
  post([this, node, a, data = std::move(data), done = std::move(done), mode](int64_t) mutable {
    NodeRt* n = find(node);
    if (!n) {
      SdoResult r;
      r.addr = a;
      r.abort_code = abort_code::kResourceNotAvailable;
      r.aborted_by_client = true;
      if (done) done(r);
      return;
    }
    n->sdo->download(a, std::move(data), std::move(done), mode);
  });
}

SdoResult Master::sdo_upload_wait(uint8_t node, ObjectAddress a, SdoMode mode) {
  if (std::this_thread::get_id() == acyclic_thread_id_) throw std::logic_error("sdo_upload_wait from the acyclic thread would deadlock");
  if (!thread_running()) throw std::logic_error("sdo_upload_wait needs the acyclic thread (start_thread)");
  auto p = std::make_shared<std::promise<SdoResult>>();
  auto f = p->get_future();
  sdo_upload(node, a, [p](const SdoResult& r) { p->set_value(r); }, mode);
  return f.get();
}

SdoResult Master::sdo_download_wait(uint8_t node, ObjectAddress a, std::vector<uint8_t> data, SdoMode mode) {
  if (std::this_thread::get_id() == acyclic_thread_id_) throw std::logic_error("sdo_download_wait from the acyclic thread would deadlock");
  if (!thread_running()) throw std::logic_error("sdo_download_wait needs the acyclic thread (start_thread)");
  auto p = std::make_shared<std::promise<SdoResult>>();
  auto f = p->get_future();
  sdo_download(node, a, std::move(data), [p](const SdoResult& r) { p->set_value(r); }, mode);
  return f.get();
}

// Realtime SDO slots: the servo thread claims a free slot and fills it; the
// acyclic thread runs the transfer and marks it done.
int Master::rt_sdo_read(uint8_t node, ObjectAddress a) noexcept {
  for (std::size_t i = 0; i < rt_sdo_.size(); ++i) {
    int expected = 0;
    if (rt_sdo_[i].state.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
      RtSdoSlot& s = rt_sdo_[i];
      s.node = node;
      s.addr = a;
      s.write = false;
      s.result = RtSdoResult{};
      s.state.store(2, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

int Master::rt_sdo_write(uint8_t node, ObjectAddress a, uint32_t value, uint8_t size) noexcept {
  if (size < 1 || size > 4) return -1;
  for (std::size_t i = 0; i < rt_sdo_.size(); ++i) {
    int expected = 0;
    if (rt_sdo_[i].state.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
      RtSdoSlot& s = rt_sdo_[i];
      s.node = node;
      s.addr = a;
      s.write = true;
      s.value = value;
      s.size = size;
      s.result = RtSdoResult{};
      s.state.store(2, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

bool Master::rt_sdo_poll(int handle, RtSdoResult& out) noexcept {
  if (handle < 0 || static_cast<std::size_t>(handle) >= rt_sdo_.size()) return false;
  RtSdoSlot& s = rt_sdo_[static_cast<std::size_t>(handle)];
  if (s.state.load(std::memory_order_acquire) != 4) return false;
  out = s.result;
  s.state.store(0, std::memory_order_release);
  return true;
}

void Master::service_rt_sdo() {
  for (auto& s : rt_sdo_) {
    if (s.state.load(std::memory_order_acquire) != 2) continue;
    s.state.store(3, std::memory_order_relaxed);
    RtSdoSlot* slot = &s;
    auto done = [slot](const SdoResult& r) {
      slot->result.abort_code = r.abort_code;
      if (r.ok() && r.upload) {
        slot->result.size = static_cast<uint8_t>(std::min<std::size_t>(r.data.size(), 4));
        slot->result.value = as_u32(r.data);
      }
      slot->state.store(4, std::memory_order_release);
    };
    NodeRt* n = find(s.node);
    if (!n) {
      s.result.abort_code = abort_code::kResourceNotAvailable;
      s.state.store(4, std::memory_order_release);
      continue;
    }
    if (s.write) n->sdo->download(s.addr, u32_bytes(s.value, s.size), done, SdoMode::Expedited);
    else n->sdo->upload(s.addr, done);
  }
}

}  // namespace cnc::canopen
