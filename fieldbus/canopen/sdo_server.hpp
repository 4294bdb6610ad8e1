// SDO server of a CANopen device (CiA 301 §7.2.4): expedited, segmented and
// block transfers in both directions on one object dictionary, with every
// protocol error answered by the abort code the standard names. One
// transfer at a time, as the standard allows. Block uploads are paced by
// poll() so that a small transmit queue never overflows. No allocation
// after construction; realtime-safe.
#pragma once

#include <cstdint>
#include <vector>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/object_dictionary.hpp"

namespace cnc::canopen {

class SdoServer {
 public:
  // Requests arrive on `request_cob` (0x600 + id), answers go on
  // `response_cob` (0x580 + id).
  SdoServer(ObjectDictionary& od, can::Transport& transport, uint32_t request_cob, uint32_t response_cob);

  void set_cob_ids(uint32_t request_cob, uint32_t response_cob) noexcept;
  uint32_t request_cob() const noexcept { return request_cob_; }
  // A transfer idle for longer than this is aborted with 0x05040000.
  void set_timeout_ns(int64_t ns) noexcept { timeout_ns_ = ns; }
  // Largest block size offered to clients (1..127).
  void set_max_block_size(uint8_t n) noexcept { max_block_ = n < 1 ? 1 : (n > 127 ? 127 : n); }

  // A request frame (the caller checks the COB-ID). Realtime-safe.
  void on_frame(const can::Frame& f, int64_t now_ns) noexcept;
  // Sends paced block-upload segments and enforces the timeout.
  void poll(int64_t now_ns) noexcept;
  bool busy() const noexcept { return state_ != State::Idle; }
  // Abandons any transfer (NMT reset) without sending anything.
  void reset() noexcept { state_ = State::Idle; }

  uint64_t aborts_sent() const noexcept { return aborts_sent_; }
  uint32_t last_abort() const noexcept { return last_abort_; }

 private:
  enum class State : uint8_t {
    Idle,
    Download,
    Upload,
    BlockDownload,
    BlockDownloadEnd,
    BlockUploadStart,
    BlockUploadSend,
    BlockUploadAck,
    BlockUploadEnd,
  };

  void send(const uint8_t (&bytes)[8]) noexcept;
  void send_abort(ObjectAddress a, uint32_t code) noexcept;
  void respond(uint8_t cs, ObjectAddress a, uint32_t value = 0) noexcept;
  void initiate_download(const uint8_t* d) noexcept;
  void download_segment(const uint8_t* d) noexcept;
  void initiate_upload(const uint8_t* d) noexcept;
  void upload_segment(const uint8_t* d) noexcept;
  void initiate_block_download(const uint8_t* d) noexcept;
  void block_download_segment(const uint8_t* d) noexcept;
  void end_block_download(const uint8_t* d) noexcept;
  void initiate_block_upload(const uint8_t* d) noexcept;
  void block_upload_ack(const uint8_t* d) noexcept;
  void send_block_segments() noexcept;
  uint32_t finish_write(std::size_t n) noexcept;
  uint32_t check_writable(ObjectAddress a) const noexcept;

  ObjectDictionary& od_;
  can::Transport& transport_;
  uint32_t request_cob_;
  uint32_t response_cob_;
  int64_t timeout_ns_ = 1'000'000'000;
  uint8_t max_block_ = 127;

  State state_ = State::Idle;
  ObjectAddress addr_;
  std::vector<uint8_t> buffer_;
  std::size_t size_ = 0;       // total size (indicated or read)
  bool size_known_ = false;
  std::size_t pos_ = 0;        // bytes transferred (downloads: received; uploads: acknowledged)
  bool toggle_ = false;
  int64_t last_ns_ = 0;
  // block transfers
  bool crc_ = false;
  uint8_t block_size_ = 0;
  uint8_t seq_ = 0;            // download: last good sequence; upload: last sent
  bool last_seen_ = false;     // download: the segment with c = 1 arrived in order
  std::size_t send_pos_ = 0;   // upload: next byte to send

  uint64_t aborts_sent_ = 0;
  uint32_t last_abort_ = 0;
};

}  // namespace cnc::canopen
