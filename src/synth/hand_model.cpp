#include "synth/hand_model.hpp"

#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "core/hand_proportions.hpp"

namespace handskin {

using namespace proportions;

namespace {

constexpr double kDeg = M_PI / 180.0;

// Polynomial smooth minimum (Quilez): blends two fields over a band of width k (mm).
double smin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
double smax(double a, double b, double k) { return -smin(-a, -b, k); }

Eigen::Vector3d heading(double deg_in_plane, double deg_down = 0) {
  return {std::cos(deg_in_plane * kDeg) * std::cos(deg_down * kDeg),
          std::sin(deg_in_plane * kDeg) * std::cos(deg_down * kDeg), -std::sin(deg_down * kDeg)};
}

}  // namespace

bool HandShapeOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(hand_length_mm >= 120 && hand_length_mm <= 260)) return bad("hand_length_mm must be in [120, 260]");
  if (!(finger_spread_deg >= 0 && finger_spread_deg <= 15)) return bad("finger_spread_deg must be in [0, 15]");
  if (!(thickness_scale >= 0.7 && thickness_scale <= 1.4)) return bad("thickness_scale must be in [0.7, 1.4]");
  if (!(width_scale >= 0.7 && width_scale <= 1.4)) return bad("width_scale must be in [0.7, 1.4]");
  if (!(thumb_abduction_deg >= 20 && thumb_abduction_deg <= 70)) return bad("thumb_abduction_deg must be in [20, 70]");
  return true;
}

double Capsule::value(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  const double w = wa + t * (wb - wa), h = ha + t * (hb - ha);
  Eigen::Vector3d d = p - (a + t * ab);
  d.z() -= dz;
  // Elliptic section: stretch Z so the ellipse becomes a circle of radius w.
  const double dist = std::sqrt(d.x() * d.x() + d.y() * d.y() + (d.z() * w / h) * (d.z() * w / h));
  return dist - w;
}

double HandModel::value(const Eigen::Vector3d& p) const {
  if ((p.array() < box_min.array()).any() || (p.array() > box_max.array()).any()) {
    // Outside the box: a positive value that grows with distance keeps the mesher's oracle simple.
    const Eigen::Vector3d q = p.cwiseMax(box_min).cwiseMin(box_max);
    return 1.0 + (p - q).norm();
  }
  const double s = options.hand_length_mm / kNominalHandLength;
  double palm_v = 1e9;
  for (const Capsule& c : palm) palm_v = smin(palm_v, c.value(p), 12.0 * s);
  double v = palm_v;
  for (const auto& finger : fingers) {
    double f = 1e9;
    for (const Capsule& c : finger) f = smin(f, c.value(p), 2.5 * s);
    v = smin(v, f, 6.0 * s);
  }
  return smax(v, wrist_cut_x - p.x(), 1.5 * s);
}

HandModel build_hand_model(const HandShapeOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("hand options", err);
  HandModel m;
  m.options = o;
  const double s = o.hand_length_mm / kNominalHandLength;
  const double W = s * o.width_scale, H = s * o.thickness_scale;
  auto P = [&](double x, double y, double z) { return Eigen::Vector3d(x * s, y * s, z * s); };
  auto capsule = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, double wa, double wb, double ha, double hb,
                     double dz) { return Capsule{a, b, wa * W, wb * W, ha * H, hb * H, dz * H}; };

  Rig& rig = m.rig;
  rig.frame = "hand";
  rig.palm_normal = Eigen::Vector3d::UnitZ();
  rig.joints[0] = Eigen::Vector3d::Zero();

  m.fingers.resize(5);
  for (int fi = 0; fi < 5; ++fi) {
    const FingerSpec& f = kFingers[fi];
    const std::vector<int> chain = finger_chain(static_cast<Finger>(fi));
    const bool thumb = fi == 0;
    const Eigen::Vector3d cmc = P(f.cmc.x(), f.cmc.y(), thumb ? -6.0 : 0.0);
    const double mc_angle = thumb ? 10.0 + o.thumb_abduction_deg : f.angle_deg;
    // The thumb sits palmar of the hand plane and points a little down out of it.
    const Eigen::Vector3d mcp = cmc + f.metacarpal * s * heading(mc_angle, thumb ? 12.0 : 0.0);
    const double ph_angle = thumb ? mc_angle - 10.0 : f.angle_deg + f.spread_steps * o.finger_spread_deg;
    const Eigen::Vector3d dir = heading(ph_angle, thumb ? 4.0 : 0.0);
    std::vector<double> lengths = {f.proximal, f.middle, f.distal};
    if (thumb) lengths = {f.proximal, f.distal};
    std::vector<Eigen::Vector3d> js = {cmc, mcp};
    for (double L : lengths) js.push_back(js.back() + L * s * dir);
    for (size_t k = 0; k < chain.size(); ++k) rig.joints[chain[k]] = js[k];

    // Phalanges: width tapers toward the tip; sections flatten toward the tip.
    const double w0 = f.width;
    const std::vector<double> widths = thumb ? std::vector<double>{w0, 0.93 * w0, 0.80 * w0}
                                             : std::vector<double>{w0, 0.91 * w0, 0.84 * w0, 0.74 * w0};
    const std::vector<double> flat = thumb ? std::vector<double>{0.86, 0.82, 0.74}
                                           : std::vector<double>{0.90, 0.88, 0.84, 0.78};
    auto& caps = m.fingers[fi];
    for (size_t k = 1; k + 1 < js.size(); ++k) {
      Eigen::Vector3d a = js[k], b = js[k + 1];
      const double wa = widths[k - 1], wb = widths[k], ha = wa * flat[k - 1], hb = wb * flat[k];
      if (k + 2 == js.size()) b = b - (hb * H - kTipInset * s) * dir;  // round tip kTipInset beyond the joint
      caps.push_back(capsule(a, b, wa, wb, ha, hb, -0.8));
    }
    // Knuckle pads on the back over the MCP and PIP joints (the thumb: over its IP joint).
    for (size_t k : thumb ? std::vector<size_t>{2} : std::vector<size_t>{1, 2}) {
      const double r = widths[k - 1] * 0.55;
      const Eigen::Vector3d c = js[k] + Eigen::Vector3d(0, 0, 0.5 * widths[k - 1] * flat[k - 1] * H);
      caps.push_back(capsule(c - 0.5 * s * dir, c + 0.5 * s * dir, r, r, 0.9 * r, 0.9 * r, 0.0));
    }
    // Metacarpals build the palm (the thumb's builds the thenar eminence).
    if (thumb) {
      m.palm.push_back(capsule(cmc, mcp, 12.0, 11.0, 11.0, 10.0, -1.0));
    } else {
      const double hw = fi == 4 ? 10.0 : 10.5;
      m.palm.push_back(capsule(cmc, mcp, hw, hw, 13.0, 12.0, -3.0));
    }
  }
  // Carpus, forearm stub (cut flat), thenar and hypothenar eminences.
  m.palm.push_back(capsule(P(6, -12, -2), P(6, 12, -2), 15.0, 15.0, 13.5, 13.5, 0.0));
  m.palm.push_back(capsule(P(-45, 0, -1), P(4, 0, -1), 26.0, 25.0, 18.0, 16.0, 0.0));
  m.palm.push_back(capsule(P(14, 10, -7), P(44, 30, -9), 13.0, 11.0, 10.0, 9.0, 0.0));
  m.palm.push_back(capsule(P(22, -21, -6), P(62, -28, -5), 10.0, 9.0, 11.0, 10.0, 0.0));
  m.wrist_cut_x = -kWristCut * s;

  // Enclosing box: capsule extents plus margin.
  m.box_min = Eigen::Vector3d::Constant(1e9);
  m.box_max = Eigen::Vector3d::Constant(-1e9);
  auto grow = [&](const Capsule& c) {
    const double r = std::max({c.wa, c.wb, c.ha, c.hb}) + std::abs(c.dz) + 2.0;
    for (const auto& e : {c.a, c.b}) {
      m.box_min = m.box_min.cwiseMin((e.array() - r).matrix());
      m.box_max = m.box_max.cwiseMax((e.array() + r).matrix());
    }
  };
  for (const auto& c : m.palm) grow(c);
  for (const auto& f : m.fingers)
    for (const auto& c : f) grow(c);
  m.box_min.x() = std::max(m.box_min.x(), m.wrist_cut_x - 2.0);
  return m;
}

}  // namespace handskin
