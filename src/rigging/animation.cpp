#include "rigging/animation.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"
#include "posture/angle_table.hpp"

namespace handskin {

namespace {
bool blank(const std::string& line) { return line.find_first_not_of(" \t\r") == std::string::npos; }
}  // namespace

KeyFrames parse_keyframes(const std::string& text, const std::string& file) {
  // The time column is taken out of the text; the rest is an angle table (its parser gives
  // the DOF columns and every error about them, with the same line numbers).
  std::istringstream in(text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? text.substr(3) : text);
  std::string line, rest;
  long lineno = 0, time_col = -1;
  bool header = false;
  std::vector<std::pair<long, std::string>> time_cells;
  while (std::getline(in, line)) {
    ++lineno;
    if (blank(line)) {
      rest += "\n";
      continue;
    }
    std::vector<std::string> cells = split_cells(line);
    if (!header) {
      for (size_t c = 0; c < cells.size(); ++c) {
        std::string h = cells[c];
        std::transform(h.begin(), h.end(), h.begin(), [](unsigned char ch) { return std::tolower(ch); });
        if (h == "time") time_col = static_cast<long>(c);
      }
      header = true;
    } else if (time_col >= 0 && time_col < static_cast<long>(cells.size())) {
      time_cells.emplace_back(lineno, cells[time_col]);
    } else if (time_col >= 0) {
      throw InputError(file + ":" + std::to_string(lineno), "the row has no cell in the 'time' column");
    }
    if (time_col >= 0 && time_col < static_cast<long>(cells.size())) cells.erase(cells.begin() + time_col);
    for (size_t c = 0; c < cells.size(); ++c) rest += (c ? "," : "") + cells[c];
    rest += "\n";
  }
  const AngleTable t = parse_angle_table(rest, file);
  KeyFrames k;
  k.dofs = t.columns;
  k.values = t.rows;
  k.lines = t.lines;
  if (k.values.size() < 2) throw InputError(file, "an animation needs at least two keys (rows), found " + std::to_string(k.values.size()));
  if (k.values.size() > 10000) throw InputError(file, "more than 10000 keys");
  for (size_t r = 0; r < k.values.size(); ++r) {
    double time = static_cast<double>(r);
    if (time_col >= 0) {
      const std::string where = file + ":" + std::to_string(time_cells[r].first);
      const std::string& c = time_cells[r].second;
      char* end = nullptr;
      time = std::strtod(c.c_str(), &end);
      if (c.empty() || end != c.c_str() + c.size() || !std::isfinite(time) || time < 0 || time > 3600)
        throw InputError(where, "time '" + c + "' must be a number of seconds in [0, 3600]");
      if (r > 0 && time <= k.times.back())
        throw InputError(where, "time " + c + " s is not after the key before it; keys must be in time order");
    }
    k.times.push_back(time);
  }
  return k;
}

KeyFrames read_keyframes(const std::string& file) { return parse_keyframes(read_file(file), file); }

double bezier_at(const std::vector<double>& T, const std::vector<double>& V, double t) {
  const size_t n = T.size();
  HS_CHECK(n == V.size() && n >= 1, "bezier_at: keys and values differ");
  if (n == 1 || t <= T.front()) return V.front();
  if (t >= T.back()) return V.back();
  const size_t k = static_cast<size_t>(std::upper_bound(T.begin(), T.end(), t) - T.begin()) - 1;
  auto slope = [&](size_t i) {  // the tangent at key i (value per second)
    if (i == 0 || i + 1 == n) return 0.0;
    // Flat at a key that is a turning point or that equals a neighbour (Blender's "auto
    // clamped" handles): the curve then never overshoots a key, and holds between equal keys.
    if ((V[i] - V[i - 1]) * (V[i + 1] - V[i]) <= 0) return 0.0;
    return (V[i + 1] - V[i - 1]) / (T[i + 1] - T[i - 1]);
  };
  const double h = T[k + 1] - T[k], u = (t - T[k]) / h, w = 1 - u;
  const double p0 = V[k], p3 = V[k + 1], p1 = p0 + slope(k) * h / 3, p2 = p3 - slope(k + 1) * h / 3;
  return w * w * w * p0 + 3 * w * w * u * p1 + 3 * w * u * u * p2 + u * u * u * p3;
}

PostureAnimation animate(const PostureSolver& solver, const KeyFrames& keys, double fps, bool inputs_only,
                         const std::string& file) {
  if (!(fps >= 1 && fps <= 240)) throw UsageError("--fps", "must be in [1, 240] frames per second");
  HS_CHECK(keys.times.size() >= 2, "animate: fewer than two keys");
  const size_t nk = keys.times.size();
  const double t0 = keys.times.front(), duration = keys.times.back() - t0;
  const size_t frames = static_cast<size_t>(std::floor(duration * fps + 1e-9)) + 1;
  if (frames > 100000) throw InputError(file, "the animation would have more than 100000 frames; lower --fps or shorten it");
  PostureAnimation a;
  const auto& dof = solver.model().dof;
  auto pins_of = [&](const std::vector<double>& row) {
    PostureInputs in;
    for (size_t c = 0; c < keys.dofs.size(); ++c)
      if (std::isfinite(row[c])) in.pins.emplace_back(keys.dofs[c], row[c]);
    return in;
  };
  std::vector<double> times(keys.times);
  for (double& t : times) t -= t0;
  if (inputs_only) {
    for (size_t r = 0; r < nk; ++r)
      for (size_t c = 0; c < keys.dofs.size(); ++c)
        if (!std::isfinite(keys.values[r][c]))
          throw InputError(file + ":" + std::to_string(keys.lines[r]),
                           "key gives no " + dofs()[keys.dofs[c]].name +
                               "; with --inputs-only every key must give every input it animates");
  }
  // Keyframe mode: whole postures at the keys; inputs-only: the keys' rows as they are.
  std::vector<std::vector<double>> series;  // per animated DOF: its value at each key
  std::vector<int> animated;
  if (inputs_only) {
    animated = keys.dofs;
    for (size_t c = 0; c < keys.dofs.size(); ++c) {
      series.emplace_back();
      for (size_t r = 0; r < nk; ++r) series.back().push_back(keys.values[r][c]);
    }
  } else {
    std::vector<Angles> postures;
    for (size_t r = 0; r < nk; ++r) {
      const PostureSolution s = solver.solve(pins_of(keys.values[r]));
      a.clamped += s.clamped_inputs;
      postures.push_back(s.angles);
    }
    for (int d = 0; d < kDofCount; ++d) {
      animated.push_back(d);
      series.emplace_back();
      for (size_t r = 0; r < nk; ++r) series.back().push_back(postures[r][d]);
    }
  }
  // Frames 1 / fps apart, and the last key's time exactly, so that the animation ends on it.
  for (size_t f = 0; f < frames; ++f) a.times.push_back(std::min(static_cast<double>(f) / fps, times.back()));
  if (a.times.back() < times.back() - 1e-9) a.times.push_back(times.back());
  for (const double t : a.times) {
    std::vector<double> v(animated.size());
    for (size_t c = 0; c < animated.size(); ++c) v[c] = bezier_at(times, series[c], t);
    if (inputs_only) {
      PostureInputs in;
      for (size_t c = 0; c < animated.size(); ++c) in.pins.emplace_back(animated[c], v[c]);
      const PostureSolution s = solver.solve(in);
      a.clamped += s.clamped_inputs;
      a.frames.push_back(s.angles);
    } else {
      Angles ang{};
      for (size_t c = 0; c < animated.size(); ++c) {
        const int d = animated[c];
        const double x = std::clamp(v[c], dof[d].lo, dof[d].hi);  // a Bézier can overshoot its keys
        a.clamped += x != v[c];
        ang[d] = x;
      }
      a.frames.push_back(ang);
    }
  }
  return a;
}

std::string animation_csv(const PostureAnimation& a) {
  std::string out = "time";
  for (int d = 0; d < kDofCount; ++d) out += "," + dofs()[d].name;
  out += "\n";
  char buf[64];
  for (size_t f = 0; f < a.frames.size(); ++f) {
    std::snprintf(buf, sizeof buf, "%.6g", a.times[f]);
    out += buf;
    for (double v : a.frames[f]) {
      std::snprintf(buf, sizeof buf, ",%.6g", v);
      out += buf;
    }
    out += "\n";
  }
  return out;
}

}  // namespace handskin
