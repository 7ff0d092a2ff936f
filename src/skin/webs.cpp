#include "skin/skin_steps.hpp"

#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "skin/principal_axes.hpp"
#include "skin/profile.hpp"

namespace handskin::skin_steps {

namespace {
// The strip across the mid-line between two fingers in which the web is looked for (half
// width), and the widest gap across it that the web's skin leaves in the samples.
constexpr double kWebStripMm = 4.0;
constexpr double kWebGapMm = 2.0;
}  // namespace

Webs find_webs(const HandFrame& H, double h) {
  const auto& q = H.q;
  const auto& J = H.J;
  const double x0 = H.lo.x();
  Webs W;
  // Along the mid-line between neighbouring fingers, where the skin ends.
  for (int f = 1; f + 1 < kFingerCount; ++f) {
    const auto c1 = finger_chain(static_cast<Finger>(f)), c2 = finger_chain(static_cast<Finger>(f + 1));
    const Eigen::Vector3d m0 = 0.5 * (J[c1[1]] + J[c2[1]]);
    Eigen::Vector3d dir = (J[c1[2]] - J[c1[1]]).normalized() + (J[c2[2]] - J[c2[1]]).normalized();
    dir.z() = 0;
    dir.normalize();
    const double len = 0.5 * ((J[c1[2]] - J[c1[1]]).norm() + (J[c2[2]] - J[c2[1]]).norm());
    // Points near the mid-line as (along, across) it. The skin holds the two fingers together
    // at s while the points in a thin strip across the mid-line there leave no gap wider than
    // kWebGapMm across it: the web's skin crosses the line, seen from the back or the palm
    // (its groove's steep walls leave gaps of ~1.5 mm); past the web the gap between the two
    // fingers' sides opens (2.5 mm and more in the samples, the flanks being unseen). A point
    // within 1.5 mm of the line, the test before, took fingers 3 mm apart for a web and ended
    // the palm up to 10 mm beyond it, bridging the gaps between the fingers' roots.
    const Eigen::Vector2d along = dir.head<2>(), across(-along.y(), along.x());
    std::vector<Eigen::Vector2d> near;
    for (const auto& p : q) {
      const Eigen::Vector2d d = (p - m0).head<2>();
      const double a = d.dot(along), c = d.dot(across);
      if (a > -1 && a < len + 1 && std::abs(c) < kWebStripMm) near.emplace_back(a, c);
    }
    std::sort(near.begin(), near.end(), [](const auto& x, const auto& y) { return x.x() < y.x(); });
    double web = -1;
    std::vector<double> lateral;
    for (double s = 0; s <= len; s += 0.5) {
      lateral.clear();
      for (auto it = std::lower_bound(near.begin(), near.end(), s - 0.75,
                                      [](const Eigen::Vector2d& p, double v) { return p.x() < v; });
           it != near.end() && it->x() <= s + 0.75; ++it)
        lateral.push_back(it->y());
      std::sort(lateral.begin(), lateral.end());
      // Joined: samples on both sides of the line, and no gap wider than kWebGapMm anywhere
      // across the strip.
      bool joined = lateral.size() >= 4 && lateral.front() < 0 && lateral.back() > 0;
      for (size_t i = 1; joined && i < lateral.size(); ++i)
        if (lateral[i] - lateral[i - 1] > kWebGapMm) joined = false;
      if (joined) web = s;
      else if (s - web > 2.0) break;
    }
    if (web < 0) {
      W.warnings.push_back(std::string("no skin found between the ") + skin_tube_name(f + 1) + " and " +
                           skin_tube_name(f + 2) + " finger roots; the web is put at the knuckles");
      web = 0;
    } else if (web >= len) {
      W.warnings.push_back(std::string("the ") + skin_tube_name(f + 1) + " and " + skin_tube_name(f + 2) +
                           " fingers touch along their whole proximal phalanx; the web is put at the middle joints");
    }
    W.points.push_back(m0 + web * dir);
  }
  // The palm's end plane: vertical, through the webs' line, moved back to the most proximal web.
  std::vector<Eigen::Vector2d> web_xy;
  for (const auto& w : W.points) web_xy.push_back(w.head<2>());
  Eigen::Matrix2d web_axes;
  Eigen::Vector2d wc;
  principal_axes<2>(web_xy, &web_axes, &wc);
  Eigen::Vector2d nend(web_axes(1, 0), -web_axes(0, 0));
  if (nend.x() < 0) nend = -nend;
  double alpha_end = std::atan2(nend.y(), nend.x());
  alpha_end = std::clamp(alpha_end, -35 * kDeg, 35 * kDeg);
  nend = Eigen::Vector2d(std::cos(alpha_end), std::sin(alpha_end));
  double back = 0;
  for (const auto& w : W.points) back = std::min(back, nend.dot(w.head<2>() - wc));
  const Eigen::Vector2d end_point = wc + (back - 0.5) * nend;
  const double x_end = end_point.x();  // where the end plane crosses the line y = wc.y
  if (x_end - x0 < 5 * h) throw InputError("rig", "the finger webs lie at the wrist end of the cloud; the rig does not fit it");
  W.centre = wc;
  W.alpha_end = alpha_end;
  W.x_end = x_end;
  return W;
}

}  // namespace handskin::skin_steps
