// The EtherCAT master, mailbox and CoE: SDO transfers, SDO information,
// emergencies, and the servo thread's non-blocking SDO slots.
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

// ---------------------------------------------------------------- mailbox

bool Master::mailbox_write(SlaveInfo& s, const uint8_t* data, std::size_t size, std::string& error) {
  const uint16_t n = s.sii.mailbox_rx_size;
  if (n == 0 || size > n) {
    error = "no mailbox";
    return false;
  }
  std::vector<uint8_t> buf(n, 0);
  std::memcpy(buf.data(), data, size);
  const int64_t deadline = monotonic_ns() + cfg_.mailbox_timeout_ms * 1'000'000;
  for (;;) {
    if (fpwr(s, s.sii.mailbox_rx_offset, buf.data(), n) == 1) return true;
    if (monotonic_ns() > deadline) {
      error = fmt("mailbox not accepted within %lld ms (SM0 full or no answer)", static_cast<long long>(cfg_.mailbox_timeout_ms));
      return false;
    }
    sleep_ns(200'000);
  }
}

bool Master::mailbox_read(SlaveInfo& s, std::vector<uint8_t>& out, int64_t timeout_ns, std::string& error) {
  const int64_t deadline = monotonic_ns() + timeout_ns;
  const uint16_t n = s.sii.mailbox_tx_size;
  for (;;) {
    uint8_t st[1] = {};
    if (fprd(s, reg::kSm0 + 8 + 5, st, 1) == 1 && (st[0] & sm::kStatusFull)) {
      out.assign(n, 0);
      if (fprd(s, s.sii.mailbox_tx_offset, out.data(), n) == 1) return true;
    }
    if (monotonic_ns() > deadline) {
      error = fmt("no answer within %lld ms", static_cast<long long>(timeout_ns / 1'000'000));
      return false;
    }
    sleep_ns(50'000);
  }
}

void Master::handle_emergency(SlaveInfo& s, const uint8_t* d) {
  const uint16_t code = get16(d);
  const uint8_t reg = d[2];
  SlaveState& st = state_[s.position - 1];
  st.emcy_code.store(code);
  st.emcy_count.fetch_add(1);
  if (code == 0) {
    post(false, slave_label(s.position) + ": EMCY 0x0000 error reset");
  } else {
    post(true, fmt("%s: EMCY 0x%04X %s (error register 0x%02X)", slave_label(s.position).c_str(), code,
                   cia402::error_code_text(code), reg));
  }
}

bool Master::coe_exchange(SlaveInfo& s, const uint8_t* sdo, std::size_t n, std::vector<uint8_t>& reply,
                          std::string& error) {
  std::vector<uint8_t> m(kMailboxHeader + 2 + std::max<std::size_t>(n, 8), 0);
  MailboxHeader h;
  h.length = static_cast<uint16_t>(2 + std::max<std::size_t>(n, 8));
  h.type = MailboxType::CoE;
  SlaveState& st = state_[s.position - 1];
  st.mailbox_counter = static_cast<uint8_t>(st.mailbox_counter % 7 + 1);
  h.counter = st.mailbox_counter;
  h.encode(m.data());
  put16(m.data() + kMailboxHeader, coe_header(CoeService::SdoRequest));
  std::memcpy(m.data() + kMailboxHeader + 2, sdo, n);
  if (!mailbox_write(s, m.data(), m.size(), error)) return false;
  std::vector<uint8_t> in;
  for (;;) {
    if (!mailbox_read(s, in, cfg_.mailbox_timeout_ms * 1'000'000, error)) return false;
    const MailboxHeader r = MailboxHeader::decode(in.data());
    if (r.length + kMailboxHeader > in.size() || r.length < 2) {
      error = "malformed mailbox reply (length " + std::to_string(r.length) + ")";
      return false;
    }
    const uint8_t* body = in.data() + kMailboxHeader;
    if (r.type == MailboxType::Error) {
      const uint16_t detail = r.length >= 4 ? get16(body + 2) : 0;
      error = fmt("mailbox error %u: %s", detail, mailbox_error_text(detail));
      return false;
    }
    if (r.type != MailboxType::CoE) continue;
    const CoeService svc = coe_service(get16(body));
    if (svc == CoeService::Emergency && r.length >= 10) {
      handle_emergency(s, body + 2);
      continue;
    }
    if (svc != CoeService::SdoResponse && svc != CoeService::SdoRequest) continue;
    reply.assign(body + 2, body + r.length);
    return true;
  }
}

SdoResult Master::do_download(SlaveInfo& s, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data, bool ca) {
  const uint8_t ca_bit = ca ? 0x10 : 0x00;
  SdoResult res;
  std::vector<uint8_t> r;
  auto check = [&](uint8_t expect) {
    if (r.size() >= 8 && r[0] == 0x80) {
      res.abort_code = get32(r.data() + 4);
      res.error = abort_text(res.abort_code);
      return false;
    }
    if (r.size() < 1 || (r[0] & 0xF0) != (expect & 0xF0) || (expect == 0x60 && r.size() >= 4 && (get16(r.data() + 1) != index || r[3] != sub))) {
      res.error = fmt("unexpected SDO reply 0x%02X", r.empty() ? 0 : r[0]);
      return false;
    }
    return true;
  };
  const std::size_t n = data.size();
  if (n >= 1 && n <= 4) {
    uint8_t q[8] = {static_cast<uint8_t>(0x23 | ca_bit | ((4 - n) << 2))};
    put16(q + 1, index);
    q[3] = sub;
    std::memcpy(q + 4, data.data(), n);
    if (!coe_exchange(s, q, 8, r, res.error) || !check(0x60)) return res;
    res.ok = true;
    return res;
  }
  const std::size_t first_room = s.sii.mailbox_rx_size - kMailboxHeader - 2 - 8;
  const std::size_t here = std::min(n, first_room);
  std::vector<uint8_t> q(8 + here, 0);
  q[0] = static_cast<uint8_t>(0x21 | ca_bit);
  put16(q.data() + 1, index);
  q[3] = sub;
  put32(q.data() + 4, static_cast<uint32_t>(n));
  std::memcpy(q.data() + 8, data.data(), here);
  if (!coe_exchange(s, q.data(), q.size(), r, res.error) || !check(0x60)) return res;
  std::size_t pos = here;
  uint8_t toggle = 0;
  const std::size_t seg_room = s.sii.mailbox_rx_size - kMailboxHeader - 2 - 1;
  while (pos < n) {
    const std::size_t k = std::min(n - pos, seg_room);
    const bool last = pos + k == n;
    std::vector<uint8_t> seg(std::max<std::size_t>(1 + k, 8), 0);
    seg[0] = static_cast<uint8_t>((toggle << 4) | (last ? 1 : 0) | (k < 7 ? (7 - k) << 1 : 0));
    std::memcpy(seg.data() + 1, data.data() + pos, k);
    if (!coe_exchange(s, seg.data(), seg.size(), r, res.error)) return res;
    if (!check(static_cast<uint8_t>(0x20 | (toggle << 4)))) return res;
    if (((r[0] >> 4) & 1) != toggle) {
      res.error = "segment toggle bit not alternated by the slave";
      return res;
    }
    toggle ^= 1;
    pos += k;
  }
  res.ok = true;
  return res;
}

SdoResult Master::do_upload(SlaveInfo& s, uint16_t index, uint8_t sub, bool ca) {
  SdoResult res;
  std::vector<uint8_t> r;
  uint8_t q[8] = {static_cast<uint8_t>(ca ? 0x50 : 0x40)};
  put16(q + 1, index);
  q[3] = sub;
  if (!coe_exchange(s, q, 8, r, res.error)) return res;
  if (r.size() >= 8 && r[0] == 0x80) {
    res.abort_code = get32(r.data() + 4);
    res.error = abort_text(res.abort_code);
    return res;
  }
  if (r.size() < 8 || (r[0] >> 5) != 2 || get16(r.data() + 1) != index || r[3] != sub) {
    res.error = fmt("unexpected SDO reply 0x%02X", r.empty() ? 0 : r[0]);
    return res;
  }
  if (r[0] & 0x02) {  // expedited
    const std::size_t size = (r[0] & 0x01) ? 4u - ((r[0] >> 2) & 3u) : 4u;
    res.data.assign(r.begin() + 4, r.begin() + 4 + static_cast<long>(size));
    res.ok = true;
    return res;
  }
  const std::size_t size = get32(r.data() + 4);
  res.data.assign(r.begin() + 8, r.begin() + 8 + static_cast<long>(std::min(size, r.size() - 8)));
  uint8_t toggle = 0;
  while (res.data.size() < size) {
    uint8_t sq[8] = {static_cast<uint8_t>(0x60 | (toggle << 4))};
    if (!coe_exchange(s, sq, 8, r, res.error)) return res;
    if (r.size() >= 8 && r[0] == 0x80) {
      res.abort_code = get32(r.data() + 4);
      res.error = abort_text(res.abort_code);
      return res;
    }
    if (r.empty() || (r[0] >> 5) != 0 || ((r[0] >> 4) & 1) != toggle) {
      res.error = fmt("unexpected upload segment 0x%02X", r.empty() ? 0 : r[0]);
      return res;
    }
    const std::size_t avail = r.size() - 1;
    const std::size_t bytes = avail == 7 ? 7 - ((r[0] >> 1) & 7) : avail;
    res.data.insert(res.data.end(), r.begin() + 1, r.begin() + 1 + static_cast<long>(std::min(bytes, size - res.data.size())));
    toggle ^= 1;
    if (r[0] & 1) break;
  }
  if (res.data.size() != size) {
    res.error = fmt("upload ended after %zu of %zu bytes", res.data.size(), size);
    return res;
  }
  res.ok = true;
  return res;
}

SdoResult Master::do_info(SlaveInfo& s, uint8_t opcode, const std::vector<uint8_t>& request) {
  SdoResult res;
  std::vector<uint8_t> m(kMailboxHeader + 2 + 4 + request.size(), 0);
  MailboxHeader h;
  h.length = static_cast<uint16_t>(2 + 4 + request.size());
  h.type = MailboxType::CoE;
  SlaveState& st = state_[s.position - 1];
  st.mailbox_counter = static_cast<uint8_t>(st.mailbox_counter % 7 + 1);
  h.counter = st.mailbox_counter;
  h.encode(m.data());
  put16(m.data() + kMailboxHeader, coe_header(CoeService::SdoInfo));
  m[kMailboxHeader + 2] = opcode;
  std::copy(request.begin(), request.end(), m.begin() + kMailboxHeader + 6);
  if (!mailbox_write(s, m.data(), m.size(), res.error)) return res;
  std::vector<uint8_t> in;
  for (;;) {
    if (!mailbox_read(s, in, cfg_.mailbox_timeout_ms * 1'000'000, res.error)) return res;
    const MailboxHeader r = MailboxHeader::decode(in.data());
    if (r.length + kMailboxHeader > in.size() || r.length < 2) {
      res.error = "malformed mailbox reply";
      return res;
    }
    const uint8_t* body = in.data() + kMailboxHeader;
    if (r.type == MailboxType::Error) {
      const uint16_t detail = r.length >= 4 ? get16(body + 2) : 0;
      res.error = fmt("mailbox error %u: %s", detail, mailbox_error_text(detail));
      return res;
    }
    if (r.type != MailboxType::CoE) continue;
    const CoeService svc = coe_service(get16(body));
    if (svc == CoeService::Emergency && r.length >= 10) {
      handle_emergency(s, body + 2);
      continue;
    }
    if (svc != CoeService::SdoInfo || r.length < 6) continue;
    const uint8_t op = body[2] & 0x7F;
    if (op == 7) {
      res.abort_code = r.length >= 10 ? get32(body + 6) : 0;
      res.error = abort_text(res.abort_code);
      return res;
    }
    res.data.insert(res.data.end(), body + 6, body + r.length);
    if (get16(body + 4) == 0) break;  // no fragments left
  }
  res.ok = true;
  return res;
}

std::vector<uint16_t> Master::sdo_info_list(unsigned position, std::string& error) {
  SlaveInfo* s = find(position);
  if (!s) {
    error = fmt("no slave at position %u", position);
    return {};
  }
  const SdoResult r = run_on_worker([=, this] { return do_info(*s, 1, le(1, 2)); });
  std::vector<uint16_t> out;
  if (!r.ok) {
    error = r.error;
    return out;
  }
  for (std::size_t i = 2; i + 1 < r.data.size(); i += 2) out.push_back(get16(r.data.data() + i));
  return out;
}

std::optional<SdoInfoObject> Master::sdo_info_object(unsigned position, uint16_t index, std::string& error) {
  SlaveInfo* s = find(position);
  if (!s) {
    error = fmt("no slave at position %u", position);
    return std::nullopt;
  }
  const SdoResult r = run_on_worker([=, this] { return do_info(*s, 3, le(index, 2)); });
  if (!r.ok || r.data.size() < 6) {
    error = r.ok ? "object description too short" : r.error;
    return std::nullopt;
  }
  SdoInfoObject o;
  o.index = get16(r.data.data());
  o.data_type = get16(r.data.data() + 2);
  o.max_sub = r.data[4];
  o.object_code = r.data[5];
  o.name.assign(r.data.begin() + 6, r.data.end());
  return o;
}

std::optional<SdoInfoEntry> Master::sdo_info_entry(unsigned position, uint16_t index, uint8_t sub, std::string& error) {
  SlaveInfo* s = find(position);
  if (!s) {
    error = fmt("no slave at position %u", position);
    return std::nullopt;
  }
  std::vector<uint8_t> q = le(index, 2);
  q.push_back(sub);
  q.push_back(0x01);  // value info: access rights
  const SdoResult r = run_on_worker([=, this] { return do_info(*s, 5, q); });
  if (!r.ok || r.data.size() < 10) {
    error = r.ok ? "entry description too short" : r.error;
    return std::nullopt;
  }
  SdoInfoEntry e;
  e.index = get16(r.data.data());
  e.sub = r.data[2];
  e.data_type = get16(r.data.data() + 4);
  e.bit_length = get16(r.data.data() + 6);
  e.access = get16(r.data.data() + 8);
  e.name.assign(r.data.begin() + 10, r.data.end());
  return e;
}

SdoResult Master::run_on_worker(std::function<SdoResult()> job) {
  if (!worker_.joinable() || std::this_thread::get_id() == worker_id_) return job();
  std::promise<SdoResult> p;
  auto f = p.get_future();
  {
    std::lock_guard lock(jobs_mutex_);
    jobs_.push_back([&] { p.set_value(job()); });
  }
  jobs_cv_.notify_all();
  return f.get();
}

SdoResult Master::sdo_upload(unsigned position, uint16_t index, uint8_t sub, bool ca) {
  SlaveInfo* s = find(position);
  if (!s) return SdoResult{false, 0, {}, fmt("no slave at position %u", position)};
  return run_on_worker([=, this] { return do_upload(*s, index, sub, ca); });
}

SdoResult Master::sdo_download(unsigned position, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data,
                               bool ca) {
  SlaveInfo* s = find(position);
  if (!s) return SdoResult{false, 0, {}, fmt("no slave at position %u", position)};
  return run_on_worker([=, this] { return do_download(*s, index, sub, data, ca); });
}

int Master::rt_sdo_read(unsigned position, uint16_t index, uint8_t sub) noexcept {
  for (std::size_t i = 0; i < rt_.size(); ++i) {
    RtRequest& r = rt_[i];
    if (r.state.load(std::memory_order_acquire) != 0) continue;
    r.position = position;
    r.index = index;
    r.sub = sub;
    r.write = false;
    r.state.store(1, std::memory_order_release);
    return static_cast<int>(i);
  }
  return -1;
}

int Master::rt_sdo_write(unsigned position, uint16_t index, uint8_t sub, uint32_t value, uint8_t size) noexcept {
  for (std::size_t i = 0; i < rt_.size(); ++i) {
    RtRequest& r = rt_[i];
    if (r.state.load(std::memory_order_acquire) != 0) continue;
    r.position = position;
    r.index = index;
    r.sub = sub;
    r.write = true;
    r.value = value;
    r.size = size;
    r.state.store(1, std::memory_order_release);
    return static_cast<int>(i);
  }
  return -1;
}

bool Master::rt_sdo_poll(int handle, uint32_t& abort_code, uint32_t& value) noexcept {
  if (handle < 0 || static_cast<std::size_t>(handle) >= rt_.size()) return false;
  RtRequest& r = rt_[static_cast<std::size_t>(handle)];
  if (r.state.load(std::memory_order_acquire) != 2) return false;
  abort_code = r.abort_code;
  value = r.result;
  r.state.store(0, std::memory_order_release);
  return true;
}

}  // namespace cnc::ethercat
