#include "synth/albedo.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "core/dof.hpp"

namespace handskin {

namespace {

double smoothstep(double a, double b, double x) {
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// Value noise on a 3D lattice: a hash per lattice point, smoothly interpolated (0..1).
double lattice(int x, int y, int z) {
  std::uint64_t h = static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15ull ^
                    static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4Full ^
                    static_cast<std::uint64_t>(z) * 0x165667B19E3779F9ull;
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 29;
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}
double value_noise(const Eigen::Vector3d& q) {
  const Eigen::Vector3d f = q.array().floor();
  const int x = static_cast<int>(f.x()), y = static_cast<int>(f.y()), z = static_cast<int>(f.z());
  const Eigen::Vector3d t = (q - f).unaryExpr([](double u) { return u * u * (3 - 2 * u); });
  double v = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    v += (dx ? t.x() : 1 - t.x()) * (dy ? t.y() : 1 - t.y()) * (dz ? t.z() : 1 - t.z()) * lattice(x + dx, y + dy, z + dz);
  }
  return v;
}

double distance_to_polyline(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& line) {
  double best = 1e18;
  for (size_t k = 0; k + 1 < line.size(); ++k) {
    const Eigen::Vector2d d = line[k + 1] - line[k];
    const double t = std::clamp((p - line[k]).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (p - line[k] - t * d).norm());
  }
  return best;
}

// A quadratic Bézier from a through b (control) to c, as a polyline of 16 pieces.
std::vector<Eigen::Vector2d> curve(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  std::vector<Eigen::Vector2d> out;
  for (int k = 0; k <= 16; ++k) {
    const double t = k / 16.0;
    const Eigen::Vector3d q = (1 - t) * (1 - t) * a + 2 * t * (1 - t) * b + t * t * c;
    out.emplace_back(q.x(), q.y());
  }
  return out;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

}  // namespace

SkinAlbedo::SkinAlbedo(const Rig& rig_hand) : rig_(rig_hand), bones_(bones_from_rig(rig_hand)) {
  const auto J = [&](const char* n) { return rig_.joints[joint_index(n).value()]; };
  const Eigen::Vector3d W = J("wrist"), mi = J("index-finger-phalanx-proximal"), mm = J("middle-finger-phalanx-proximal"),
                        mr = J("ring-finger-phalanx-proximal"), ml = J("pinky-finger-phalanx-proximal"),
                        tc = J("thumb-metacarpal"), tm = J("thumb-phalanx-proximal");
  const double L = (mm - W).norm();  // palm length
  const Eigen::Vector3d toward_wrist = (W - mm).normalized();
  const Eigen::Vector3d radial = (mi - ml).normalized();  // from the little finger toward the index
  // Distal transverse crease: from the ulnar edge ~0.17 L proximal of the little MCP, curving to
  // the web between index and middle finger.
  palm_creases_.push_back({curve(ml + 0.17 * L * toward_wrist - 0.35 * (mi - ml).norm() * radial,
                                 mr + 0.20 * L * toward_wrist, 0.5 * (mi + mm) + 0.05 * L * toward_wrist),
                           0.55, 0.30});
  // Proximal transverse crease: from the radial edge above the thumb obliquely across the palm.
  const Eigen::Vector3d radial_start = mi + 0.22 * L * toward_wrist + 0.15 * (mi - ml).norm() * radial;
  palm_creases_.push_back({curve(radial_start, mm + 0.30 * L * toward_wrist, mr + 0.42 * L * toward_wrist - 0.2 * (mr - ml).norm() * radial),
                           0.5, 0.26});
  // Thenar crease: from the same radial start, round the ball of the thumb to the wrist.
  palm_creases_.push_back({curve(radial_start, 0.5 * (tc + tm) + 0.35 * (mm - 0.5 * (tc + tm)), W + 0.08 * L * (-toward_wrist)),
                           0.55, 0.28});
}

Eigen::Vector3f SkinAlbedo::colour(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const {
  // The nearest link tells palm, finger or thumb, and which way is dorsal there.
  const Bone* bone = &bones_.front();
  double best = 1e18;
  for (const auto& b : bones_) {
    const double d = distance_to_bone(p, b);
    if (d < best) best = d, bone = &b;
  }
  const std::string name = joints()[bone->joint].name;
  const bool digit = name.find("phalanx") != std::string::npos;
  const bool thumb = name.rfind("thumb", 0) == 0;
  const Eigen::Vector3d a = (bone->b - bone->a).normalized();
  Eigen::Vector3d dorsal;
  if (thumb) {
    dorsal = Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ().dot(a) * a;
  } else {
    const Eigen::Vector3d lateral = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(a) * a;
    dorsal = a.cross(lateral);
  }
  dorsal = dorsal.squaredNorm() > 1e-12 ? dorsal.normalized() : Eigen::Vector3d::UnitZ();
  const double t_len = (bone->b - bone->a).norm();
  const double s = (p - bone->a).dot(a);  // along the link from its base, mm
  Eigen::Vector3d radial = p - (bone->a + std::clamp(s, 0.0, t_len) * a);
  radial = radial.squaredNorm() > 1e-12 ? radial.normalized() : n;
  const double up = digit ? radial.dot(dorsal) : n.z();  // +1 on the back, −1 on the palm

  const Eigen::Vector3d back_tone(0.84, 0.64, 0.53), palm_tone(0.91, 0.71, 0.63);
  const double w_back = smoothstep(-0.35, 0.35, up);
  Eigen::Vector3d c = w_back * back_tone + (1 - w_back) * palm_tone;
  // Mottle (±3 % luminance) and a redder tone on the palmar finger pads
  c *= 0.97 + 0.06 * value_noise(p / 6.0);
  // (faded in along the proximal phalanx, so that the palm's tone meets it without an edge).
  if (digit && up < 0) {
    const double pad = smoothstep(0.0, 0.8, -up) * (ends_with(name, "phalanx-proximal") ? smoothstep(0.0, 0.6, s / t_len) : 1.0);
    c.y() *= 1.0 - 0.05 * pad, c.z() *= 1.0 - 0.04 * pad;
  }

  double dark = 0;  // crease darkening, 0..1
  const auto line_at = [&](double dist, double width, double depth) { return depth * std::exp(-(dist * dist) / (width * width)); };
  if (!digit && up < 0.2) {
    const Eigen::Vector2d q(p.x(), p.y());
    const double palmar = smoothstep(0.2, -0.4, up);
    for (const auto& cr : palm_creases_) dark = std::max(dark, palmar * line_at(distance_to_polyline(q, cr.line), cr.width, cr.depth));
  }
  if (digit) {
    // Palmar creases at the base of this link's joint (PIP, DIP, IP: a pair 1.2 mm apart) and
    // across the proximal phalanx's base; dorsal wrinkles over the PIPs.
    const double palmar = smoothstep(-0.2, -0.6, up), dorsal_side = smoothstep(0.4, 0.8, up);
    const bool proximal = ends_with(name, "phalanx-proximal");
    if (!proximal) {
      for (double off : {-0.6, 0.6}) dark = std::max(dark, palmar * line_at(s - off, 0.35, 0.28));
      if (ends_with(name, "phalanx-intermediate"))
        for (double off : {-1.6, 0.0, 1.6}) dark = std::max(dark, dorsal_side * line_at(s - off, 0.35, 0.10));
    } else if (!thumb) {
      dark = std::max(dark, palmar * line_at(s - 0.35 * t_len, 0.4, 0.25));
    }
  }
  c *= 1.0 - dark;

  // Nails: the dorsal side of the distal phalanx, from 35 % of its length to the tip.
  if (ends_with(name, "phalanx-distal")) {
    const double tt = s / std::max(t_len, 1e-9);
    const double across = smoothstep(0.45, 0.62, radial.dot(dorsal));
    const double along = smoothstep(0.30, 0.40, tt);
    const double nail = across * along;
    if (nail > 0) {
      Eigen::Vector3d nail_c(0.92, 0.74, 0.72);
      nail_c = (1 - smoothstep(0.86, 0.93, tt)) * nail_c + smoothstep(0.86, 0.93, tt) * Eigen::Vector3d(0.96, 0.92, 0.88);
      nail_c = (1 - smoothstep(0.45, 0.38, tt)) * nail_c + smoothstep(0.45, 0.38, tt) * Eigen::Vector3d(0.95, 0.85, 0.82);
      c = (1 - nail) * c + nail * nail_c;
    }
  }
  return c.cwiseMax(0.0).cwiseMin(1.0).cast<float>();
}

}  // namespace handskin
