#include "skin/skin_steps.hpp"

#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "skin/profile.hpp"

namespace handskin::skin_steps {

using profile::segment_distance2;

// Which tube a link's points go to: the carpus and the four metacarpals make the palm; the
// thumb's three links the thumb; the phalanges of a finger its tube.
int tube_of_bone(const Bone& b) {
  if (b.joint == 0) return static_cast<int>(SkinTube::Palm);
  for (int f = 0; f < kFingerCount; ++f) {
    const auto chain = finger_chain(static_cast<Finger>(f));
    if (std::find(chain.begin(), chain.end(), b.joint) == chain.end()) continue;
    if (f == 0) return static_cast<int>(SkinTube::Thumb);
    return b.joint == chain.front() ? static_cast<int>(SkinTube::Palm) : 1 + f;
  }
  return static_cast<int>(SkinTube::Palm);
}

HandFrame to_hand_frame(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const std::vector<Bone>& bones) {
  HandFrame H;
  H.T = hand_frame_from_rig(rig);
  const Eigen::Isometry3d& T = H.T;
  H.q.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) H.q[i] = T * points[i];
  for (int j = 0; j < kJointCount; ++j) H.J[j] = T * rig.joints[j];
  const size_t nb = bones.size();
  H.A.resize(nb), H.B.resize(nb), H.bone_tube.resize(nb);
  for (size_t b = 0; b < nb; ++b) H.A[b] = T * bones[b].a, H.B[b] = T * bones[b].b, H.bone_tube[b] = tube_of_bone(bones[b]);
  H.lo = H.q.front(), H.hi = H.q.front();
  for (const auto& p : H.q) H.lo = H.lo.cwiseMin(p), H.hi = H.hi.cwiseMax(p);
  std::vector<int> palm_joints = {0};
  for (int f = 0; f < kFingerCount; ++f) {
    const auto c = finger_chain(static_cast<Finger>(f));
    palm_joints.push_back(c[0]);
    palm_joints.push_back(c[1]);
  }
  for (int j : palm_joints)
    if (((H.J[j].array() < H.lo.array() - 15).any() || (H.J[j].array() > H.hi.array() + 15).any()))
      throw InputError("rig", std::string("joint '") + joints()[j].name +
                                  "' lies outside the merged cloud (more than 15 mm beyond its bounding box)");
  return H;
}

TubePoints assign_points(const HandFrame& H, double overlap) {
  const auto& q = H.q;
  const auto &A = H.A, &B = H.B;
  const auto& bone_tube = H.bone_tube;
  const Eigen::Vector3d &lo = H.lo, &hi = H.hi;
  const size_t nb = A.size();
  TubePoints P;
  P.tube.resize(kSkinTubes);
  auto& tube_pts = P.tube;
  auto& palm_pts = P.palm;
  // Thumb and palm share the points within thumb_overlap_mm of their boundary, so that both
  // tubes follow the thenar skin across it and the union leaves no groove there.
  constexpr int kThumb = static_cast<int>(SkinTube::Thumb);
  std::vector<std::uint8_t> label(q.size()), shared(q.size());
  // Candidate links per 4 mm cell. The distance to a segment changes by at most r, the cell's
  // half-diagonal, across the cell; so a link more than 2r + overlap farther from the cell's
  // centre than the nearest one can neither be a point's nearest nor matter to the shared
  // band. Only the candidates are measured (about a quarter of the links); results are those
  // of measuring every link, ties included (candidates keep the links' order).
  constexpr double kCell = 4.0;
  const double cell_r = 0.5 * std::sqrt(3.0) * kCell;
  const Eigen::Array3i cells = ((hi - lo) / kCell).array().floor().cast<int>() + 1;
  auto cell_of = [&](const Eigen::Vector3d& p) {
    const Eigen::Array3i c = ((p - lo) / kCell).array().floor().cast<int>().min(cells - 1).max(0);
    return (static_cast<size_t>(c.z()) * cells.y() + c.y()) * cells.x() + c.x();
  };
  std::vector<std::vector<std::uint8_t>> candidates(static_cast<size_t>(cells.prod()));
#pragma omp parallel for schedule(static)
  for (long c = 0; c < static_cast<long>(candidates.size()); ++c) {
    const long x = c % cells.x(), y = (c / cells.x()) % cells.y(), z = c / (cells.x() * cells.y());
    const Eigen::Vector3d centre = lo + kCell * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5);
    std::vector<double> d(nb);
    double dmin = 1e300;
    for (size_t b = 0; b < nb; ++b) dmin = std::min(dmin, d[b] = std::sqrt(segment_distance2(centre, A[b], B[b])));
    for (size_t b = 0; b < nb; ++b)
      if (d[b] <= dmin + 2 * cell_r + overlap) candidates[c].push_back(static_cast<std::uint8_t>(b));
  }
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(q.size()); ++i) {
    const Eigen::Vector3d& p = q[i];
    size_t best = 0;
    double bd = 1e300, best_thumb = 1e300, best_other = 1e300;
    for (const size_t b : candidates[cell_of(p)]) {
      const double d = segment_distance2(p, A[b], B[b]);
      if (d < bd) bd = d, best = b;
      double& group = bone_tube[b] == kThumb ? best_thumb : best_other;
      group = std::min(group, d);
    }
    label[i] = static_cast<std::uint8_t>(bone_tube[best]);
    const double dt = std::sqrt(best_thumb), dn = std::sqrt(best_other);
    shared[i] = label[i] == kThumb ? dn < dt + overlap : dt < dn + overlap;
  }
  // The palm's planes take the fingers' points too (the knuckles and the webs lie within the
  // palm's end), but not where a finger leaves the palm's thickness: a finger flexed at its MCP
  // rises (or drops) through the planes by the knuckles, and the palm tube's last rings, taking
  // it in, folded (a hand with its MCPs flexed 60 deg, on its own rig). The palm's thickness:
  // its own points' heights (z, toward the back), 1st to 99th percentile, kPalmBandMm either side.
  constexpr double kPalmBandMm = 2.0;
  constexpr int kPalm = static_cast<int>(SkinTube::Palm);
  double zlo = -1e300, zhi = 1e300;
  {
    std::vector<double> z;
    for (size_t i = 0; i < q.size(); ++i)
      if (label[i] == kPalm) z.push_back(q[i].z());
    if (z.size() >= 100) {
      const size_t k = z.size() / 100;
      std::nth_element(z.begin(), z.begin() + k, z.end());
      zlo = z[k] - kPalmBandMm;
      std::nth_element(z.begin(), z.end() - 1 - k, z.end());
      zhi = z[z.size() - 1 - k] + kPalmBandMm;
    }
  }
  for (size_t i = 0; i < q.size(); ++i) {
    tube_pts[label[i]].push_back(q[i]);
    const bool finger = label[i] != kThumb && label[i] != kPalm;
    if (finger && (q[i].z() < zlo || q[i].z() > zhi)) continue;
    if (label[i] != kThumb || shared[i]) palm_pts.push_back(q[i]);
    if (label[i] != kThumb && shared[i]) tube_pts[kThumb].push_back(q[i]);
  }
  return P;
}

}  // namespace handskin::skin_steps
