// The drive-parameter restore: the backup files of `cnc-commission backup`
// (commission/backup.hpp, one DCF-like file per drive, CANopen or
// EtherCAT) written back into the drives. For every drive, first (nothing
// written yet): its identity 0x1018:1-3 (vendor, product, revision) must be
// the backup's, else the restore refuses naming the drive; every
// parameter of the backup is read from the drive, and the ones that differ
// are the changes. Only when every drive passed this are the changes
// downloaded (SDO, or CoE SDO over the EtherCAT master; a CANopen node with
// changes is first sent NMT Enter Pre-Operational and left there; before
// any of it the CAN bus is listened to for another master; the node must
// then report PRE-OPERATIONAL by heartbeat or node guarding, else nothing is
// written to it, and again after the writes), each read back and compared; a CANopen or CoE drive with
// "store parameters" (0x1010:1) is then asked to store them ("save"). A
// write refused half-way (any abort but read-only, or no answer) stops the
// restore there: that drive is not stored, the state it is left in (NMT
// state, every object written so far) is read from it and said, and no
// other drive is written after it. Restored are the parameters of
// 0x2000-0x9FFF (manufacturer and profile objects) that are not read-only
// (AccessType ro/const in the file), and the PDO configuration: CANopen's
// communication parameters 0x1400-0x15FF / 0x1800-0x19FF and mappings
// 0x1600-0x17FF / 0x1A00-0x1BFF, EtherCAT's mappings and sync-manager
// assignments 0x1C12/0x1C13, written in the order CiA 301 and ETG.1000.6
// require (restore_pdos below). The other objects below 0x2000
// (identity, names, heartbeat) are only kept in the backup for the
// record. A drive that refuses a write as read-only (SDO abort 0x06010002)
// keeps its value and says so (and the restore goes on). Bad input (a missing file, a line that does
// not parse, a drive that does not answer or is another drive) is a
// problem naming file and line or drive, and then nothing is written.
// Non-realtime.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/types.hpp"

namespace cnc::ethercat {
class Master;
}

namespace cnc::commission {

// One [index] / [indexsubN] section of a backup file.
struct BackupEntry {
  canopen::ObjectAddress addr;
  canopen::DataType type = canopen::DataType::Unsigned32;
  std::string name;
  std::string access;        // "" not known
  std::string value;         // ParameterValue as written
  std::vector<uint8_t> data; // its bytes
  int line = 0;              // of its section header
};

// One drive's backup file as read.
struct BackupFile {
  std::filesystem::path path;
  int node = 0;              // CANopen node-ID (NodeID=)
  unsigned slave = 0;        // EtherCAT position (EtherCATSlave=)
  char axis = 0;             // from NodeName=x-axis (0: none)
  std::vector<BackupEntry> entries;
  const BackupEntry* find(uint16_t index, uint8_t sub) const noexcept;
  // "node 3 (axis Z, node-03-z.dcf)", "EtherCAT slave 1 (axis X, slave-01-x.dcf)"
  std::string label() const;
};

// Reads one backup file; throws std::runtime_error "FILE:LINE: what" for a
// line that does not parse, a value that is not of its DataType, a
// section without ParameterValue, a file without NodeID/EtherCATSlave.
BackupFile load_backup_file(const std::filesystem::path& file);
// Every *.dcf of `dir` (sorted), each as load_backup_file; throws naming
// the folder when it has none.
std::vector<BackupFile> load_backup_dir(const std::filesystem::path& dir);

// Whether a restore writes this entry back as a parameter (0x2000-0x9FFF,
// not ro/const).
bool restorable(const BackupEntry& e) noexcept;
// Whether it is part of the PDO configuration a restore writes back in
// order (not ro/const): 0x1400-0x1BFF, 0x1C12, 0x1C13.
bool pdo_entry(const BackupEntry& e) noexcept;

// One drive as the restore reaches it.
class DriveChannel {
 public:
  struct Result {
    bool ok = false;
    bool silent = false;       // no answer at all (time-out, no such slave)
    uint32_t abort_code = 0;   // the drive's SDO abort
    std::vector<uint8_t> data;
    std::string error;         // "0x06010002 attempt to write a read only object", "no answer within 500 ms"
  };
  virtual ~DriveChannel() = default;
  virtual Result upload(canopen::ObjectAddress a) = 0;
  virtual Result download(canopen::ObjectAddress a, const std::vector<uint8_t>& data) = 0;
  // Before the first write: brings the drive into the state its
  // configuration is written in, and confirms it. CANopen: NMT Enter
  // Pre-Operational (CiA 301: PDO mappings change there; many drives refuse
  // them in Operational), confirmed by the node's heartbeat (0x700+id, when
  // its 0x1017 is not 0) or else its answer to node guarding (RTR on
  // 0x700+id); a node that does not report PRE-OPERATIONAL within the
  // channel's NMT time-out is refused (not ok, `error` says what it
  // reported, or that it reported nothing), and nothing is written to it.
  // The node stays there. EtherCAT: nothing (the master holds the slaves in
  // PREOP). `done` says what was done and seen ("" nothing).
  virtual Result prepare_for_writes(std::string& done) {
    done.clear();
    Result r;
    r.ok = true;
    return r;
  }
  // After the writes (all of them, or up to a refused one): the drive's
  // communication state as the drive reports it now ("" not known by this
  // channel). CANopen: "PRE-OPERATIONAL (heartbeat 0x701)", or not ok
  // naming what it reported instead.
  virtual Result report_state(std::string& state) {
    state.clear();
    Result r;
    r.ok = true;
    return r;
  }
};
// A CANopen node over `bus` (SDO client; `timeout_ns` per transfer;
// `nmt_timeout_ns`: how long an NMT state change may take to be reported,
// at least three heartbeat periods of the node).
std::unique_ptr<DriveChannel> canopen_channel(can::Transport& bus, int node, int64_t timeout_ns,
                                              int64_t nmt_timeout_ns = 500'000'000);
// An EtherCAT slave over `master` (CoE SDO; the master in PREOP).
std::unique_ptr<DriveChannel> ethercat_channel(ethercat::Master& master, unsigned position);

// One parameter to write: the backup's value and the drive's.
struct RestoreChange {
  BackupEntry entry;
  std::string now;           // the drive's value before (as ParameterValue text)
  bool written = false;
  std::string read_back;     // after the write
  std::string note;          // "read-only in this drive: left at ..."
};

struct DriveRestore {
  BackupFile file;
  std::vector<RestoreChange> changes;  // restorable entries whose value differs
  // PDO entries whose value differs; restoring them rewrites each PDO they
  // belong to in order: CANopen: the PDO disabled (COB-ID bit 31), its
  // mapping's sub-index 0 set to 0, the entries, sub-index 0, the other
  // communication parameters, the backup's COB-ID last; EtherCAT (in
  // PREOP): 0x1C12/0x1C13 sub-index 0 to 0 first, the mappings as above,
  // then the assignments and their sub-index 0.
  std::vector<RestoreChange> pdo_changes;
  std::vector<std::string> pdo_steps;  // the writes of that sequence, in order
  int unchanged = 0;                   // restorable entries already equal
  std::vector<std::string> notes;      // serial number differs, stored or not
  bool checked = false;                // identity matched and its parameters were read
  // A write the drive refused (or did not answer) stops the restore there:
  // "writing 0x1A00:02 (mapping entry) = 0x10180120: 0x06040041 ...".
  // Nothing more is written to any drive, and this one is not stored.
  std::string stopped;
  // After such a stop, the state the drive is left in, as read from it:
  // its NMT state and every object written to it so far ("0x1800:01 =
  // 0x80000181"), or why it is not known.
  std::vector<std::string> left;
  bool not_reached = false;            // an earlier drive's stop: nothing written to this one
};

struct RestoreResult {
  std::vector<DriveRestore> drives;
  std::vector<std::string> problems;   // any: nothing (more) written
  bool dry_run = false;
  bool ok() const noexcept { return problems.empty(); }
};

// Where each file's drive is reached: the CAN bus (CANopen files) and the
// EtherCAT master (EtherCAT files, in PREOP); null: that bus is not there,
// and its files are a problem.
struct RestoreBuses {
  can::Transport* can = nullptr;
  ethercat::Master* ethercat = nullptr;
  int64_t sdo_timeout_ns = 500'000'000;
  // Before writing to CANopen drives, the CAN bus is listened to this long
  // for another master (other_master_traffic); 0: not.
  int64_t listen_ns = 300'000'000;
  // A CANopen node's NMT state change is confirmed within this (or three
  // of its heartbeat periods, when longer).
  int64_t nmt_timeout_ns = 500'000'000;
};

// What only a CANopen master sends, seen on `bus` within `window_ns`
// (after what was queued before is dropped): NMT commands (0x000), SYNC
// (0x080), RPDOs of the predefined connection set (0x201-0x57F less the
// TPDOs' identifiers) and SDO requests (0x601-0x67F). "" when none, else
// for people: "SYNC (0x080) x60, RPDO 0x201 x60". A master that sends none
// of these within the window (idle, or its nodes all Pre-operational
// without SDO traffic) is not seen. Non-realtime.
std::string other_master_traffic(can::Transport& bus, int64_t window_ns);

// The restore as described above; with `dry_run` only the checks and the
// list of changes (nothing written).
RestoreResult restore_drives(const std::vector<BackupFile>& files, const RestoreBuses& buses, bool dry_run);
// The same with a channel for each file given by `open` (tests, other
// transports); `open` returns null when the file's bus is not there, with
// `why` saying so.
RestoreResult restore_drives(const std::vector<BackupFile>& files,
                             const std::function<std::unique_ptr<DriveChannel>(const BackupFile&, std::string& why)>& open,
                             bool dry_run);

// Lines for people: per drive what was (or would be) written, read back,
// left alone; then the problems.
std::string describe(const RestoreResult& r);

}  // namespace cnc::commission
