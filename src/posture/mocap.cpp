#include "posture/mocap.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/paths.hpp"

#include "posture/angle_table.hpp"

namespace handskin {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const Eigen::Vector3d kMissing(kNaN, kNaN, kNaN);

bool parse_number(const std::string& s, double* v) {
  if (s.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return *end == '\0';
}

// Each marker's X, Y, Z cells of a data row: cells [first + 3 m, first + 3 m + 3), or, when
// `columns` is given, the cells it names per marker.
// Qualisys writes an unseen marker as 0 0 0 (`zero_is_missing`); TRC leaves the cells empty.
std::vector<Eigen::Vector3d> read_positions(const std::vector<std::string>& cells, size_t first, size_t markers,
                                            double scale, bool zero_is_missing, const std::string& where,
                                            const std::vector<std::array<size_t, 3>>* columns = nullptr) {
  std::vector<Eigen::Vector3d> p(markers, kMissing);
  for (size_t m = 0; m < markers; ++m) {
    double xyz[3] = {0, 0, 0};
    bool ok = true;
    for (int k = 0; k < 3; ++k) {
      const size_t c = columns ? (*columns)[m][k] : first + 3 * m + k;
      if (c >= cells.size() || cells[c].empty()) {
        ok = false;
        continue;
      }
      if (!parse_number(cells[c], &xyz[k])) throw InputError(where, "'" + cells[c] + "' is not a number");
      if (!std::isfinite(xyz[k])) ok = false;
    }
    if (ok && !(zero_is_missing && xyz[0] == 0 && xyz[1] == 0 && xyz[2] == 0)) p[m] = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]) * scale;
  }
  return p;
}
}  // namespace

MarkerTrack read_qualisys_tsv(const std::string& file) { return parse_qualisys_tsv(read_file(file), file); }

MarkerTrack parse_qualisys_tsv(const std::string& text, const std::string& file) {
  std::istringstream in(text);
  MarkerTrack t;
  std::string line;
  long lineno = 0;
  size_t first = 0;  // column of the first coordinate
  std::vector<std::array<size_t, 3>> columns;  // per marker its X, Y, Z columns, when not in threes
  long declared_frames = -1;
  bool data = false;
  while (std::getline(in, line)) {
    ++lineno;
    const auto cells = split_fields(line, '\t', false);
    const std::string where = file + ":" + std::to_string(lineno);
    if (!data) {
      if (cells[0] == "MARKER_NAMES") {
        t.names.assign(cells.begin() + 1, cells.end());
        while (!t.names.empty() && t.names.back().empty()) t.names.pop_back();
      } else if (cells[0] == "FREQUENCY" && cells.size() > 1) {
        if (!parse_number(cells[1], &t.rate_hz) || !(t.rate_hz > 0)) throw InputError(where, "FREQUENCY is not a positive number");
      } else if (cells[0] == "NO_OF_FRAMES" && cells.size() > 1) {
        double v;
        if (!parse_number(cells[1], &v) || !(v >= 0 && v <= 1e9) || v != std::floor(v))
          throw InputError(where, "NO_OF_FRAMES '" + cells[1] + "' is not a count in [0, 1e9]");
        declared_frames = static_cast<long>(v);
      } else if (cells[0] == "Frame") {  // column header of exports with frame and time columns
        first = 2;
        data = true;
        // Each marker's columns by their names ("hand_top X" …): an export with more columns
        // per marker (QTM's trajectory types, "hand_top Type") is read by name, not by threes.
        std::map<std::string, size_t> at;
        for (size_t c = 0; c < cells.size(); ++c) at.emplace(cells[c], c);
        std::vector<std::array<size_t, 3>> named;
        for (const std::string& m : t.names) {
          const auto x = at.find(m + " X"), y = at.find(m + " Y"), z = at.find(m + " Z");
          if (x == at.end() || y == at.end() || z == at.end()) break;
          named.push_back({x->second, y->second, z->second});
        }
        if (named.size() == t.names.size() && !named.empty()) columns = std::move(named);
      } else {
        double v;
        if (parse_number(cells[0], &v)) {  // exports without the column header: data starts here
          if (t.names.empty()) throw InputError(where, "data before a MARKER_NAMES line");
          data = true;
          first = 0;
        } else {
          continue;  // other header keys
        }
      }
      if (!data) continue;
      if (cells[0] == "Frame") continue;
    }
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (t.names.empty()) throw InputError(file, "no MARKER_NAMES line before the data");
    // Qualisys writes every cell of every row (an unseen marker as 0 0 0): a short row is a
    // file cut mid-row, not a frame with markers missing.
    size_t expected = first + 3 * t.names.size();
    for (const auto& m : columns) expected = std::max({expected, m[0] + 1, m[1] + 1, m[2] + 1});
    if (cells.size() < expected)
      throw InputError(where, "the row has " + std::to_string(cells.size()) + " cells, " + std::to_string(expected) +
                                  " expected (" + std::to_string(t.names.size()) + " markers): the file is cut mid-row?");
    t.frames.push_back(read_positions(cells, first, t.names.size(), 1.0, true, where, columns.empty() ? nullptr : &columns));
  }
  if (t.names.empty()) throw InputError(file, "not a Qualisys TSV export (no MARKER_NAMES line)");
  if (t.frames.empty()) throw InputError(file, "no data rows");
  if (declared_frames >= 0 && declared_frames != static_cast<long>(t.frames.size()))
    throw InputError(file, "NO_OF_FRAMES says " + std::to_string(declared_frames) + " but the file holds " +
                               std::to_string(t.frames.size()) + " rows (truncated?)");
  return t;
}

MarkerTrack read_trc(const std::string& file) { return parse_trc(read_file(file), file); }

MarkerTrack parse_trc(const std::string& text, const std::string& file) {
  std::istringstream in(text);
  MarkerTrack t;
  std::string line;
  long lineno = 0;
  std::vector<std::string> keys;
  double scale = 1.0;
  long declared_frames = -1, declared_markers = -1;
  auto count_of = [](const std::string& cell, const std::string& where, const char* key) {
    double v;
    if (!parse_number(cell, &v) || !(v >= 0 && v <= 1e9) || v != std::floor(v))
      throw InputError(where, std::string(key) + " '" + cell + "' is not a count in [0, 1e9]");
    return static_cast<long>(v);
  };
  const bool ends_with_newline = !text.empty() && text.back() == '\n';
  int stage = 0;  // 0: PathFileType, 1: keys, 2: values, 3: names, 4: X1 Y1 Z1, 5: data
  while (std::getline(in, line)) {
    ++lineno;
    const auto cells = split_fields(line, '\t', false);
    const std::string where = file + ":" + std::to_string(lineno);
    if (stage == 0) {
      if (cells[0] != "PathFileType") throw InputError(where, "not a TRC file (first line must start with PathFileType)");
      stage = 1;
    } else if (stage == 1) {
      keys = cells;
      stage = 2;
    } else if (stage == 2) {
      for (size_t k = 0; k < keys.size() && k < cells.size(); ++k) {
        if (keys[k] == "DataRate" && !parse_number(cells[k], &t.rate_hz)) throw InputError(where, "DataRate is not a number");
        if (keys[k] == "NumFrames") declared_frames = count_of(cells[k], where, "NumFrames");
        if (keys[k] == "NumMarkers") declared_markers = count_of(cells[k], where, "NumMarkers");
        if (keys[k] == "Units") {
          if (cells[k] == "m") scale = 1000.0;
          else if (cells[k] == "cm") scale = 10.0;
          else if (cells[k] != "mm") throw InputError(where, "Units '" + cells[k] + "' (use mm, cm or m)");
        }
      }
      stage = 3;
    } else if (stage == 3) {
      if (cells.size() < 3 || cells[0] != "Frame#") throw InputError(where, "expected the 'Frame#  Time  markers...' line");
      for (size_t k = 2; k < cells.size(); ++k)
        if (!cells[k].empty()) t.names.push_back(cells[k]);
      stage = 4;
    } else if (stage == 4) {
      stage = 5;  // X1 Y1 Z1 ... line
    } else {
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      // A TRC leaves an unseen marker's cells empty (some writers drop trailing ones): a row
      // may be short by whole markers, but not end inside one — nor may the file's last,
      // unterminated row be short at all.
      const size_t expected = 2 + 3 * t.names.size();
      const bool last = in.peek() == std::char_traits<char>::eof();
      if (cells.size() < expected && ((cells.size() - 2) % 3 != 0 || (last && !ends_with_newline)))
        throw InputError(where, "the row has " + std::to_string(cells.size()) + " cells, " + std::to_string(expected) +
                                    " expected: the file is cut mid-row?");
      t.frames.push_back(read_positions(cells, 2, t.names.size(), scale, false, where));
    }
  }
  if (stage < 5 || t.names.empty()) throw InputError(file, "incomplete TRC header");
  if (t.frames.empty()) throw InputError(file, "no data rows");
  if (declared_markers >= 0 && declared_markers != static_cast<long>(t.names.size()))
    throw InputError(file, "NumMarkers says " + std::to_string(declared_markers) + " but the header names " +
                               std::to_string(t.names.size()) + " markers");
  if (declared_frames >= 0 && declared_frames != static_cast<long>(t.frames.size()))
    throw InputError(file, "NumFrames says " + std::to_string(declared_frames) + " but the file holds " +
                               std::to_string(t.frames.size()) + " rows (truncated?)");
  return t;
}

MarkerTrack read_marker_file(const std::string& file) {
  const std::string ext = lower_extension(file);
  if (ext == ".tsv") return read_qualisys_tsv(file);
  if (ext == ".trc") return read_trc(file);
  throw InputError(file, "unknown marker-file extension (use .tsv for Qualisys or .trc for OpenSim)");
}

MocapAngles angles_from_markers(const MarkerTrack& track, const std::string& file) {
  // Markers by name; a name as Vicon and QTM label them for a subject ("P01:hand_top") or in
  // capitals ("Hand_Top") is the marker set's name too (an exact name first).
  std::map<std::string, int> idx;
  for (size_t k = 0; k < track.names.size(); ++k) idx.emplace(track.names[k], static_cast<int>(k));
  for (size_t k = 0; k < track.names.size(); ++k) {
    std::string plain = track.names[k].substr(track.names[k].find_last_of(':') + 1);
    std::transform(plain.begin(), plain.end(), plain.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    idx.emplace(plain, static_cast<int>(k));
  }
  for (const char* need : {"hand_top", "hand_left", "hand_right"})
    if (!idx.count(need))
      throw InputError(file, std::string("no marker '") + need +
                                 "': the back-of-hand markers hand_top, hand_left, hand_right are needed for a hand frame");
  MocapAngles out;
  auto has = [&](const std::string& n) { return idx.count(n) > 0; };
  // Each angle needs only the markers its lines join (besides the back's three): an occluded
  // fingertip leaves its PIP bend out of that frame, not the MCP flexion and spread beside it
  // (before, a digit's angles were all or nothing: a recording without thumb_tip lost
  // thumb.cmc.abd, which hand_left -> thumb_middle gives alone, and every frame that missed a
  // fingertip lost that finger's MCP angles too).
  struct Angle {
    std::string name;
    std::vector<std::string> needs;  ///< markers besides the back's three
  };
  std::vector<Angle> angles;
  for (const std::string d : {"thumb", "index", "middle", "ring", "little"}) {
    const std::string mid = d + "_middle", tip = d + "_tip";
    if (d == "thumb") {
      angles.push_back({"thumb.cmc.abd", {mid}});
      angles.push_back({"thumb.mcp.flex", {mid, tip}});
    } else {
      angles.push_back({d + ".mcp.flex", {mid}});
      angles.push_back({d + ".pip.flex", {mid, tip}});
      angles.push_back({d + ".mcp.abd", d == "middle" ? std::vector<std::string>{mid} : std::vector<std::string>{mid, "middle_middle"}});
    }
  }
  std::vector<std::string> cols;
  std::vector<std::vector<int>> needs;  // per column: the markers' indices
  for (const Angle& a : angles) {
    std::vector<std::string> absent;
    for (const auto& m : a.needs)
      if (!has(m)) absent.push_back(m);
    if (!absent.empty()) {
      std::string list;
      for (const auto& m : absent) list += (list.empty() ? "" : ", ") + m;
      out.notes.push_back(a.name + ": no marker " + list + " in the recording; left out");
      continue;
    }
    cols.push_back(a.name);
    needs.emplace_back();
    for (const auto& m : a.needs) needs.back().push_back(idx.at(m));
  }
  // Which back-of-hand marker is on the thumb's side, and which hand it is: from the recording
  // itself, not assumed. The marker set's convention puts hand_left on the thumb's side (as on a
  // right hand seen from above); markers named by the subject's left and right on a left hand
  // put hand_right there instead (the thumb's markers lie nearer it): the two are swapped. And
  // the back of the hand is the side of its plane away from the fingertips and the thumb: u x v
  // for a right hand, v x u for a left one (a left hand taken for a right one had the sign of
  // every flexion turned: the mirror image of the shared recording gave index.mcp.flex 77° off).
  const auto median = [](std::vector<double> v) {
    if (v.empty()) return kNaN;
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const auto marker = [&](const std::vector<Eigen::Vector3d>& fr, const std::string& n) {
    return has(n) ? fr[idx.at(n)] : Eigen::Vector3d::Constant(kNaN);
  };
  // The hand's axes from the back's markers: u along the hand, v toward the thumb's side.
  const auto hand_axes = [](const Eigen::Vector3d& top, const Eigen::Vector3d& thumb_side, const Eigen::Vector3d& other) {
    const Eigen::Vector3d u = (top - 0.5 * (thumb_side + other)).normalized(), w = thumb_side - other;
    return std::pair<Eigen::Vector3d, Eigen::Vector3d>{u, (w - w.dot(u) * u).normalized()};
  };
  const std::string thumb_marker = has("thumb_middle") ? "thumb_middle" : "thumb_tip";
  std::vector<double> nearer_left;
  for (const auto& fr : track.frames) {
    const Eigen::Vector3d t = marker(fr, thumb_marker), l = marker(fr, "hand_left"), r = marker(fr, "hand_right");
    if (t.allFinite() && l.allFinite() && r.allFinite()) nearer_left.push_back((t - r).norm() - (t - l).norm());
  }
  const bool swapped = median(nearer_left) < 0;  // NaN (no thumb marker): the convention
  const std::string thumb_side = swapped ? "hand_right" : "hand_left", other_side = swapped ? "hand_left" : "hand_right";
  std::vector<double> below;  // per frame: the digits' markers' mean depth below the u x v plane
  for (const auto& fr : track.frames) {
    const Eigen::Vector3d top = marker(fr, "hand_top"), l = marker(fr, thumb_side), r = marker(fr, other_side);
    if (!top.allFinite() || !l.allFinite() || !r.allFinite()) continue;
    const std::pair<Eigen::Vector3d, Eigen::Vector3d> axes = hand_axes(top, l, r);
    const Eigen::Vector3d n = axes.first.cross(axes.second);
    double sum = 0;
    int count = 0;
    for (const char* m : {"thumb_middle", "thumb_tip", "index_tip", "middle_tip", "ring_tip", "little_tip"})
      if (const Eigen::Vector3d q = marker(fr, m); q.allFinite()) sum -= (q - top).dot(n), ++count;
    if (count > 0) below.push_back(sum / count);
  }
  const bool left_hand = median(below) < 0;
  out.notes.push_back(std::string(left_hand ? "a left hand" : "a right hand") +
                      " (its fingertips and thumb lie on that side of the back-of-hand plane)" +
                      (swapped ? "; hand_right is on the thumb's side (the thumb's markers lie nearer it): hand_left "
                                 "and hand_right are taken the other way round below"
                               : ""));
  out.notes.push_back(
      "hand frame: u = hand_top - midpoint(hand_left, hand_right) (along the hand), v = toward hand_left (thumb "
      "side), n = the back of the hand (u x v on a right hand, v x u on a left one)");
  out.notes.push_back(
      "<f>.mcp.flex: elevation of hand_top -> <f>_middle below the back-of-hand plane; <f>.pip.flex: the further "
      "bend of <f>_middle -> <f>_tip (PIP and DIP together); <f>.mcp.abd: lateral angle of hand_top -> <f>_middle "
      "from the middle finger's, away from it positive; thumb.mcp.flex: bend between hand_left -> thumb_middle and "
      "thumb_middle -> thumb_tip (MCP and IP together); thumb.cmc.abd: lateral angle of hand_left -> thumb_middle "
      "from the hand axis. Angles carry marker-placement offsets: calibrate uses them relative to their median");
  constexpr double kDeg = 180.0 / M_PI;
  size_t frames_with_back = 0;
  for (const auto& fr : track.frames) {
    std::vector<double> row(cols.size(), kNaN);
    auto P = [&](const std::string& n) { return fr[idx.at(n)]; };
    const Eigen::Vector3d top = P("hand_top"), left = P(thumb_side), right = P(other_side);
    if (top.allFinite() && left.allFinite() && right.allFinite()) {
      ++frames_with_back;
      // (Named variables, not a structured binding: the lambdas below capture them, which
      // C++17 allows of variables only — clang refuses a binding.)
      const std::pair<Eigen::Vector3d, Eigen::Vector3d> axes = hand_axes(top, left, right);
      const Eigen::Vector3d u = axes.first, v = axes.second;
      const Eigen::Vector3d n = left_hand ? v.cross(u) : u.cross(v);
      auto elevation = [&](const Eigen::Vector3d& d) { return std::atan2(-d.dot(n), d.dot(u)) * kDeg; };
      auto lateral = [&](const Eigen::Vector3d& d) { return std::atan2(d.dot(v), d.dot(u)) * kDeg; };
      for (size_t c = 0; c < cols.size(); ++c) {
        bool seen = true;
        for (const int m : needs[c]) seen = seen && fr[m].allFinite();
        if (!seen) continue;
        const std::string& name = cols[c];
        const std::string f = name.substr(0, name.find('.'));
        const Eigen::Vector3d mid = P(f + "_middle");
        if (f == "thumb") {
          const Eigen::Vector3d p = mid - left;
          row[c] = name == "thumb.mcp.flex"
                       ? std::acos(std::clamp(p.normalized().dot((P("thumb_tip") - mid).normalized()), -1.0, 1.0)) * kDeg
                       : lateral(p);
          continue;
        }
        const Eigen::Vector3d p = mid - top;
        if (name.find(".mcp.flex") != std::string::npos) {
          row[c] = elevation(p);
        } else if (name.find(".pip.flex") != std::string::npos) {
          row[c] = elevation(P(f + "_tip") - mid) - elevation(p);
        } else if (f == "middle") {
          row[c] = lateral(p);
        } else {
          const double lat_mid = lateral(P("middle_middle") - top);
          row[c] = f == "index" ? lateral(p) - lat_mid : lat_mid - lateral(p);
        }
      }
    }
    out.table.rows.push_back(std::move(row));
    out.table.lines.push_back(static_cast<long>(out.table.rows.size()));
  }
  // An angle whose markers were never seen together is left out, said in the notes, not
  // written as a column of empty cells; a recording that gives no angle at all is an error.
  if (!track.frames.empty() && frames_with_back == 0)
    throw InputError(file, "hand_top, hand_left and hand_right are never seen in the same frame: no hand frame, no angles");
  std::vector<size_t> kept;
  for (size_t c = 0; c < cols.size(); ++c) {
    bool any = false;
    for (const auto& row : out.table.rows) any = any || std::isfinite(row[c]);
    if (any) {
      kept.push_back(c);
    } else {
      std::string list;
      for (const int m : needs[c]) list += (list.empty() ? "" : ", ") + track.names[m];
      out.notes.push_back(cols[c] + ": its markers (" + list + " and the back's three) are never seen together; left out");
    }
  }
  if (kept.empty()) throw InputError(file, "no joint angle can be measured: every digit's markers are missing or never seen");
  if (kept.size() < cols.size()) {
    for (auto& row : out.table.rows) {
      std::vector<double> r;
      for (const size_t c : kept) r.push_back(row[c]);
      row = std::move(r);
    }
    std::vector<std::string> names;
    for (const size_t c : kept) names.push_back(cols[c]);
    cols = std::move(names);
  }
  for (const auto& c : cols) out.table.columns.push_back(dof_index(c).value());
  for (const auto& row : out.table.rows)
    out.frames_with_gaps += std::any_of(row.begin(), row.end(), [](double v) { return std::isnan(v); });
  return out;
}

}  // namespace handskin
