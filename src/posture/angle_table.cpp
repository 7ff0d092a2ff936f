#include "posture/angle_table.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <set>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"

namespace handskin {

std::vector<std::string> split_fields(const std::string& line, char separator, bool trim) {
  std::vector<std::string> cells;
  std::string cur;
  for (char c : line) {
    if (c == separator) {
      cells.push_back(cur);
      cur.clear();
    } else if (c != '\r' && c != '\n') {
      cur += c;
    }
  }
  cells.push_back(cur);
  if (trim)
    for (auto& c : cells) {
      const size_t a = c.find_first_not_of(" \t"), b = c.find_last_not_of(" \t");
      c = a == std::string::npos ? "" : c.substr(a, b - a + 1);
    }
  return cells;
}

std::vector<std::string> split_cells(const std::string& line) { return split_fields(line, ',', true); }

namespace {
// A cell as it can be shown in one line of an error: control and non-ASCII bytes as \xNN,
// so an invisible character is seen.
std::string printable(const std::string& c) {
  std::string out;
  for (const unsigned char ch : c) {
    if (ch >= 0x20 && ch < 0x7f) {
      out += static_cast<char>(ch);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", ch);
      out += buf;
    }
  }
  return out;
}
}  // namespace

AngleTable parse_angle_table(const std::string& text, const std::string& file) {
  AngleTable t;
  // A UTF-8 byte-order mark (spreadsheets write one) is not part of the first DOF's name.
  const bool bom = text.compare(0, 3, "\xEF\xBB\xBF") == 0;
  std::istringstream in(bom ? text.substr(3) : text);
  std::string line;
  long lineno = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;  // blank lines
    const std::vector<std::string> cells = split_cells(line);
    const std::string where = file + ":" + std::to_string(lineno);
    if (!header) {
      if (cells.size() == 1 && line.find(';') != std::string::npos)
        throw InputError(where, "the header is separated by ';'; this format uses ',' between cells and '.' in numbers");
      if (cells.size() == 1 && line.find('\t') != std::string::npos)
        throw InputError(where, "the header is separated by tabs; this format uses ',' between cells");
      std::set<int> seen;
      for (const auto& c : cells) {
        const auto d = dof_index(c);
        if (!d) throw InputError(where, "header names unknown DOF '" + printable(c) + "'");
        if (!seen.insert(*d).second) throw InputError(where, "header names DOF '" + c + "' twice");
        t.columns.push_back(*d);
      }
      header = true;
      continue;
    }
    if (cells.size() != t.columns.size())
      throw InputError(where, std::to_string(cells.size()) + " cells, but the header has " +
                                  std::to_string(t.columns.size()));
    std::vector<double> row(cells.size(), std::numeric_limits<double>::quiet_NaN());
    for (size_t k = 0; k < cells.size(); ++k) {
      if (cells[k].empty()) continue;
      char* end = nullptr;
      const double v = std::strtod(cells[k].c_str(), &end);
      if (*end != '\0' || !std::isfinite(v))
        throw InputError(where, "column '" + dofs()[t.columns[k]].name + "': '" + cells[k] + "' is not a finite number");
      if (std::abs(v) > 1e5)
        throw InputError(where, "column '" + dofs()[t.columns[k]].name + "': " + cells[k] +
                                    " is not a plausible angle (degrees) or offset (mm)");
      row[k] = v;
    }
    t.rows.push_back(std::move(row));
    t.lines.push_back(lineno);
  }
  if (!header) throw InputError(file, "empty: no header line");
  return t;
}

AngleTable read_angle_table(const std::string& file) { return parse_angle_table(read_file(file), file); }

void write_angle_table(const std::string& file, const AngleTable& t) {
  std::string out;
  for (size_t k = 0; k < t.columns.size(); ++k) out += (k ? "," : "") + dofs()[t.columns[k]].name;
  out += '\n';
  char buf[64];
  for (const auto& row : t.rows) {
    for (size_t k = 0; k < row.size(); ++k) {
      if (k) out += ',';
      if (std::isfinite(row[k])) {
        std::snprintf(buf, sizeof buf, "%.6g", row[k]);
        out += buf;
      }
    }
    out += '\n';
  }
  write_file_atomic(file, out);
}

}  // namespace handskin
