#include "rigging/deform.hpp"

#include "core/dof.hpp"
#include "core/errors.hpp"

namespace handskin {

std::vector<Eigen::Isometry3d> link_motions(const Skeleton& skeleton, const Angles& angles) {
  const auto frames = skeleton.frames(angles);
  std::vector<Eigen::Isometry3d> out;
  out.reserve(kJointCount - 1);
  for (int k = 0; k + 1 < kJointCount; ++k) {
    const int j = link_joint(k);
    out.push_back(frames[j] * skeleton.rest_frame(j).inverse());
  }
  return out;
}

Blend parse_blend(const std::string& name, const std::string& where) {
  if (name == "lbs") return Blend::Linear;
  if (name == "dqs") return Blend::DualQuaternion;
  throw InputError(where, "'" + name + "': the blending must be lbs or dqs");
}

namespace {

struct DualQuat {
  Eigen::Quaterniond r, d;  // real (rotation) and dual (½ t r) parts
};

DualQuat to_dual(const Eigen::Isometry3d& T) {
  DualQuat q;
  q.r = Eigen::Quaterniond(T.linear());
  q.r.normalize();
  const Eigen::Vector3d t = T.translation();
  const Eigen::Quaterniond tq(0, t.x(), t.y(), t.z());
  const Eigen::Quaterniond d = tq * q.r;
  q.d = Eigen::Quaterniond(0.5 * d.w(), 0.5 * d.x(), 0.5 * d.y(), 0.5 * d.z());
  return q;
}

}  // namespace

void deform_into(const std::vector<Eigen::Vector3d>& rest, const SkinBinding& binding,
                 const std::vector<Eigen::Isometry3d>& motions, Blend blend, std::vector<Eigen::Vector3d>* out) {
  HS_CHECK(rest.size() == binding.vertices.size(), "binding and mesh differ in size");
  out->resize(rest.size());
  if (blend == Blend::Linear) {
    for (size_t i = 0; i < rest.size(); ++i) {
      const VertexWeights& w = binding.vertices[i];
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      double sum = 0;  // weights are floats: their sum is 1 to 1e-7, which is 1e-5 mm at 100 mm
      for (int k = 0; k < kMaxInfluences && w.link[k] >= 0; ++k) {
        p += w.weight[k] * (motions[w.link[k]] * rest[i]);
        sum += w.weight[k];
      }
      (*out)[i] = p / sum;
    }
    return;
  }
  std::vector<DualQuat> dq;
  dq.reserve(motions.size());
  for (const auto& m : motions) dq.push_back(to_dual(m));
  for (size_t i = 0; i < rest.size(); ++i) {
    const VertexWeights& w = binding.vertices[i];
    Eigen::Vector4d r = Eigen::Vector4d::Zero(), d = Eigen::Vector4d::Zero();
    const Eigen::Quaterniond& pivot = dq[w.link[0]].r;
    for (int k = 0; k < kMaxInfluences && w.link[k] >= 0; ++k) {
      const DualQuat& q = dq[w.link[k]];
      // Shortest path: quaternions on the pivot's hemisphere.
      const double s = (q.r.coeffs().dot(pivot.coeffs()) < 0 ? -1.0 : 1.0) * w.weight[k];
      r += s * q.r.coeffs();
      d += s * q.d.coeffs();
    }
    const double len = r.norm();
    r /= len;
    d /= len;
    const Eigen::Quaterniond R(r(3), r(0), r(1), r(2)), D(d(3), d(0), d(1), d(2));
    // t = 2 d r*
    const Eigen::Quaterniond t = D * R.conjugate();
    (*out)[i] = R * rest[i] + 2 * Eigen::Vector3d(t.x(), t.y(), t.z());
  }
}

std::vector<Eigen::Vector3d> deform(const std::vector<Eigen::Vector3d>& rest, const SkinBinding& binding,
                                    const std::vector<Eigen::Isometry3d>& motions, Blend blend) {
  std::vector<Eigen::Vector3d> out;
  deform_into(rest, binding, motions, blend, &out);
  return out;
}

}  // namespace handskin
