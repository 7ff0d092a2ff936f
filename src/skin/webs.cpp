#include "skin/skin_steps.hpp"

#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "skin/principal_axes.hpp"
#include "skin/profile.hpp"

namespace handskin::skin_steps {

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
    std::vector<Eigen::Vector2d> near;
    for (const auto& p : q)
      if ((p - m0).head<2>().norm() < len + 5) near.emplace_back((p - m0).head<2>());
    double web = -1;
    for (double s = 0; s <= len; s += 0.5) {
      const Eigen::Vector2d c = s * dir.head<2>();
      bool any = false;
      for (const auto& p : near)
        if ((p - c).squaredNorm() < 1.5 * 1.5) {
          any = true;
          break;
        }
      if (any) web = s;
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
