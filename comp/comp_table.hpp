// A joint's screw-error table as the servo thread uses it: ascending
// nominal positions with a forward and a reverse trim each (the correction
// added to the motor command when travelling + or -), linear between
// entries, the end values held beyond the ends. Read from and written to
// LinuxCNC's COMP_FILE formats (types 0 and 1) with no size limit.
// Loading allocates and throws (non-realtime); lookups never allocate.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace cnc::comp {

// [JOINT_n]COMP_FILE_TYPE.
enum class CompFileType : int {
  Positions = 0,  // nominal, position reached moving +, position reached moving -
  Trims = 1,      // nominal, forward trim, reverse trim
};

struct CompTable {
  std::vector<double> nominal;  // strictly ascending
  std::vector<double> forward;  // trim added to the command while moving +
  std::vector<double> reverse;  // trim added to the command while moving -

  std::size_t size() const noexcept { return nominal.size(); }
  bool empty() const noexcept { return nominal.empty(); }
  // Trim at `pos` for direction > 0 (forward), < 0 (reverse) or 0 (the mean
  // of both). Realtime-safe.
  double at(double pos, int direction) const noexcept;
  double forward_at(double pos) const noexcept { return interpolate(forward, pos); }
  double reverse_at(double pos) const noexcept { return interpolate(reverse, pos); }
  // Largest |trim| and largest |slope| between entries (for load checks).
  double max_abs_trim() const noexcept;
  double max_abs_slope() const noexcept;

 private:
  double interpolate(const std::vector<double>& values, double pos) const noexcept;
};

struct CompParseOptions {
  // A trim larger than this (machine units) is refused as implausible: it
  // usually means the wrong COMP_FILE_TYPE.
  double max_abs_trim = 1.0;
};

// Parses a COMP_FILE's text. `file_name` names the file in errors
// (ConfigError "file:line: ..."). The rules are those of docs/compensation.md,
// chosen so that a file accepted here gives the same table in LinuxCNC 2.9
// (whose loader stops at the first line that is not three numbers): one
// "nominal a b" triplet per line from the first line on, a '#' or ';'
// comment allowed after the numbers; the first comment or blank line ends
// the table and only comments and blank lines (notes) may follow; any
// other line is an error; nominals strictly ascending, trims finite and
// within max_abs_trim, at least one entry. Unlike LinuxCNC (256), the
// number of entries is not limited.
CompTable parse_comp_table(std::string_view text, CompFileType type, const std::string& file_name,
                           const CompParseOptions& options = {});
CompTable load_comp_file(const std::filesystem::path& path, CompFileType type, const CompParseOptions& options = {});

// The table as a COMP_FILE of `type`. `notes` (lines, without '#') are
// written after the table, where LinuxCNC's loader no longer reads.
std::string format_comp_table(const CompTable& table, CompFileType type, const std::vector<std::string>& notes = {});

}  // namespace cnc::comp
