#pragma once
/// Joint-angle tables (CSV, formats/hand-rig.md): a header of DOF names or aliases, one
/// posture a row, degrees, an empty cell = not given.
#include <string>
#include <vector>

namespace handskin {

struct AngleTable {
  std::vector<int> columns;               ///< DOF index per column
  std::vector<std::vector<double>> rows;  ///< NaN = empty cell
  std::vector<long> lines;                ///< file line of each row (for messages)
};

/// Throws InputError naming the file and line: unknown or repeated DOF in the header, a row
/// with another number of cells than the header, a cell that is not a finite number.
AngleTable read_angle_table(const std::string& file);
AngleTable parse_angle_table(const std::string& text, const std::string& file);
/// One line of such a table split at its commas, each cell trimmed of spaces and tabs ('\r'
/// dropped).
std::vector<std::string> split_cells(const std::string& line);
/// Atomic write; NaN cells are written empty.
void write_angle_table(const std::string& file, const AngleTable& table);

}  // namespace handskin
