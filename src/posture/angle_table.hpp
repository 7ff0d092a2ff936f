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
/// One line of a delimited text table split at `separator` (carriage returns and newlines
/// dropped), each cell's surrounding spaces and tabs trimmed when `trim`: the CSV reader's
/// (comma, trimmed) and the motion-capture TSV reader's (tab, as is).
std::vector<std::string> split_fields(const std::string& line, char separator, bool trim);
/// A CSV line's cells: split_fields(line, ',', true).
std::vector<std::string> split_cells(const std::string& line);
/// Atomic write; NaN cells are written empty.
void write_angle_table(const std::string& file, const AngleTable& table);

}  // namespace handskin
