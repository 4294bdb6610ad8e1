// SDO client of the master (CiA 301 §7.2.4): one channel to one node's SDO
// server, expedited / segmented / block transfers in both directions, a
// timeout per transfer (abort 0x05040000 sent), toggle, sequence and CRC
// checks with the standard abort codes, and a queue so callers may post
// several transfers. Non-realtime (allocates the data buffers); driven by
// the master's acyclic thread through on_frame() and poll().
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/types.hpp"

namespace cnc::canopen {

enum class SdoMode : uint8_t { Auto, Expedited, Segmented, Block };
const char* to_string(SdoMode m) noexcept;

struct SdoResult {
  ObjectAddress addr;
  bool upload = false;
  uint32_t abort_code = 0;     // 0 = success
  bool aborted_by_client = false;  // we aborted (timeout, protocol error), else the server did
  std::vector<uint8_t> data;   // uploads
  // Set when the master aborted because the node's reply named another
  // object (multiplexer mismatch): the object it answered for.
  std::optional<ObjectAddress> answered_for;
  bool ok() const noexcept { return abort_code == 0; }
  // "0x06020000 object does not exist in the object dictionary", or with
  // answered_for "0x08000000 general error: the node answered for 0x1017:00"
  std::string abort_text() const;
  // "SDO upload 0x1018:01 aborted by the server: 0x06020000 object does not exist in the object dictionary"
  std::string message() const;

  template <class T>
  T as() const noexcept {
    uint8_t buf[sizeof(T)] = {};
    for (std::size_t i = 0; i < sizeof(T) && i < data.size(); ++i) buf[i] = data[i];
    return get_le<T>(buf);
  }
};

// A bus-wide budget of SDO request frames per cycle, shared by a master's
// SDO clients, so that SDO traffic stays inside the share the bus-load
// plan gives it (SDO_FRAMES_PER_CYCLE: a request and its response, so
// half of them are the master's). Frames beyond the budget wait for a
// later cycle in the client's queue. Acyclic thread only.
class SdoPacer {
 public:
  // requests_per_cycle 0: unpaced.
  SdoPacer(int64_t cycle_ns, uint32_t requests_per_cycle) noexcept
      : cycle_ns_(cycle_ns > 0 ? cycle_ns : 1'000'000), per_cycle_(requests_per_cycle) {}
  // Inactive (no cyclic exchange yet), every request may go.
  void set_active(bool on) noexcept { active_ = on; }
  bool available(int64_t now_ns) noexcept {
    if (per_cycle_ == 0 || !active_) return true;
    const int64_t w = now_ns / cycle_ns_;
    if (w != window_) {
      window_ = w;
      used_ = 0;
    }
    return used_ < per_cycle_;
  }
  void consume() noexcept { ++used_; }
  uint32_t requests_per_cycle() const noexcept { return per_cycle_; }
  uint64_t deferred() const noexcept { return deferred_; }
  void count_deferred() noexcept { ++deferred_; }

 private:
  int64_t cycle_ns_;
  uint32_t per_cycle_;
  int64_t window_ = -1;
  uint32_t used_ = 0;
  uint64_t deferred_ = 0;
  bool active_ = true;
};

struct SdoClientOptions {
  int64_t timeout_ns = 500'000'000;
  std::size_t block_threshold = 64;  // Auto downloads longer than this use block transfer
  uint8_t block_size = 127;          // offered for block uploads
  uint8_t protocol_switch_threshold = 0;  // block upload: server may answer normally at or below this size
  bool crc = true;                   // block transfers with CRC
  SdoPacer* pacer = nullptr;         // the bus's SDO budget (none: unpaced)
};

class SdoClient {
 public:
  using Done = std::function<void(const SdoResult&)>;

  SdoClient(can::Transport& transport, uint8_t node_id, SdoClientOptions options = {});
  SdoClient(const SdoClient&) = delete;
  SdoClient& operator=(const SdoClient&) = delete;

  uint8_t node_id() const noexcept { return node_id_; }
  uint32_t response_cob() const noexcept { return response_cob_; }
  SdoClientOptions& options() noexcept { return options_; }

  // Queue a transfer; `done` runs (in the caller of on_frame/poll) when it
  // ends. Mode Auto: downloads expedited up to 4 bytes, segmented up to the
  // block threshold, block above; uploads start as a normal upload.
  void upload(ObjectAddress a, Done done, SdoMode mode = SdoMode::Auto);
  void download(ObjectAddress a, std::vector<uint8_t> data, Done done, SdoMode mode = SdoMode::Auto);

  // A frame from the server (COB-ID response_cob()). Returns false for others.
  bool on_frame(const can::Frame& f, int64_t now_ns);
  // Starts queued transfers, paces block downloads, enforces the timeout.
  void poll(int64_t now_ns);
  bool idle() const noexcept { return state_ == State::Idle && queue_.empty(); }
  std::size_t queued() const noexcept { return queue_.size() + (state_ == State::Idle ? 0 : 1); }
  // Ends every transfer with `code` (sending an abort for the active one).
  void cancel_all(uint32_t code, int64_t now_ns);

 private:
  enum class State : uint8_t {
    Idle,
    InitDownload,
    DownloadSegment,
    InitUpload,
    UploadSegment,
    InitBlockDownload,
    BlockDownloadSend,
    BlockDownloadAck,
    BlockDownloadEnd,
    InitBlockUpload,
    BlockUploadReceive,
    BlockUploadEnd,
  };
  struct Request {
    ObjectAddress addr;
    bool upload = false;
    SdoMode mode = SdoMode::Auto;
    std::vector<uint8_t> data;
    Done done;
  };

  void start(int64_t now_ns);
  void send(const uint8_t (&b)[8]);
  // Sends queued request frames as far as the transport and the pacer allow.
  void flush();
  void fail(uint32_t code, bool by_client, std::optional<ObjectAddress> answered_for = std::nullopt);
  void finish();
  void send_download_segment();
  void send_block_segments();
  void on_upload_response(const uint8_t* d);

  can::Transport& transport_;
  uint8_t node_id_;
  uint32_t request_cob_, response_cob_;
  SdoClientOptions options_;
  std::deque<Request> queue_;
  std::deque<can::Frame> out_;  // request frames of the active transfer not sent yet
  Request active_;
  State state_ = State::Idle;
  int64_t deadline_ns_ = 0;
  int64_t now_ns_ = 0;
  bool toggle_ = false;
  std::size_t pos_ = 0;       // bytes sent (downloads) or confirmed
  std::size_t size_ = 0;      // indicated size for uploads
  bool size_known_ = false;
  bool crc_ = false;
  uint8_t block_size_ = 0;
  uint8_t seq_ = 0;
  std::size_t send_pos_ = 0;
  std::vector<uint8_t> rx_;
};

}  // namespace cnc::canopen
