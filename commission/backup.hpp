// Step 9's drive-parameter backup: an SDO upload, from the CANopen drive of
// every enabled axis, of the parameters that make the drive behave as
// commissioned (identity 0x1018 and device type, names and versions, the
// heartbeat 0x1017, the CiA 402 mode and option codes 0x6060, 0x6007,
// 0x605A-0x605E, quick stop deceleration 0x6085, polarity 0x607E, software
// limits 0x607D, factor group 0x608F/0x6091/0x6092, following-error window
// 0x6065/0x6066, position window 0x6067/0x6068, homing 0x6098/0x6099/
// 0x609A and home offset 0x607C, interpolation period 0x60C2, the loops'
// gains 0x60F9/0x60FB where the drive has them (the sub-indices its EDS
// lists, else those its sub-index 0 counts), every PDO the drive has:
// communication parameters 0x1400-0x15FF/0x1800-0x19FF (those the EDS
// lists, else found by reading them in turn until 8 numbers in a row do
// not exist) and mappings 0x1600-0x17FF/0x1A00-0x1BFF, and the readable
// objects of 0x2000-0x5FFF that the drive's EDS lists). One DCF-like file per drive ([index] or
// [indexsubN] sections with ParameterValue), written atomically. An object
// the drive lacks is listed in the file's [Missing] section; a node that
// does not answer is a problem naming it, and then nothing is written.
// Works on any can::Transport, as the bus scan.
// EtherCAT drives (axes with a slave position) are read the same way over
// CoE SDO through the EtherCAT master in PREOP: the same CiA 402 list, the
// identity 0x1018, the PDO assignment 0x1C12/0x1C13 (the PDOs its
// sub-index 0 counts) and every mapping 0x1600-0x17FF/0x1A00-0x1BFF (those
// the SDO information lists, else found in turn as above), and the
// manufacturer objects 0x2000-0x5FFF the drive lists in its SDO
// information (with each entry's access, kept as AccessType so that a
// restore leaves read-only values alone). Same file format, "slave-NN-l.dcf".
// A restore (commission/restore.hpp) reads these files back. Non-realtime.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "commission/config_writer.hpp"
#include "commission/state.hpp"
#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/types.hpp"

namespace cnc::ethercat {
class Master;
}

namespace cnc::commission {

struct BackupObject {
  canopen::ObjectAddress addr;
  canopen::DataType type = canopen::DataType::Unsigned32;
  std::string name;
  std::string access;   // "rw" "ro" "wo" "const" as the EDS or SDO information says; "" not known
};

// The fixed list read from every drive (the PDOs are added as they are
// found, the mapping entries after their sub-index 0 is read, the EDS's
// manufacturer objects per drive).
const std::vector<BackupObject>& backup_objects();

struct BackedUpValue {
  BackupObject object;
  std::vector<uint8_t> data;
};

struct NodeBackup {
  int node = 0;                         // CANopen node-ID (0: an EtherCAT drive)
  unsigned slave = 0;                   // EtherCAT: position in the segment (0: a CANopen drive)
  char axis = 'X';
  std::string eds;                      // the matched EDS ("" none)
  std::vector<BackedUpValue> values;    // in address order
  std::vector<std::string> missing;     // "1009: 0x06020000 object does not exist..." (address: abort)
  std::string file;                     // its file name
};

struct BackupResult {
  std::vector<NodeBackup> nodes;
  std::vector<std::string> skipped;     // disabled axes, said so
  std::vector<std::string> problems;    // silent nodes, unreadable EDS: nothing is written
  bool ok() const noexcept { return problems.empty(); }
};

struct BackupOptions {
  int64_t timeout_ns = 500'000'000;     // per SDO transfer
  // Without an EDS (CANopen) or SDO information (EtherCAT) the PDOs are
  // searched for number by number; this many numbers in a row that do not
  // exist end the search (a gap as long loses the PDOs after it).
  unsigned pdo_search_gap = 8;
};

// Reads the CANopen drives of the state's enabled axes over `bus`.
BackupResult backup_drives(can::Transport& bus, const State& s, const BackupOptions& options = {});

// Reads the EtherCAT drives of the state's enabled axes through `master`
// (scanned and in PREOP: Master::to_preop). A slave position the segment
// does not have, or a slave without CoE, is a problem naming it.
BackupResult backup_ethercat_drives(ethercat::Master& master, const State& s);
// The same on the segment of `interface` ("raw:eth0", "sim:<segment>"):
// brings the slaves to PREOP, reads them, leaves them in INIT. A segment
// that cannot be opened or scanned is a problem.
BackupResult backup_ethercat_drives(const std::string& interface, const State& s);
// Whether the state has enabled axes on CANopen (node) or EtherCAT (slave) drives.
bool has_canopen_axes(const State& s);
bool has_ethercat_axes(const State& s);

// ParameterValue as written for `type` (unsigned as 0x-hex of the type's
// size, signed decimal, reals, strings as text, others as hex bytes), and
// back: nullopt when `text` is not a value of that type.
std::string backup_value_text(canopen::DataType type, const std::vector<uint8_t>& data);
std::optional<std::vector<uint8_t>> parse_backup_value(canopen::DataType type, const std::string& text);

// The file of one drive (DCF-like INI text); `time` and `interface` go into
// its header.
std::string format_backup(const NodeBackup& b, const State& s, const std::string& time);

// Writes every drive's file to `dir` atomically (when the result has no
// problem; else throws std::runtime_error listing them) and records the
// backup in the state. Returns the files written.
std::vector<std::filesystem::path> write_backup(State& s, BackupResult& r, const std::filesystem::path& dir);

// The backup's files as the configuration writer adds them to its folder
// (<dir>/drive-backup/<file>), read from where `backup` wrote them; throws
// std::runtime_error naming a file that is gone. None when no backup was taken.
std::vector<GeneratedFile> backup_files(const State& s, const std::filesystem::path& dir);

// Now, UTC, ISO 8601 ("2026-11-27T07:15:02Z").
std::string utc_now();

}  // namespace cnc::commission
