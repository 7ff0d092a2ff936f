#include "rigging/binding.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/dof.hpp"
#include "core/errors.hpp"

// Why by hand: bone heat is one sparse solve per link with the cotangent Laplacian. libigl
// (not packaged in Debian) has it; CGAL has no skinning weights; the Laplacian is a dozen
// lines over the mesh's faces, and Eigen's sparse Cholesky does the solves.

namespace handskin {

bool BindingOptions::IsValid(std::string* error) const {
  if (mode != "smooth" && mode != "rigid") return invalid(error, "binding mode must be 'smooth' or 'rigid'");
  if (!(heat > 0 && heat <= 1e3)) return invalid(error, "heat must be in (0, 1e3]");
  if (!(min_weight >= 0 && min_weight < 0.25)) return invalid(error, "min_weight must be in [0, 0.25)");
  return true;
}

int link_joint(int link) { return joints()[link + 1].parent; }

VertexWeights top_weights(std::vector<std::pair<double, int>> w, double min_weight) {
  std::sort(w.begin(), w.end(), [](const auto& a, const auto& b) { return a.first > b.first || (a.first == b.first && a.second < b.second); });
  VertexWeights out;
  double sum = 0;
  int n = 0;
  for (const auto& [v, l] : w) {
    if (n == kMaxInfluences || (n > 0 && v < min_weight)) break;
    out.link[n] = l;
    out.weight[n] = static_cast<float>(std::max(v, 0.0));
    sum += out.weight[n];
    ++n;
  }
  if (!(sum > 0)) {  // nothing reached this vertex: its nearest link alone
    out.weight = {1, 0, 0, 0};
    for (int k = 1; k < kMaxInfluences; ++k) out.link[k] = -1;
    return out;
  }
  for (int k = 0; k < n; ++k) out.weight[k] = static_cast<float>(out.weight[k] / sum);
  return out;
}

SkinBinding bind_skin(const Mesh& mesh, const std::vector<Bone>& bones, const BindingOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("binding options", err);
  if (mesh.n_vertices() == 0) throw InputError("skin", "no vertices to bind");
  if (bones.empty()) throw InputError("rig", "no bone links to bind the skin to");
  const auto t0 = std::chrono::steady_clock::now();
  const int n = static_cast<int>(mesh.n_vertices()), nb = static_cast<int>(bones.size());
  SkinBinding B;
  B.mode = o.mode;
  const std::vector<Eigen::Vector3d>& x = mesh.vertices;
  std::vector<int> nearest(static_cast<size_t>(n));
  std::vector<double> dist(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    double best = 1e300;
    for (int k = 0; k < nb; ++k) {
      const double d = distance_to_bone(x[i], bones[k]);
      if (d < best) best = d, nearest[i] = k;
    }
    dist[i] = std::max(best, 1e-3);
  }
  if (o.mode == "rigid") {
    for (int i = 0; i < n; ++i) {
      VertexWeights w;
      w.link[0] = nearest[i];
      w.weight[0] = 1;
      B.vertices.push_back(w);
    }
  } else {
    // Cotangent Laplacian (cotangents clamped at 0: obtuse angles would give negative
    // weights and break the discrete maximum principle that keeps weights in [0, 1]) and
    // lumped areas (a third of each adjacent triangle).
    std::vector<Eigen::Triplet<double>> tl;
    std::vector<double> area(static_cast<size_t>(n), 0.0);
    for (const std::array<int, 3>& id : mesh.faces) {
      const double a2 = (x[id[1]] - x[id[0]]).cross(x[id[2]] - x[id[0]]).norm();
      if (!(a2 > 1e-12)) continue;
      for (int c = 0; c < 3; ++c) area[id[c]] += a2 / 6;
      for (int c = 0; c < 3; ++c) {
        const int i = id[(c + 1) % 3], j = id[(c + 2) % 3];
        const Eigen::Vector3d e1 = x[i] - x[id[c]], e2 = x[j] - x[id[c]];
        const double cot = std::max(0.0, e1.dot(e2) / e1.cross(e2).norm());
        const double w = 0.5 * cot;
        tl.emplace_back(i, j, -w);
        tl.emplace_back(j, i, -w);
        tl.emplace_back(i, i, w);
        tl.emplace_back(j, j, w);
      }
    }
    std::vector<double> mh(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      mh[i] = std::max(area[i], 1e-9) * o.heat / (dist[i] * dist[i]);
      tl.emplace_back(i, i, mh[i]);
    }
    Eigen::SparseMatrix<double> A(n, n);
    A.setFromTriplets(tl.begin(), tl.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
    HS_CHECK(solver.info() == Eigen::Success, "bone heat: the system did not factor");
    std::vector<std::vector<std::pair<double, int>>> per_vertex(static_cast<size_t>(n));
    Eigen::VectorXd rhs(n);
    for (int k = 0; k < nb; ++k) {
      for (int i = 0; i < n; ++i) rhs(i) = nearest[i] == k ? mh[i] : 0.0;
      if (rhs.isZero()) continue;
      const Eigen::VectorXd w = solver.solve(rhs);
      for (int i = 0; i < n; ++i)
        if (w(i) > 1e-6) per_vertex[i].emplace_back(w(i), k);
    }
    for (int i = 0; i < n; ++i) {
      VertexWeights w = top_weights(per_vertex[i], o.min_weight);
      if (w.link[0] < 0) w.link[0] = nearest[i];
      B.vertices.push_back(w);
    }
  }
  B.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return B;
}

}  // namespace handskin
