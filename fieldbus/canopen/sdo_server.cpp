#include "fieldbus/canopen/sdo_server.hpp"

#include <algorithm>
#include <cstring>

#include "fieldbus/canopen/crc16.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {
namespace {
ObjectAddress address_of(const uint8_t* d) noexcept { return ObjectAddress{get_le<uint16_t>(d + 1), d[3]}; }
}  // namespace

SdoServer::SdoServer(ObjectDictionary& od, can::Transport& transport, uint32_t request_cob, uint32_t response_cob)
    : od_(od), transport_(transport), request_cob_(request_cob), response_cob_(response_cob) {
  buffer_.resize(od_.max_capacity() + 8);
}

void SdoServer::set_cob_ids(uint32_t request_cob, uint32_t response_cob) noexcept {
  request_cob_ = request_cob;
  response_cob_ = response_cob;
  state_ = State::Idle;
}

void SdoServer::send(const uint8_t (&bytes)[8]) noexcept { transport_.send(can::Frame::make(response_cob_, bytes, 8)); }

void SdoServer::send_abort(ObjectAddress a, uint32_t code) noexcept {
  uint8_t b[8] = {0x80};
  put_le<uint16_t>(b + 1, a.index);
  b[3] = a.sub;
  put_le<uint32_t>(b + 4, code);
  send(b);
  ++aborts_sent_;
  last_abort_ = code;
  state_ = State::Idle;
}

void SdoServer::respond(uint8_t cs, ObjectAddress a, uint32_t value) noexcept {
  uint8_t b[8] = {cs};
  put_le<uint16_t>(b + 1, a.index);
  b[3] = a.sub;
  put_le<uint32_t>(b + 4, value);
  send(b);
}

uint32_t SdoServer::check_writable(ObjectAddress a) const noexcept {
  const OdEntry* e = od_.find(a);
  if (!e) return od_.has_index(a.index) ? abort_code::kNoSubIndex : abort_code::kNoObject;
  if (!is_writable(e->access)) return abort_code::kReadOnly;
  return 0;
}

uint32_t SdoServer::finish_write(std::size_t n) noexcept {
  const OdEntry* e = od_.find(addr_);
  if (e && is_fixed_size(e->type) && !size_known_ && n > e->capacity) n = e->capacity;  // size not indicated
  return od_.write(addr_, buffer_.data(), n, true);
}

void SdoServer::on_frame(const can::Frame& f, int64_t now_ns) noexcept {
  if (f.is_remote() || f.is_error()) return;
  uint8_t d[8] = {};
  std::memcpy(d, f.data.data(), std::min<std::size_t>(f.len, 8));
  last_ns_ = now_ns;
  // During a block download every frame is a segment, except an abort
  // (0x80 would be sequence number 0, which is invalid).
  if (state_ == State::BlockDownload) {
    if (d[0] == 0x80) {
      state_ = State::Idle;
      return;
    }
    block_download_segment(d);
    return;
  }
  const uint8_t ccs = d[0] >> 5;
  switch (ccs) {
    case 1: initiate_download(d); return;
    case 2: initiate_upload(d); return;
    case 0:
      if (state_ == State::Download) download_segment(d);
      else send_abort(addr_, abort_code::kCommandSpecifier);
      return;
    case 3:
      if (state_ == State::Upload) upload_segment(d);
      else send_abort(addr_, abort_code::kCommandSpecifier);
      return;
    case 4:  // abort from the client: no answer
      state_ = State::Idle;
      return;
    case 5:
      switch (d[0] & 0x03) {
        case 0: initiate_block_upload(d); return;
        case 3:  // start upload
          if (state_ == State::BlockUploadStart && d[0] == 0xA3) {
            state_ = State::BlockUploadSend;
            seq_ = 0;
            send_block_segments();
          } else {
            send_abort(addr_, abort_code::kCommandSpecifier);
          }
          return;
        case 2:
          if (state_ == State::BlockUploadAck || state_ == State::BlockUploadSend) block_upload_ack(d);
          else send_abort(addr_, abort_code::kCommandSpecifier);
          return;
        case 1:  // end response from the client
          if (state_ == State::BlockUploadEnd) state_ = State::Idle;
          else send_abort(addr_, abort_code::kCommandSpecifier);
          return;
      }
      return;
    case 6:
      if ((d[0] & 0x01) == 0) initiate_block_download(d);
      else if (state_ == State::BlockDownloadEnd) end_block_download(d);
      else send_abort(addr_, abort_code::kCommandSpecifier);
      return;
    default:
      send_abort(state_ == State::Idle ? address_of(d) : addr_, abort_code::kCommandSpecifier);
      return;
  }
}

// --- expedited and segmented download ---

void SdoServer::initiate_download(const uint8_t* d) noexcept {
  addr_ = address_of(d);
  state_ = State::Idle;
  if (const uint32_t code = check_writable(addr_)) return send_abort(addr_, code);
  const bool expedited = d[0] & 0x02;
  const bool sized = d[0] & 0x01;
  if (expedited) {
    const std::size_t n = sized ? 4u - ((d[0] >> 2) & 0x03) : 4u;
    std::memcpy(buffer_.data(), d + 4, n);
    size_known_ = sized;
    if (const uint32_t code = finish_write(n)) return send_abort(addr_, code);
    respond(0x60, addr_);
    return;
  }
  size_known_ = sized;
  size_ = sized ? get_le<uint32_t>(d + 4) : 0;
  if (sized) {
    const OdEntry* e = od_.find(addr_);
    if (size_ > e->capacity) return send_abort(addr_, abort_code::kLengthTooHigh);
    if (is_fixed_size(e->type) && size_ < e->capacity) return send_abort(addr_, abort_code::kLengthTooLow);
  }
  pos_ = 0;
  toggle_ = false;
  state_ = State::Download;
  respond(0x60, addr_);
}

void SdoServer::download_segment(const uint8_t* d) noexcept {
  const bool t = d[0] & 0x10;
  if (t != toggle_) return send_abort(addr_, abort_code::kToggleBit);
  const std::size_t n = 7u - ((d[0] >> 1) & 0x07);
  if (pos_ + n > buffer_.size() - 1 || pos_ + n > od_.find(addr_)->capacity) {
    return send_abort(addr_, abort_code::kLengthTooHigh);
  }
  std::memcpy(buffer_.data() + pos_, d + 1, n);
  pos_ += n;
  if (d[0] & 0x01) {
    state_ = State::Idle;
    if (size_known_ && pos_ != size_) return send_abort(addr_, abort_code::kLengthMismatch);
    if (const uint32_t code = finish_write(pos_)) return send_abort(addr_, code);
  }
  uint8_t b[8] = {static_cast<uint8_t>(0x20 | (t ? 0x10 : 0))};
  send(b);
  toggle_ = !toggle_;
}

// --- expedited and segmented upload ---

void SdoServer::initiate_upload(const uint8_t* d) noexcept {
  addr_ = address_of(d);
  state_ = State::Idle;
  std::size_t n = 0;
  if (const uint32_t code = od_.read(addr_, buffer_.data(), buffer_.size(), n, true)) return send_abort(addr_, code);
  if (n <= 4 && n > 0) {
    uint8_t b[8] = {static_cast<uint8_t>(0x43 | ((4 - n) << 2))};
    put_le<uint16_t>(b + 1, addr_.index);
    b[3] = addr_.sub;
    std::memcpy(b + 4, buffer_.data(), n);
    send(b);
    return;
  }
  size_ = n;
  pos_ = 0;
  toggle_ = false;
  state_ = State::Upload;
  respond(0x41, addr_, static_cast<uint32_t>(n));
}

void SdoServer::upload_segment(const uint8_t* d) noexcept {
  const bool t = d[0] & 0x10;
  if (t != toggle_) return send_abort(addr_, abort_code::kToggleBit);
  const std::size_t n = std::min<std::size_t>(7, size_ - pos_);
  const bool last = pos_ + n >= size_;
  uint8_t b[8] = {static_cast<uint8_t>((t ? 0x10 : 0) | ((7 - n) << 1) | (last ? 1 : 0))};
  std::memcpy(b + 1, buffer_.data() + pos_, n);
  pos_ += n;
  send(b);
  toggle_ = !toggle_;
  if (last) state_ = State::Idle;
}

// --- block download ---

void SdoServer::initiate_block_download(const uint8_t* d) noexcept {
  addr_ = address_of(d);
  state_ = State::Idle;
  if (d[0] & 0x18) return send_abort(addr_, abort_code::kCommandSpecifier);  // reserved bits
  if (const uint32_t code = check_writable(addr_)) return send_abort(addr_, code);
  crc_ = d[0] & 0x04;
  size_known_ = d[0] & 0x02;
  size_ = size_known_ ? get_le<uint32_t>(d + 4) : 0;
  if (size_known_ && size_ > od_.find(addr_)->capacity) return send_abort(addr_, abort_code::kLengthTooHigh);
  pos_ = 0;
  seq_ = 0;
  last_seen_ = false;
  block_size_ = max_block_;
  state_ = State::BlockDownload;
  uint8_t b[8] = {static_cast<uint8_t>(0xA0 | 0x04)};  // the server checks CRCs
  put_le<uint16_t>(b + 1, addr_.index);
  b[3] = addr_.sub;
  b[4] = block_size_;
  send(b);
}

void SdoServer::block_download_segment(const uint8_t* d) noexcept {
  const uint8_t seq = d[0] & 0x7F;
  const bool last = d[0] & 0x80;
  if (seq == 0 || seq > block_size_) return send_abort(addr_, abort_code::kSequenceNumber);
  if (seq == seq_ + 1 && !last_seen_) {
    if (pos_ + 7 > buffer_.size()) return send_abort(addr_, abort_code::kLengthTooHigh);
    std::memcpy(buffer_.data() + pos_, d + 1, 7);
    pos_ += 7;
    seq_ = seq;
    if (last) last_seen_ = true;
  }
  // Segments after a lost one are ignored; the acknowledgement at the end of
  // the sub-block names the last good one and the client repeats from there.
  if (seq == block_size_ || last) {
    uint8_t b[8] = {0xA2, seq_, block_size_};
    send(b);
    seq_ = 0;
    if (last_seen_) state_ = State::BlockDownloadEnd;
  }
}

void SdoServer::end_block_download(const uint8_t* d) noexcept {
  if ((d[0] & 0xE3) != 0xC1) return send_abort(addr_, abort_code::kCommandSpecifier);
  const std::size_t unused = (d[0] >> 2) & 0x07;
  state_ = State::Idle;
  if (unused > pos_) return send_abort(addr_, abort_code::kLengthMismatch);
  const std::size_t n = pos_ - unused;
  if (size_known_ && n != size_) return send_abort(addr_, abort_code::kLengthMismatch);
  if (crc_ && crc16_ccitt(0, buffer_.data(), n) != get_le<uint16_t>(d + 1)) return send_abort(addr_, abort_code::kCrc);
  if (const uint32_t code = finish_write(n)) return send_abort(addr_, code);
  uint8_t b[8] = {0xA1};
  send(b);
}

// --- block upload ---

void SdoServer::initiate_block_upload(const uint8_t* d) noexcept {
  addr_ = address_of(d);
  state_ = State::Idle;
  if (d[0] & 0x18) return send_abort(addr_, abort_code::kCommandSpecifier);
  const uint8_t blksize = d[4];
  const uint8_t pst = d[5];
  if (blksize < 1 || blksize > 127) return send_abort(addr_, abort_code::kBlockSize);
  std::size_t n = 0;
  if (const uint32_t code = od_.read(addr_, buffer_.data(), buffer_.size(), n, true)) return send_abort(addr_, code);
  if (pst != 0 && n <= pst) {
    // Protocol switch: answer as a normal upload.
    uint8_t req[8] = {0x40};
    put_le<uint16_t>(req + 1, addr_.index);
    req[3] = addr_.sub;
    initiate_upload(req);
    return;
  }
  crc_ = d[0] & 0x04;
  size_ = n;
  pos_ = 0;
  send_pos_ = 0;
  block_size_ = blksize;
  state_ = State::BlockUploadStart;
  uint8_t b[8] = {static_cast<uint8_t>(0xC0 | 0x04 | 0x02)};  // CRC supported, size indicated
  put_le<uint16_t>(b + 1, addr_.index);
  b[3] = addr_.sub;
  put_le<uint32_t>(b + 4, static_cast<uint32_t>(n));
  send(b);
}

void SdoServer::send_block_segments() noexcept {
  while (state_ == State::BlockUploadSend && seq_ < block_size_) {
    const std::size_t n = std::min<std::size_t>(7, size_ - send_pos_);
    const bool last = send_pos_ + n >= size_;
    uint8_t b[8] = {static_cast<uint8_t>((last ? 0x80 : 0) | (seq_ + 1))};
    std::memcpy(b + 1, buffer_.data() + send_pos_, n);
    if (transport_.send(can::Frame::make(response_cob_, b, 8)) != can::SendStatus::Ok) return;  // resume in poll()
    ++seq_;
    send_pos_ += n;
    if (last) break;
  }
  state_ = State::BlockUploadAck;
}

void SdoServer::block_upload_ack(const uint8_t* d) noexcept {
  if (d[0] != 0xA2) return send_abort(addr_, abort_code::kCommandSpecifier);
  const uint8_t ackseq = d[1];
  const uint8_t blksize = d[2];
  if (ackseq > seq_) return send_abort(addr_, abort_code::kSequenceNumber);
  if (blksize < 1 || blksize > 127) return send_abort(addr_, abort_code::kBlockSize);
  pos_ = std::min(size_, pos_ + 7u * ackseq);
  if (pos_ >= size_ && send_pos_ >= size_ && ackseq == seq_) {
    const std::size_t in_last = size_ == 0 ? 0 : (size_ - 1) % 7 + 1;
    uint8_t b[8] = {static_cast<uint8_t>(0xC1 | ((7 - in_last) << 2))};
    put_le<uint16_t>(b + 1, crc_ ? crc16_ccitt(0, buffer_.data(), size_) : 0);
    send(b);
    state_ = State::BlockUploadEnd;
    return;
  }
  // Next sub-block (or repeat what was not acknowledged).
  send_pos_ = pos_;
  block_size_ = blksize;
  seq_ = 0;
  state_ = State::BlockUploadSend;
  send_block_segments();
}

void SdoServer::poll(int64_t now_ns) noexcept {
  if (state_ == State::Idle) return;
  if (state_ == State::BlockUploadSend) send_block_segments();
  if (now_ns - last_ns_ > timeout_ns_) send_abort(addr_, abort_code::kTimeout);
}

}  // namespace cnc::canopen
