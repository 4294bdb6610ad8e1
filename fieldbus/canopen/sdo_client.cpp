#include "fieldbus/canopen/sdo_client.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "fieldbus/canopen/crc16.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {

const char* to_string(SdoMode m) noexcept {
  switch (m) {
    case SdoMode::Auto: return "auto";
    case SdoMode::Expedited: return "expedited";
    case SdoMode::Segmented: return "segmented";
    case SdoMode::Block: return "block";
  }
  return "?";
}

std::string SdoResult::abort_text() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "0x%08X %s", abort_code, sdo_abort_text(abort_code));
  std::string out = buf;
  if (answered_for) {
    char a[16];
    out += std::string(": the node answered for ") + format(*answered_for, a, sizeof a);
  }
  return out;
}

std::string SdoResult::message() const {
  char a[16];
  char buf[320];
  if (ok()) {
    std::snprintf(buf, sizeof buf, "SDO %s %s done", upload ? "upload" : "download", format(addr, a, sizeof a));
  } else {
    std::snprintf(buf, sizeof buf, "SDO %s %s aborted by the %s: %s", upload ? "upload" : "download",
                  format(addr, a, sizeof a), aborted_by_client ? "master" : "device", abort_text().c_str());
  }
  return buf;
}

SdoClient::SdoClient(can::Transport& transport, uint8_t node_id, SdoClientOptions options)
    : transport_(transport),
      node_id_(node_id),
      request_cob_(cob::sdo_request(node_id)),
      response_cob_(cob::sdo_response(node_id)),
      options_(options) {}

void SdoClient::upload(ObjectAddress a, Done done, SdoMode mode) {
  queue_.push_back(Request{a, true, mode, {}, std::move(done)});
}

void SdoClient::download(ObjectAddress a, std::vector<uint8_t> data, Done done, SdoMode mode) {
  queue_.push_back(Request{a, false, mode, std::move(data), std::move(done)});
}

void SdoClient::send(const uint8_t (&b)[8]) {
  out_.push_back(can::Frame::make(request_cob_, b, 8));
  flush();
  if (!out_.empty() && options_.pacer) options_.pacer->count_deferred();
}

void SdoClient::flush() {
  while (!out_.empty()) {
    if (options_.pacer && !options_.pacer->available(now_ns_)) return;  // a later cycle (poll)
    if (transport_.send(out_.front()) != can::SendStatus::Ok) return;   // queue full or down: poll retries
    if (options_.pacer) options_.pacer->consume();
    out_.pop_front();
  }
}

void SdoClient::fail(uint32_t code, bool by_client, std::optional<ObjectAddress> answered_for) {
  out_.clear();  // what the server never saw of this transfer
  if (by_client) {
    uint8_t b[8] = {0x80};
    put_le<uint16_t>(b + 1, active_.addr.index);
    b[3] = active_.addr.sub;
    put_le<uint32_t>(b + 4, code);
    send(b);
  }
  SdoResult r;
  r.addr = active_.addr;
  r.upload = active_.upload;
  r.abort_code = code;
  r.aborted_by_client = by_client;
  r.answered_for = answered_for;
  state_ = State::Idle;
  Done done = std::move(active_.done);
  if (done) done(r);
}

void SdoClient::finish() {
  SdoResult r;
  r.addr = active_.addr;
  r.upload = active_.upload;
  if (active_.upload) r.data = std::move(rx_);
  rx_.clear();
  state_ = State::Idle;
  Done done = std::move(active_.done);
  if (done) done(r);
}

void SdoClient::cancel_all(uint32_t code, int64_t now_ns) {
  now_ns_ = now_ns;
  if (state_ != State::Idle) fail(code, true);
  while (!queue_.empty()) {
    active_ = std::move(queue_.front());
    queue_.pop_front();
    fail(code, false);
  }
}

void SdoClient::start(int64_t now_ns) {
  if (state_ != State::Idle || queue_.empty()) return;
  active_ = std::move(queue_.front());
  queue_.pop_front();
  deadline_ns_ = now_ns + options_.timeout_ns;
  toggle_ = false;
  pos_ = send_pos_ = 0;
  rx_.clear();
  uint8_t b[8] = {};
  put_le<uint16_t>(b + 1, active_.addr.index);
  b[3] = active_.addr.sub;
  if (active_.upload) {
    if (active_.mode == SdoMode::Block) {
      b[0] = static_cast<uint8_t>(0xA0 | (options_.crc ? 0x04 : 0));
      b[4] = options_.block_size;
      b[5] = options_.protocol_switch_threshold;
      block_size_ = options_.block_size;
      seq_ = 0;
      state_ = State::InitBlockUpload;
    } else {
      b[0] = 0x40;
      state_ = State::InitUpload;
    }
    send(b);
    return;
  }
  const std::size_t n = active_.data.size();
  SdoMode mode = active_.mode;
  if (mode == SdoMode::Auto) {
    mode = (n >= 1 && n <= 4) ? SdoMode::Expedited : (n <= options_.block_threshold ? SdoMode::Segmented : SdoMode::Block);
  }
  if (mode == SdoMode::Expedited && (n == 0 || n > 4)) mode = SdoMode::Segmented;
  switch (mode) {
    case SdoMode::Expedited:
      b[0] = static_cast<uint8_t>(0x23 | ((4 - n) << 2));
      std::memcpy(b + 4, active_.data.data(), n);
      state_ = State::InitDownload;
      pos_ = n;
      break;
    case SdoMode::Block:
      b[0] = static_cast<uint8_t>(0xC0 | (options_.crc ? 0x04 : 0) | 0x02);
      put_le<uint32_t>(b + 4, static_cast<uint32_t>(n));
      state_ = State::InitBlockDownload;
      break;
    default:
      b[0] = 0x21;
      put_le<uint32_t>(b + 4, static_cast<uint32_t>(n));
      state_ = State::InitDownload;
      break;
  }
  send(b);
}

void SdoClient::send_download_segment() {
  const std::size_t n = std::min<std::size_t>(7, active_.data.size() - pos_);
  const bool last = pos_ + n >= active_.data.size();
  uint8_t b[8] = {static_cast<uint8_t>((toggle_ ? 0x10 : 0) | ((7 - n) << 1) | (last ? 1 : 0))};
  std::memcpy(b + 1, active_.data.data() + pos_, n);
  send_pos_ = pos_ + n;
  send(b);
  state_ = State::DownloadSegment;
}

void SdoClient::send_block_segments() {
  // The whole block is queued; flush() sends it at the transport's and the
  // pacer's pace.
  const std::size_t size = active_.data.size();
  while (seq_ < block_size_) {
    const std::size_t n = std::min<std::size_t>(7, size - send_pos_);
    const bool last = send_pos_ + n >= size;
    uint8_t b[8] = {static_cast<uint8_t>((last ? 0x80 : 0) | (seq_ + 1))};
    std::memcpy(b + 1, active_.data.data() + send_pos_, n);
    send(b);
    ++seq_;
    send_pos_ += n;
    if (last) break;
  }
  state_ = State::BlockDownloadAck;
}

void SdoClient::on_upload_response(const uint8_t* d) {
  const bool expedited = d[0] & 0x02;
  const bool sized = d[0] & 0x01;
  if (expedited) {
    const std::size_t n = sized ? 4u - ((d[0] >> 2) & 0x03) : 4u;
    rx_.assign(d + 4, d + 4 + n);
    finish();
    return;
  }
  size_known_ = sized;
  size_ = sized ? get_le<uint32_t>(d + 4) : 0;
  rx_.clear();
  toggle_ = false;
  uint8_t b[8] = {0x60};
  send(b);
  state_ = State::UploadSegment;
}

bool SdoClient::on_frame(const can::Frame& f, int64_t now_ns) {
  if (f.id != response_cob_ || f.is_remote() || f.is_error() || f.is_extended()) return false;
  now_ns_ = now_ns;
  if (state_ == State::Idle) return true;  // late answer to an aborted transfer
  uint8_t d[8] = {};
  std::memcpy(d, f.data.data(), std::min<std::size_t>(f.len, 8));
  deadline_ns_ = now_ns + options_.timeout_ns;

  // During a block upload every frame is a segment (0x80 would be seqno 0).
  if (state_ == State::BlockUploadReceive) {
    if (d[0] == 0x80) {
      fail(get_le<uint32_t>(d + 4), false);
      return true;
    }
    const uint8_t seq = d[0] & 0x7F;
    const bool last = d[0] & 0x80;
    if (seq == 0 || seq > block_size_) {
      fail(abort_code::kSequenceNumber, true);
      return true;
    }
    if (seq == seq_ + 1) {
      rx_.insert(rx_.end(), d + 1, d + 8);
      seq_ = seq;
      if (last) state_ = State::BlockUploadEnd;
    }
    if (seq == block_size_ || last) {
      uint8_t b[8] = {0xA2, seq_, options_.block_size};
      send(b);
      seq_ = 0;
    }
    return true;
  }

  if (d[0] == 0x80) {
    fail(get_le<uint32_t>(d + 4), false);
    return true;
  }
  const uint8_t scs = d[0] >> 5;
  const ObjectAddress addr{get_le<uint16_t>(d + 1), d[3]};
  auto multiplexer_ok = [&] {
    if (addr == active_.addr) return true;
    fail(abort_code::kGeneral, true, addr);
    return false;
  };
  switch (state_) {
    case State::InitDownload:
      if (scs != 3) return fail(abort_code::kCommandSpecifier, true), true;
      if (!multiplexer_ok()) return true;
      if (pos_ >= active_.data.size() && !active_.data.empty()) finish();  // expedited
      else send_download_segment();
      return true;
    case State::DownloadSegment: {
      if (scs != 1) return fail(abort_code::kCommandSpecifier, true), true;
      if (((d[0] & 0x10) != 0) != toggle_) return fail(abort_code::kToggleBit, true), true;
      pos_ = send_pos_;
      toggle_ = !toggle_;
      if (pos_ >= active_.data.size()) finish();
      else send_download_segment();
      return true;
    }
    case State::InitUpload:
      if (scs != 2) return fail(abort_code::kCommandSpecifier, true), true;
      if (!multiplexer_ok()) return true;
      on_upload_response(d);
      return true;
    case State::UploadSegment: {
      if (scs != 0) return fail(abort_code::kCommandSpecifier, true), true;
      if (((d[0] & 0x10) != 0) != toggle_) return fail(abort_code::kToggleBit, true), true;
      const std::size_t n = 7u - ((d[0] >> 1) & 0x07);
      rx_.insert(rx_.end(), d + 1, d + 1 + n);
      if (d[0] & 0x01) {
        if (size_known_ && rx_.size() != size_) return fail(abort_code::kLengthMismatch, true), true;
        finish();
        return true;
      }
      if (size_known_ && rx_.size() >= size_) return fail(abort_code::kLengthMismatch, true), true;
      toggle_ = !toggle_;
      uint8_t b[8] = {static_cast<uint8_t>(0x60 | (toggle_ ? 0x10 : 0))};
      send(b);
      return true;
    }
    case State::InitBlockDownload:
      if (scs != 5 || (d[0] & 0x03) != 0) return fail(abort_code::kCommandSpecifier, true), true;
      if (!multiplexer_ok()) return true;
      crc_ = options_.crc && (d[0] & 0x04);
      block_size_ = d[4];
      if (block_size_ < 1 || block_size_ > 127) return fail(abort_code::kBlockSize, true), true;
      seq_ = 0;
      send_pos_ = pos_ = 0;
      state_ = State::BlockDownloadSend;
      send_block_segments();
      return true;
    case State::BlockDownloadSend:
    case State::BlockDownloadAck: {
      if (d[0] != 0xA2) return fail(abort_code::kCommandSpecifier, true), true;
      const uint8_t ackseq = d[1];
      if (ackseq > seq_) return fail(abort_code::kSequenceNumber, true), true;
      if (d[2] < 1 || d[2] > 127) return fail(abort_code::kBlockSize, true), true;
      const std::size_t size = active_.data.size();
      pos_ = std::min(size, pos_ + 7u * ackseq);
      if (pos_ >= size && ackseq == seq_ && send_pos_ >= size) {
        const std::size_t in_last = size == 0 ? 0 : (size - 1) % 7 + 1;
        uint8_t b[8] = {static_cast<uint8_t>(0xC1 | ((7 - in_last) << 2))};
        put_le<uint16_t>(b + 1, crc_ ? crc16_ccitt(0, active_.data.data(), size) : 0);
        send(b);
        state_ = State::BlockDownloadEnd;
        return true;
      }
      block_size_ = d[2];
      out_.clear();  // segments past the acknowledged one are sent again
      send_pos_ = pos_;
      seq_ = 0;
      state_ = State::BlockDownloadSend;
      send_block_segments();
      return true;
    }
    case State::BlockDownloadEnd:
      if (d[0] != 0xA1) return fail(abort_code::kCommandSpecifier, true), true;
      finish();
      return true;
    case State::InitBlockUpload:
      if (scs == 2) {  // the server switched to a normal upload
        if (!multiplexer_ok()) return true;
        on_upload_response(d);
        return true;
      }
      if (scs != 6 || (d[0] & 0x01) != 0) return fail(abort_code::kCommandSpecifier, true), true;
      if (!multiplexer_ok()) return true;
      crc_ = options_.crc && (d[0] & 0x04);
      size_known_ = d[0] & 0x02;
      size_ = size_known_ ? get_le<uint32_t>(d + 4) : 0;
      rx_.clear();
      seq_ = 0;
      block_size_ = options_.block_size;
      state_ = State::BlockUploadReceive;
      {
        uint8_t b[8] = {0xA3};
        send(b);
      }
      return true;
    case State::BlockUploadEnd: {
      if ((d[0] & 0xE3) != 0xC1) return fail(abort_code::kCommandSpecifier, true), true;
      const std::size_t unused = (d[0] >> 2) & 0x07;
      if (unused > rx_.size()) return fail(abort_code::kLengthMismatch, true), true;
      rx_.resize(rx_.size() - unused);
      if (size_known_ && rx_.size() != size_) return fail(abort_code::kLengthMismatch, true), true;
      if (crc_ && crc16_ccitt(0, rx_.data(), rx_.size()) != get_le<uint16_t>(d + 1)) {
        return fail(abort_code::kCrc, true), true;
      }
      uint8_t b[8] = {0xA1};
      send(b);
      finish();
      return true;
    }
    default:
      return true;
  }
}

void SdoClient::poll(int64_t now_ns) {
  now_ns_ = now_ns;
  flush();
  if (state_ == State::BlockDownloadSend) send_block_segments();
  if (state_ != State::Idle && now_ns >= deadline_ns_) fail(abort_code::kTimeout, true);
  if (state_ == State::Idle) start(now_ns);
}

}  // namespace cnc::canopen
