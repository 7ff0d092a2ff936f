#include "patches/patches.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/errors.hpp"
#include "mesh/point_grid.hpp"

namespace handskin {

namespace {

void bernstein(double t, double B[4], double D[4]) {
  const double s = 1 - t;
  B[0] = s * s * s, B[1] = 3 * t * s * s, B[2] = 3 * t * t * s, B[3] = t * t * t;
  if (D) D[0] = -3 * s * s, D[1] = 3 * s * s - 6 * t * s, D[2] = 6 * t * s - 3 * t * t, D[3] = 3 * t * t;
}

// Patch (a, b) and local (s, t) of (u, v): u wraps around the tube, v is clamped to [0, nv].
void locate(int nu, int nv, double u, double v, int* a, int* b, double* s, double* t) {
  u = std::fmod(u, static_cast<double>(nu));
  if (u < 0) u += nu;
  v = std::clamp(v, 0.0, static_cast<double>(nv));
  *a = std::min(static_cast<int>(u), nu - 1);
  *b = std::min(static_cast<int>(v), nv - 1);
  *s = u - *a;
  *t = v - *b;
}

int net_index(int NU, int NV, int i, int j) { return ((i % NU + NU) % NU) * NV + j; }

// Patch (a, b) of a tube: its 4 × 4 block of the net, with each point's link.
BezierPatch patch_of(const TubeSurface& T, int a, int b) {
  const int NU = 3 * T.nu, NV = 3 * T.nv + 1;
  BezierPatch P;
  P.tube = T.tube, P.span_u = a, P.span_v = b;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const int k = net_index(NU, NV, 3 * a + i, 3 * b + j);
      P.P[4 * i + j] = T.net[k];
      P.cp_link[4 * i + j] = T.net_link.empty() ? -1 : T.net_link[k];
    }
  return P;
}

int nearest_link(const Eigen::Vector3d& p, const std::vector<Bone>& bones) {
  int best = -1;
  double bd = 1e300;
  for (size_t k = 0; k < bones.size(); ++k) {
    const double d = distance_to_bone(p, bones[k]);
    if (d < bd) bd = d, best = static_cast<int>(k);
  }
  return best;
}

struct Datum {
  Eigen::Vector3d p;
  double u = 0, v = 0, w = 1;
  int side = -1;  ///< 0 palm, 1 back; -1 a ring point (weak data, parameters fixed)
};

// Least squares for the tube's net (eq. 4.5): data, C1 across borders, fairness. The normal
// equations are assembled from per-patch blocks into a sparse matrix.
void fit_net(TubeSurface* T, const std::vector<Datum>& data, const PatchOptions& o) {
  const int NU = 3 * T->nu, NV = 3 * T->nv + 1;
  // Unknowns: one per net point, except that a closed end's row is one point.
  std::vector<int> unknown(static_cast<size_t>(NU) * NV);
  int n = 0;
  for (int i = 0; i < NU; ++i)
    for (int j = 0; j < NV; ++j) {
      const bool tied = (j == 0 && T->closed_start) || (j == NV - 1 && T->closed_end);
      unknown[net_index(NU, NV, i, j)] = tied && i > 0 ? unknown[net_index(NU, NV, 0, j)] : n++;
    }
  auto id = [&](int i, int j) { return unknown[net_index(NU, NV, i, j)]; };
  // Each patch's 16 × 16 block of the normal equations is one product C·Cᵀ of its data's
  // basis values (columns scaled by √w), then scattered into the tube's matrix once.
  const int patches = T->nu * T->nv;
  std::vector<std::vector<int>> of_patch(patches);
  std::vector<Eigen::Matrix<double, 16, 1>> basis(data.size());
  double wsum = 0;
  for (size_t k = 0; k < data.size(); ++k) {
    const Datum& d = data[k];
    int a, b;
    double s, t, Bu[4], Bv[4];
    locate(T->nu, T->nv, d.u, d.v, &a, &b, &s, &t);
    bernstein(s, Bu, nullptr);
    bernstein(t, Bv, nullptr);
    const double sw = std::sqrt(d.w);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) basis[k](4 * i + j) = sw * Bu[i] * Bv[j];
    of_patch[a * T->nv + b].push_back(static_cast<int>(k));
    wsum += d.w;
  }
  std::vector<Eigen::Matrix<double, 16, 16>> block(patches);
  std::vector<Eigen::Matrix<double, 16, 3>> rhs(patches);
#pragma omp parallel for schedule(dynamic) if (patches > 8)
  for (int k = 0; k < patches; ++k) {
    const std::vector<int>& ids = of_patch[k];
    Eigen::Matrix<double, 16, Eigen::Dynamic> C(16, ids.size());
    Eigen::Matrix<double, Eigen::Dynamic, 3> Y(ids.size(), 3);
    for (size_t q = 0; q < ids.size(); ++q) {
      C.col(q) = basis[ids[q]];
      Y.row(q) = std::sqrt(data[ids[q]].w) * data[ids[q]].p.transpose();
    }
    block[k].noalias() = C * C.transpose();
    rhs[k].noalias() = C * Y;
  }
  std::vector<Eigen::Triplet<double>> A;
  A.reserve(static_cast<size_t>(patches) * 256 + unknown.size() * 18);
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(n, 3);
  for (int a = 0; a < T->nu; ++a)
    for (int b = 0; b < T->nv; ++b) {
      int idx[16];
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) idx[4 * i + j] = id(3 * a + i, 3 * b + j);
      const int k = a * T->nv + b;
      for (int x = 0; x < 16; ++x) {
        for (int y = 0; y < 16; ++y) A.emplace_back(idx[x], idx[y], block[k](x, y));
        R.row(idx[x]) += rhs[k].row(x);
      }
    }
  // Second differences of the net (fairness everywhere, C1 at the borders): rows e_a − 2e_b + e_c.
  const double per_point = wsum / n;
  auto triple = [&](int i0, int i1, int i2, double w) {
    const int id[3] = {i0, i1, i2};
    const double c[3] = {1, -2, 1};
    for (int x = 0; x < 3; ++x)
      for (int y = 0; y < 3; ++y) A.emplace_back(id[x], id[y], w * c[x] * c[y]);
  };
  for (int i = 0; i < NU; ++i)
    for (int j = 0; j < NV; ++j) {
      const bool border_u = i % 3 == 0, border_v = j % 3 == 0 && j > 0 && j < NV - 1;
      triple(id(i - 1, j), id(i, j), id(i + 1, j), per_point * (o.fairness + (border_u ? o.c1_weight : 0)));
      if (j > 0 && j < NV - 1)
        triple(id(i, j - 1), id(i, j), id(i, j + 1), per_point * (o.fairness + (border_v ? o.c1_weight : 0)));
    }
  // The normal matrix is banded (each net point couples with its patches' 4 × 4 blocks):
  // sparse Cholesky (LDLᵀ), never an inverse.
  Eigen::SparseMatrix<double> As(n, n);
  As.setFromTriplets(A.begin(), A.end());  // duplicates are summed
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(As);
  HS_CHECK(ldlt.info() == Eigen::Success, "patch fit: the normal equations could not be factored");
  const Eigen::MatrixXd X = ldlt.solve(R);
  T->net.resize(unknown.size());
  for (size_t k = 0; k < unknown.size(); ++k) T->net[k] = X.row(unknown[k]).transpose();
}

// Newton (Gauss–Newton) foot point of d.p on the surface from (d.u, d.v), at most `iterations`
// steps; returns how far the parameters moved (in spans).
double foot_point(const TubeSurface& T, Datum* d, int iterations, double* residual2 = nullptr) {
  double moved = 0;
  for (int it = 0; it < iterations; ++it) {
    Eigen::Vector3d S, Su, Sv;
    T.derivatives(d->u, d->v, &S, &Su, &Sv);
    const Eigen::Vector3d r = d->p - S;
    if (residual2) *residual2 = r.squaredNorm();  // at the parameters before this step
    Eigen::Matrix2d J;
    J << Su.dot(Su), Su.dot(Sv), Su.dot(Sv), Sv.dot(Sv);
    const Eigen::Vector2d g(Su.dot(r), Sv.dot(r));
    if (std::abs(J.determinant()) < 1e-12) break;
    Eigen::Vector2d step = J.ldlt().solve(g);
    const double len = step.norm();
    if (len > 0.5) step *= 0.5 / len;  // at most half a span per step
    const double v0 = d->v;
    d->u += step(0);
    d->v = std::clamp(d->v + step(1), 0.0, static_cast<double>(T.nv));
    moved += std::hypot(step(0), d->v - v0);
    if (step.norm() < 1e-7) break;
  }
  return moved;
}

DistanceFigures figures_of(std::vector<double> r) {
  DistanceFigures f;
  f.points = r.size();
  if (r.empty()) return f;
  double s = 0, s2 = 0;
  for (double x : r) s += x, s2 += x * x, f.max = std::max(f.max, x);
  f.mean = s / r.size();
  f.rms = std::sqrt(s2 / r.size());
  const size_t k = static_cast<size_t>(0.95 * (r.size() - 1));
  std::nth_element(r.begin(), r.begin() + k, r.end());
  f.p95 = r[k];
  return f;
}

}  // namespace

bool PatchOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (palm_around < 3 || palm_around > 64 || digit_around < 3 || digit_around > 64)
    return bad("patches around a tube must be in [3, 64]");
  if (palm_along < 1 || palm_along > 64 || digit_along < 1 || digit_along > 64)
    return bad("patches along a tube must be in [1, 64]");
  if (!(fairness >= 0 && fairness <= 10)) return bad("fairness must be in [0, 10]");
  if (!(c1_weight >= 0 && c1_weight <= 1e4)) return bad("c1_weight must be in [0, 1e4]");
  if (!(ring_weight > 0 && ring_weight <= 10)) return bad("ring_weight must be in (0, 10]");
  if (max_corrections < 0 || max_corrections > 100) return bad("max_corrections must be in [0, 100]");
  if (!(correction_tolerance > 0)) return bad("correction_tolerance must be > 0");
  if (tessellation < 1 || tessellation > 64) return bad("tessellation must be in [1, 64]");
  for (const auto& [tube, sp] : tube_spans) {
    if (tube < 0 || tube >= kSkinTubes) return bad("a layout names an unknown tube");
    if (sp[0] < 3 || sp[0] > 64 || sp[1] < 1 || sp[1] > 64)
      return bad(std::string("layout of the ") + skin_tube_name(tube) + " tube: around must be in [3, 64], along in [1, 64]");
  }
  return true;
}

std::map<int, std::array<int, 2>> parse_patch_layout(const Json& j, const std::string& file) {
  const std::string format = get_string(j, "format", file);
  if (format != "handskin-patches/1" && format != "handskin-patch-layout/1")
    throw InputError(file, "key 'format' must be \"handskin-patches/1\" or \"handskin-patch-layout/1\" (got \"" + format + "\")");
  const Json& tubes = require(j, "tubes", file);
  if (!tubes.is_array() || tubes.empty()) throw InputError(file, "key 'tubes' must be a non-empty array");
  std::map<int, std::array<int, 2>> out;
  for (size_t k = 0; k < tubes.size(); ++k) {
    const std::string where = file + ": tubes[" + std::to_string(k) + "]";
    if (!tubes[k].is_object()) throw InputError(where, "must be an object");
    const std::string name = get_string(tubes[k], "tube", where);
    int tube = -1;
    for (int t = 0; t < kSkinTubes; ++t)
      if (name == skin_tube_name(t)) tube = t;
    if (tube < 0) throw InputError(where, "unknown tube '" + name + "' (palm, thumb, index, middle, ring, little)");
    if (out.count(tube)) throw InputError(where, "tube '" + name + "' given twice");
    out[tube] = {static_cast<int>(get_int(tubes[k], "around", where, 3, 64)), static_cast<int>(get_int(tubes[k], "along", where, 1, 64))};
  }
  return out;
}

Eigen::Vector3d BezierPatch::eval(double u, double v) const {
  double Bu[4], Bv[4];
  bernstein(u, Bu, nullptr);
  bernstein(v, Bv, nullptr);
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) s += Bu[i] * Bv[j] * P[4 * i + j];
  return s;
}

const Eigen::Vector3d& TubeSurface::net_at(int i, int j) const { return net[net_index(3 * nu, 3 * nv + 1, i, j)]; }

void TubeSurface::derivatives(double u, double v, Eigen::Vector3d* S, Eigen::Vector3d* Su, Eigen::Vector3d* Sv) const {
  int a, b;
  double s, t, Bu[4], Du[4], Bv[4], Dv[4];
  locate(nu, nv, u, v, &a, &b, &s, &t);
  bernstein(s, Bu, Du);
  bernstein(t, Bv, Dv);
  *S = *Su = *Sv = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const Eigen::Vector3d& p = net_at(3 * a + i, 3 * b + j);
      *S += Bu[i] * Bv[j] * p;
      *Su += Du[i] * Bv[j] * p;
      *Sv += Bu[i] * Dv[j] * p;
    }
}

Eigen::Vector3d TubeSurface::eval(double u, double v) const {
  Eigen::Vector3d S, Su, Sv;
  derivatives(u, v, &S, &Su, &Sv);
  return S;
}

PatchSkin fit_patch_skin(const SkinResult& skin, const std::vector<Eigen::Vector3d>& points,
                         const std::vector<std::uint32_t>& sides, const PatchOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("patch options", err);
  HS_CHECK(points.size() == sides.size(), "points and sides differ in length");
  const auto t0 = std::chrono::steady_clock::now();
  PatchSkin out;
  for (const auto& b : skin.bones) out.bones.push_back(b.name());

  // --- the tubes' parameter domains: chord length along and around the rings ---
  struct Domain {
    std::vector<std::vector<Eigen::Vector3d>> rings;  ///< the tube's rings, with the closing ones
    std::vector<char> closing;                        ///< per ring: added to close an end (weak data)
    std::vector<double> u_of_point, v_of_ring;
  };
  std::vector<Domain> domains;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<int, 3>> node_of;  // tube slot, ring, point
  for (size_t g = 0; g < skin.grid.size(); ++g) {
    const RingGrid& rg = skin.grid[g];
    if (!rg.present || rg.rings.size() < 2) continue;
    const size_t m = rg.rings[0].size();
    TubeSurface T;
    T.tube = rg.tube;
    const bool palm = rg.tube == static_cast<int>(SkinTube::Palm);
    T.nu = palm ? o.palm_around : o.digit_around;
    T.nv = palm ? o.palm_along : o.digit_along;
    if (const auto it = o.tube_spans.find(rg.tube); it != o.tube_spans.end()) T.nu = it->second[0], T.nv = it->second[1];
    Domain D;
    // Closing rings: a digit's tip ends at its pole (and a capped start would begin at its
    // first ring's centre, drawn in halfway). The closed row of control points is one point
    // (tied in fit_net): the end is closed by patches with one edge collapsed.
    auto centroid = [&](const std::vector<Eigen::Vector3d>& r) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const auto& p : r) c += p;
      return Eigen::Vector3d(c / static_cast<double>(r.size()));
    };
    // The wrist end stays open: capping it (a cone of patches to the first ring's centre) took
    // the fixture's surface → truth mean from 0.54 to 0.69 mm (docs/patches.md).
    T.closed_start = false;
    T.closed_end = !palm && rg.pole.has_value();
    if (T.closed_start) {
      const Eigen::Vector3d c = centroid(rg.rings.front());
      std::vector<Eigen::Vector3d> half;
      for (const auto& p : rg.rings.front()) half.push_back(0.5 * (p + c));
      D.rings.push_back(std::vector<Eigen::Vector3d>(m, c));
      D.rings.push_back(half);
      D.closing = {1, 1};
    }
    for (const auto& ring : rg.rings) D.rings.push_back(ring), D.closing.push_back(0);
    if (T.closed_end) D.rings.push_back(std::vector<Eigen::Vector3d>(m, *rg.pole)), D.closing.push_back(1);
    std::vector<double> around(m + 1, 0.0);
    for (const auto& ring : rg.rings)
      for (size_t j = 0; j < m; ++j) around[j + 1] += (ring[(j + 1) % m] - ring[j]).norm();
    for (size_t j = 1; j <= m; ++j) around[j] += around[j - 1];
    for (size_t j = 0; j < m; ++j) D.u_of_point.push_back(T.nu * around[j] / around[m]);
    // Along: the mean distance between corresponding points of consecutive rings (along the
    // tube this is the rings' spacing; over a cap, its radius).
    std::vector<double> along(1, 0.0);
    for (size_t r = 1; r < D.rings.size(); ++r) {
      double d = 0;
      for (size_t j = 0; j < m; ++j) d += (D.rings[r][j] - D.rings[r - 1][j]).norm();
      along.push_back(along.back() + d / static_cast<double>(m));
    }
    for (double a : along) D.v_of_ring.push_back(T.nv * a / std::max(along.back(), 1e-9));
    for (size_t r = 0; r < D.rings.size(); ++r)
      for (size_t j = 0; j < m; ++j) {
        nodes.push_back(D.rings[r][j]);
        node_of.push_back({static_cast<int>(out.tubes.size()), static_cast<int>(r), static_cast<int>(j)});
      }
    out.tubes.push_back(T);
    domains.push_back(std::move(D));
  }
  if (out.tubes.empty()) throw InputError("skin", "no ring grid to fit patches on");

  // --- data: each measured point to the tube of its nearest ring point, parameters from it;
  //     the ring points themselves as weak data (they bridge what the scans did not see) ---
  std::vector<std::vector<Datum>> data(out.tubes.size());
  constexpr double kFarMm = 5.0;  // farther from every ring: not the skin (a stray sample)
  const PointGrid grid(nodes, 2.0);  // exact nearest ring point within kFarMm
  std::vector<int> nearest(points.size(), -1);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < static_cast<long>(points.size()); ++k) nearest[k] = grid.nearest(points[k], kFarMm);
  for (size_t k = 0; k < points.size(); ++k) {
    if (nearest[k] < 0) continue;
    const auto& [t, r, j] = node_of[nearest[k]];
    data[t].push_back({points[k], domains[t].u_of_point[j], domains[t].v_of_ring[r], 1.0, static_cast<int>(sides[k])});
  }
  for (size_t t = 0; t < out.tubes.size(); ++t) {
    const Domain& D = domains[t];
    for (size_t r = 0; r < D.rings.size(); ++r)
      for (size_t j = 0; j < D.rings[r].size(); ++j)
        data[t].push_back({D.rings[r][j], D.u_of_point[j], D.v_of_ring[r], o.ring_weight, -1});
  }

  // --- fit, then correct the parameters (eqs. 4.6–4.7) until they settle ---
  // Each round: foot points on the current surface (their residuals give the round's RMS),
  // then the refit. The tubes are independent: fitted in parallel.
  auto fit_all = [&] {
#pragma omp parallel for schedule(dynamic)
    for (long t = 0; t < static_cast<long>(out.tubes.size()); ++t) fit_net(&out.tubes[t], data[t], o);
  };
  fit_all();
  for (int round = 0; round <= o.max_corrections; ++round) {
    double max_update = 0, sum2 = 0;
    long count = 0;
    for (size_t t = 0; t < out.tubes.size(); ++t) {
      std::vector<Datum>& D = data[t];
#pragma omp parallel for reduction(max : max_update) reduction(+ : sum2, count) schedule(static)
      for (long k = 0; k < static_cast<long>(D.size()); ++k)
        if (D[k].side >= 0) {
          double r2 = 0;
          max_update = std::max(max_update, foot_point(out.tubes[t], &D[k], 1, &r2));
          sum2 += r2;
          ++count;
        }
    }
    out.rms_per_round.push_back(std::sqrt(sum2 / std::max(count, 1L)));
    if (round == o.max_corrections) break;
    out.max_update_per_round.push_back(max_update);
    fit_all();
    if (max_update < o.correction_tolerance) break;
  }
  // Final foot points on the final surface: the exact data → surface distances.
  std::vector<double> residual[2];
  for (size_t t = 0; t < out.tubes.size(); ++t) {
    std::vector<Datum>& D = data[t];
    std::vector<double> r(D.size(), -1);
#pragma omp parallel for schedule(static)
    for (long k = 0; k < static_cast<long>(D.size()); ++k)
      if (D[k].side >= 0) {
        foot_point(out.tubes[t], &D[k], 8);
        r[k] = (out.tubes[t].eval(D[k].u, D[k].v) - D[k].p).norm();
      }
    // Patches are numbered tube by tube, around-major (as built below).
    size_t first_patch = 0;
    for (size_t q = 0; q < t; ++q) first_patch += static_cast<size_t>(out.tubes[q].nu) * out.tubes[q].nv;
    for (size_t k = 0; k < D.size(); ++k)
      if (D[k].side >= 0) {
        residual[D[k].side == 1 ? 1 : 0].push_back(r[k]);
        int a, b;
        double ls, lt;
        locate(out.tubes[t].nu, out.tubes[t].nv, D[k].u, D[k].v, &a, &b, &ls, &lt);
        out.samples.push_back({D[k].p, static_cast<float>(r[k]), static_cast<std::uint8_t>(D[k].side == 1 ? 1 : 0),
                               static_cast<int>(first_patch) + a * out.tubes[t].nv + b, static_cast<float>(ls),
                               static_cast<float>(lt)});
      }
  }
  out.side = {figures_of(residual[0]), figures_of(residual[1])};

  // --- patches, their links, the net's binding, continuity figures ---
  std::vector<double> g1;
  for (TubeSurface& T : out.tubes) {
    T.net_link.resize(T.net.size());
    for (size_t k = 0; k < T.net.size(); ++k) T.net_link[k] = nearest_link(T.net[k], skin.bones);
    out.control_points += T.net.size();
    for (int a = 0; a < T.nu; ++a)
      for (int b = 0; b < T.nv; ++b) {
        BezierPatch P = patch_of(T, a, b);
        P.link = nearest_link(P.eval(0.5, 0.5), skin.bones);
        out.patches.push_back(P);
      }
    // Shared borders: the same curve from both sides (G0), and the angle between the two
    // sides' normals along it (G1), 9 samples per border.
    auto normal = [&](double u, double v) {
      Eigen::Vector3d S, Su, Sv;
      T.derivatives(u, v, &S, &Su, &Sv);
      return Eigen::Vector3d(Su.cross(Sv).normalized());
    };
    auto jump_deg = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / M_PI;
    };
    auto side_eval = [&](int a, int b, double s, double t) { return patch_of(T, a, b).eval(s, t); };
    constexpr double kEps = 1e-6;
    for (int a = 0; a < T.nu; ++a)
      for (int b = 0; b < T.nv; ++b)
        for (int q = 1; q <= 9; ++q) {
          const double s = q / 10.0;
          // the border between (a, b) and (a + 1, b): u = a + 1
          out.g0_gap_mm = std::max(out.g0_gap_mm, (side_eval(a, b, 1, s) - side_eval((a + 1) % T.nu, b, 0, s)).norm());
          {
            const double j = jump_deg(normal(a + 1 - kEps, b + s), normal(a + 1 + kEps, b + s));
            if (std::isfinite(j)) g1.push_back(j);  // not at a closed end's collapsed point
          }
          if (b + 1 < T.nv) {
            out.g0_gap_mm = std::max(out.g0_gap_mm, (side_eval(a, b, s, 1) - side_eval(a, b + 1, s, 0)).norm());
            const double j = jump_deg(normal(a + s, b + 1 - kEps), normal(a + s, b + 1 + kEps));
            if (std::isfinite(j)) g1.push_back(j);
          }
        }
  }
  if (!g1.empty()) {
    std::sort(g1.begin(), g1.end());
    out.g1_median_deg = g1[g1.size() / 2];
    out.g1_p95_deg = g1[static_cast<size_t>(0.95 * (g1.size() - 1))];
    out.g1_max_deg = g1.back();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

PatchSkin pose_patch_skin(const PatchSkin& s, const Skeleton& skeleton, const Angles& angles) {
  // Link k of bones_from_rig runs from joints()[k + 1].parent to joint k + 1: it moves with
  // its first joint's frame.
  const auto frames = skeleton.frames(angles);
  std::vector<Eigen::Isometry3d> move;
  for (int k = 0; k + 1 < kJointCount; ++k) {
    const int j = joints()[k + 1].parent;
    move.push_back(frames[j] * skeleton.rest_frame(j).inverse());
  }
  HS_CHECK(s.bones.size() == move.size(), "patches bound to another skeleton");
  PatchSkin out;
  out.tubes = s.tubes;
  out.patches = s.patches;
  out.bones = s.bones;
  out.side = s.side;
  out.max_update_per_round = s.max_update_per_round;
  out.rms_per_round = s.rms_per_round;
  out.g0_gap_mm = s.g0_gap_mm;
  out.g1_median_deg = s.g1_median_deg, out.g1_p95_deg = s.g1_p95_deg, out.g1_max_deg = s.g1_max_deg;
  out.control_points = s.control_points;
  out.seconds = s.seconds;
  for (TubeSurface& T : out.tubes)
    for (size_t k = 0; k < T.net.size(); ++k) {
      const int l = T.net_link[k];
      HS_CHECK(l >= 0 && l < static_cast<int>(move.size()), "a control point without its link");
      T.net[k] = move[l] * T.net[k];
    }
  size_t p = 0;
  for (const TubeSurface& T : out.tubes)
    for (int a = 0; a < T.nu; ++a)
      for (int b = 0; b < T.nv; ++b, ++p) {
        const int link = out.patches[p].link;
        out.patches[p] = patch_of(T, a, b);
        out.patches[p].link = link;
      }
  return out;
}

namespace {
// Sample (i, j) of a tube's n-per-span grid repeats sample (0, j): on a closed end's row every
// sample is the pole, made once.
bool repeats_pole(const TubeSurface& T, int i, int j, int NV) {
  return i > 0 && ((j == 0 && T.closed_start) || (j == NV - 1 && T.closed_end));
}
}  // namespace

void tessellation_vertices(const PatchSkin& s, int n, std::vector<Eigen::Vector3d>* out) {
  HS_CHECK(n >= 1, "tessellation needs at least one quad per patch side");
  // Every sample sits at a patch-local parameter k / n: the Bernstein values once.
  std::vector<std::array<double, 4>> B(static_cast<size_t>(n) + 1);
  for (int k = 0; k <= n; ++k) bernstein(static_cast<double>(k) / n, B[k].data(), nullptr);
  out->clear();
  for (const TubeSurface& T : s.tubes) {
    const int NU = T.nu * n, NV = T.nv * n + 1, NU3 = 3 * T.nu, NV3 = 3 * T.nv + 1;
    for (int i = 0; i < NU; ++i)
      for (int j = 0; j < NV; ++j) {
        if (repeats_pole(T, i, j, NV)) continue;
        const int a = i / n, ks = i % n;
        const int b = std::min(j / n, T.nv - 1), kt = j - b * n;
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        for (int ii = 0; ii < 4; ++ii) {
          Eigen::Vector3d row = Eigen::Vector3d::Zero();
          for (int jj = 0; jj < 4; ++jj) row += B[kt][jj] * T.net[net_index(NU3, NV3, 3 * a + ii, 3 * b + jj)];
          p += B[ks][ii] * row;
        }
        out->push_back(p);
      }
  }
}

TriMesh tessellate(const PatchSkin& s, int n) {
  std::vector<Eigen::Vector3d> points;
  tessellation_vertices(s, n, &points);  // checks n; the vertices in the order made below
  TriMesh mesh;
  size_t next = 0;
  for (const TubeSurface& T : s.tubes) {
    const int NU = T.nu * n, NV = T.nv * n + 1;
    std::vector<TriMesh::VertexHandle> vh(static_cast<size_t>(NU) * NV);
    for (int i = 0; i < NU; ++i)
      for (int j = 0; j < NV; ++j) {
        if (repeats_pole(T, i, j, NV)) {
          vh[i * NV + j] = vh[j];
          continue;
        }
        const Eigen::Vector3d& p = points[next++];
        vh[i * NV + j] = mesh.add_vertex(TriMesh::Point(p.x(), p.y(), p.z()));
      }
    // Outward: the normal at a mid-tube point against the direction from the ring's centre.
    const int jm = NV / 2;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int i = 0; i < NU; ++i) {
      const auto& p = mesh.point(vh[i * NV + jm]);
      centre += Eigen::Vector3d(p[0], p[1], p[2]);
    }
    centre /= NU;
    Eigen::Vector3d S, Su, Sv;
    T.derivatives(0.5, static_cast<double>(jm) / n, &S, &Su, &Sv);
    const bool flip = Su.cross(Sv).dot(S - centre) < 0;
    for (int i = 0; i < NU; ++i)
      for (int j = 0; j + 1 < NV; ++j) {
        auto a = vh[i * NV + j], b = vh[((i + 1) % NU) * NV + j], c = vh[((i + 1) % NU) * NV + j + 1], d = vh[i * NV + j + 1];
        if (flip) std::swap(b, d);
        if (a != b && b != c && a != c) mesh.add_face(a, b, c);
        if (a != c && c != d && a != d) mesh.add_face(a, c, d);
      }
  }
  return mesh;
}

}  // namespace handskin
