// The patch net's least squares (patch_steps.hpp, step 4 of the fit): the data at their foot
// points, C1 and G1 across the borders, fairness, solved by sparse Cholesky and
// preconditioned conjugate gradients.
#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <algorithm>
#include <cmath>
#include <map>

#include "core/errors.hpp"
#include "patches/patch_steps.hpp"

namespace handskin::patch_steps {

namespace {

// CHOLMOD's simplicial factorisation, not its supernodal one: the supernodal one hands its
// dense blocks to whatever BLAS the machine's libblas.so.3 is (Debian's alternatives: ATLAS,
// OpenBLAS, the reference), each rounding its sums its own way, so the patches' last bits, and
// with them the refinement's chaotic choices, followed the BLAS installed (on the fixture at
// 0.5 mm, ATLAS and OpenBLAS: the web's kink 64.9° against 70.3°). The simplicial one uses no
// BLAS: the same bytes on every machine (checked with ATLAS and OpenBLAS), and on these systems
// (3 × 884 unknowns, up to ~3 × 2500 refined) it is also faster: BM_PatchesFixture 315–323 →
// 263–271 ms (docs/performance.md).
using NetCholesky = Eigen::CholmodSimplicialLLT<Eigen::SparseMatrix<double>>;

// A face's parameter speed across its side s (relative to the layout it was refined from):
// halved by every halving along the cross direction (v across sides 0 and 2, u across 1 and 3).
double cross_speed(const PatchLayout& L, int f, int s) { return std::ldexp(1.0, -L.level(f, s % 2 == 0 ? 1 : 0)); }

// The control point on the layout edge (v, w) next to corner v, and the face's parameter speed
// along it.
int net_edge_near(const PatchSkin& s, int v, int w, double* speed) {
  const auto& faces = s.layout.faces;
  // The face that runs v -> w; else (a long side, which LayoutTopology::around names by its far
  // end) the one that runs w -> v, its face's only.
  int found = -1, side = -1;
  bool forward = false;
  for (size_t f = 0; f < faces.size() && !forward; ++f)
    for (int k = 0; k < 4 && !forward; ++k) {
      const int a = faces[f][k], b = faces[f][(k + 1) % 4];
      if ((a == v && b == w) || (found < 0 && a == w && b == v)) found = static_cast<int>(f), side = k, forward = a == v;
    }
  HS_CHECK(found >= 0, "patch net: no face runs an edge of the layout");
  std::array<std::array<int, 2>, 4> on, in;
  border(side, &on, &in);
  *speed = cross_speed(s.layout, found, side + 1);
  const auto& near = on[forward ? 1 : 2];
  return s.patch_control[found][4 * near[0] + near[1]];
}


// The least squares' weights (NetFit::fit says what each term is).
constexpr double kTangentWeight = 0.005;
// The G1 rows' weight against a C1 row's. On 12 hands of the family at 0.1 the G1 p95 is
// 0.41–0.62° (8.4–9.5° without), the surface → true skin mean as before (median 0.1643 →
// 0.1633 mm). On one of them 0.03 leaves the p95 at 1.27°, 0.3 takes it to 0.33° with the
// surface → true skin mean 1.6 % larger than at 0.1.
constexpr double kG1Weight = 0.1;
// A separation's bound (NetSolver::bounds) as a penalty, relative to the data's weight per
// control point: strong enough that the bound holds to ~1e-4 mm, well within its margin.
constexpr double kBoundWeight = 1e3;
constexpr int kBoundPasses = 4;

// G1 along the borders that end where other than four patches meet, where C1 cannot hold (it
// is left out next to such a corner). At samples along the border, with n the mean of the two
// patches' normals and D_f, D_g their derivatives across it (each into its own patch), the kink
// is sin α_f + sin α_g = n·D_f/|D_f| + n·D_g/|D_g|: zero when the two cross directions are
// one line, whatever the plane's tilt (to first order a turn of both about the border leaves
// it zero, so the penalty does not pin the tangent plane where the last round left it). With
// n and the lengths from the last round the rows are linear; they couple the border's control
// points with both inner rows (12 control points, 36 unknowns).
struct G1Border {
  int f, s, g, gs;
  std::array<int, 12> ids;  ///< the border (f's order), f's inner row, g's inner row (g's order)
};
std::vector<G1Border> g1_borders(const PatchSkin& out, const LayoutTopology& T) {
  std::vector<G1Border> list;
  const auto& faces = out.layout.faces;
  for (int f = 0; f < static_cast<int>(out.patches.size()); ++f)
    for (int s = 0; s < 4; ++s) {
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      if (g < f || (g == f && gs < s)) continue;  // each border once
      if (T.half[f][s] >= 0) continue;  // a T-junction's (hanging_borders)
      if (out.layout.is_crease(faces[f][s], faces[f][(s + 1) % 4])) continue;
      if (T.regular(faces[f][s]) && T.regular(faces[f][(s + 1) % 4])) continue;
      G1Border b{f, s, g, gs, {}};
      std::array<std::array<int, 2>, 4> on_f, in_f, on_g, in_g;
      border(s, &on_f, &in_f);
      border(gs, &on_g, &in_g);
      for (int k = 0; k < 4; ++k) {
        b.ids[k] = out.patch_control[f][4 * on_f[k][0] + on_f[k][1]];
        b.ids[4 + k] = out.patch_control[f][4 * in_f[k][0] + in_f[k][1]];
        b.ids[8 + k] = out.patch_control[g][4 * in_g[k][0] + in_g[k][1]];
      }
      list.push_back(b);
    }
  return list;
}
// The kink penalty of the border between side s of patch f and side gs of patch g, Σ over
// samples of w·(L·kink)² (L the cross derivatives' mean length / 3, so that it weighs like a C1
// row in mm²), as a 3N × 3N matrix on the block's N control points `ids`. `fb`, `fi`, `gb`, `gi`:
// where in `ids` f's border, f's inner row, g's border and g's inner row are (each in its own
// patch's order along the side); the sample t along f's side lies at tg(t) along g's.
template <int N, typename Along>
Eigen::Matrix<double, 3 * N, 3 * N> kink_block(const PatchSkin& out, int f, int s, int g, int gs, const std::array<int, N>& ids,
                                               const int fb[4], const int fi[4], const int gb[4], const int gi[4], Along tg_of,
                                               double w) {
  constexpr int kSamples = 9;
  Eigen::Matrix<double, 3 * N, 3 * N> M = Eigen::Matrix<double, 3 * N, 3 * N>::Zero();
  for (int q = 1; q <= kSamples; ++q) {
    const double t = q / (kSamples + 1.0), tg = tg_of(t);
    const Eigen::Vector2d a = on_side(s, t), c = on_side(gs, tg);
    Eigen::Vector3d Sa, Sau, Sav, Sc, Scu, Scv;
    out.patches[f].derivatives(a.x(), a.y(), &Sa, &Sau, &Sav);
    out.patches[g].derivatives(c.x(), c.y(), &Sc, &Scu, &Scv);
    const Eigen::Vector3d na = Sau.cross(Sav), nc = Scu.cross(Scv);
    if (na.norm() < 1e-12 || nc.norm() < 1e-12) continue;
    const Eigen::Vector3d nm = na.normalized() + nc.normalized();
    if (nm.norm() < 1e-6) continue;
    const Eigen::Vector3d n = nm.normalized();
    double Bf[4], Bg[4];
    bernstein(t, Bf, nullptr);
    bernstein(tg, Bg, nullptr);
    Eigen::Vector3d Df = Eigen::Vector3d::Zero(), Dg = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) {
      Df += 3 * Bf[k] * (out.control[ids[fi[k]]] - out.control[ids[fb[k]]]);
      Dg += 3 * Bg[k] * (out.control[ids[gi[k]]] - out.control[ids[gb[k]]]);
    }
    const double lf = Df.norm(), lg = Dg.norm();
    if (lf < 1e-9 || lg < 1e-9) continue;
    // Weighed as the unsplit faces' rows would be: a face halved across the border has half
    // the cross derivative, and the rows' weight (L²) would fall fourfold with each halving.
    const double L = (lf / cross_speed(out.layout, f, s) + lg / cross_speed(out.layout, g, gs)) / 6;
    Eigen::Matrix<double, 3 * N, 1> row = Eigen::Matrix<double, 3 * N, 1>::Zero();
    for (int k = 0; k < 4; ++k) {
      row.template segment<3>(3 * fi[k]) += 3 * Bf[k] * L / lf * n;
      row.template segment<3>(3 * fb[k]) -= 3 * Bf[k] * L / lf * n;
      row.template segment<3>(3 * gi[k]) += 3 * Bg[k] * L / lg * n;
      row.template segment<3>(3 * gb[k]) -= 3 * Bg[k] * L / lg * n;
    }
    M.noalias() += w * row * row.transpose();
  }
  return M;
}
// A shared border's: g runs it the other way, its border is f's reversed.
Eigen::Matrix<double, 36, 36> g1_block(const PatchSkin& out, const G1Border& b, double w) {
  static constexpr int fb[4] = {0, 1, 2, 3}, fi[4] = {4, 5, 6, 7}, gb[4] = {3, 2, 1, 0}, gi[4] = {8, 9, 10, 11};
  return kink_block<12>(out, b.f, b.s, b.g, b.gs, b.ids, fb, fi, gb, gi, [](double t) { return 1 - t; }, w);
}

// G1 across a T-junction's short side (LayoutTopology) that ends where other than four patches
// meet (its C1 rows are left out there, as a shared border's): the kink rows of g1_block at
// samples along the short side, the long side's face g sampled where it lies along its side. Its cross derivative
// there involves g's whole border and inner row, so the rows couple 16 control points: f's
// border (derived from g's, LayoutTopology) and inner row, g's border and inner row.
struct HangingBorder {
  int f, s, g, gs, h;
  std::array<int, 16> ids;  ///< f's border and inner row (f's order), g's border and inner row (g's order)
};
std::vector<HangingBorder> hanging_borders(const PatchSkin& out, const LayoutTopology& T) {
  std::vector<HangingBorder> list;
  const auto& faces = out.layout.faces;
  for (int f = 0; f < static_cast<int>(out.patches.size()); ++f)
    for (int s = 0; s < 4; ++s) {
      if (T.half[f][s] < 0 || out.layout.is_crease(faces[f][s], faces[f][(s + 1) % 4])) continue;
      if (T.regular(faces[f][s]) && T.regular(faces[f][(s + 1) % 4])) continue;  // C1 holds it (net_penalties)
      HangingBorder b{f, s, T.neighbour[f][s], T.neighbour_side[f][s], T.half[f][s], {}};
      std::array<std::array<int, 2>, 4> on_f, in_f, on_g, in_g;
      border(s, &on_f, &in_f);
      border(b.gs, &on_g, &in_g);
      for (int k = 0; k < 4; ++k) {
        b.ids[k] = out.patch_control[f][4 * on_f[k][0] + on_f[k][1]];
        b.ids[4 + k] = out.patch_control[f][4 * in_f[k][0] + in_f[k][1]];
        b.ids[8 + k] = out.patch_control[b.g][4 * on_g[k][0] + on_g[k][1]];
        b.ids[12 + k] = out.patch_control[b.g][4 * in_g[k][0] + in_g[k][1]];
      }
      list.push_back(b);
    }
  return list;
}
Eigen::Matrix<double, 48, 48> hanging_block(const PatchSkin& out, const HangingBorder& b, double w) {
  static constexpr int fb[4] = {0, 1, 2, 3}, fi[4] = {4, 5, 6, 7}, gb[4] = {8, 9, 10, 11}, gi[4] = {12, 13, 14, 15};
  const double h = b.h;
  return kink_block<16>(out, b.f, b.s, b.g, b.gs, b.ids, fb, fi, gb, gi, [h](double t) { return 0.5 * h + 0.5 * (1 - t); }, w);
}

// The normal equations' solver, kept from round to round. The matrix's pattern is the same
// every round (the same net, blocks and penalties), and so are the penalties' values: the
// first round builds the pattern, keeps the penalties' share of the values and where each
// patch's 48 × 48 block lands; later rounds copy the one and add the others there.
//
// Sparse Cholesky of the normal equations; never an inverse. CHOLMOD's simplicial Cholesky
// (SuiteSparse, through Eigen; NetCholesky above says why not its supernodal one, which was
// 6–8 times faster than Eigen's own simplicial LDLᵀ and is slower than this one). A
// correction round changes the matrix only a little (the points' parameters and normals move),
// so a round first tries conjugate gradients preconditioned by the last factor, from the last
// round's control points (`preconditioned_cg`): iterations of one sparse product and two
// triangular solves (~0.26 ms each on the fixture) against a new factorisation (~17 ms). Where
// they would not converge within kCgBudget iterations the round factors its own matrix, which
// later rounds then use. The G1 rows and the normals change most in the early rounds, which
// factor; the later ones converge so as the surface settles.
constexpr int kCgBudget = 40;  // iterations; a factorisation costs about 65 on the fixture (a budget of 60 took as long)
constexpr int kCgCheck = 6;    // iterations between two predictions of the iterations still needed
constexpr int kCgStalled = 12;  // given up within this many: the next round factors at once
constexpr double kCgTolerance = 1e-7;  // relative residual; the control points then agree with direct solves within ~3e-4 mm
// The correction rounds' solves stop at a relative residual of 1e-4: each is one step of the
// alternation between foot points and control points, whose next round moves the parameters
// again, and a solve to 1e-7 there bought nothing. On the fixture and five family pairs (H01,
// H02, H05, H07, H10) every figure of the report stayed within 0.001 mm (means) and 0.02 mm
// (maxima) of solves to 1e-7, the G1 p95 within 0.07° (with G0 alone, c1_weight 0, 0.002–0.006 mm
// farther from the truth); the fit took 10–25 % less time (392
// patches on the fixture, with the final solve below: 1.67 → 1.27 s). The surface kept is then solved again to kCgTolerance
// (polish_net): the least squares of the final parameters, exactly.
constexpr double kCgRoundTolerance = 1e-4;

// Conjugate gradients on A x = b (A holding both halves) from x, preconditioned by M (the
// Cholesky factor of an earlier round's matrix). Written out rather than Eigen's
// ConjugateGradient so that it can give up early and deterministically: every kCgCheck
// iterations the residual's rate of decrease over the last ones predicts how many more
// convergence needs, and when the total would pass kCgBudget it stops (the caller then
// factors). Returns true when the relative residual reached `tolerance`.
bool preconditioned_cg(const Eigen::SparseMatrix<double>& A,
                       const NetCholesky& M, const Eigen::VectorXd& b,
                       double tolerance, Eigen::VectorXd* x, int* iterations) {
  *iterations = 0;
  const double bn = b.norm();
  if (bn == 0) {
    x->setZero();
    return true;
  }
  Eigen::VectorXd r = b - A * *x;
  double err = r.norm() / bn, err_checked = err;
  Eigen::VectorXd z = M.solve(r);
  Eigen::VectorXd p = z, Ap(b.size());
  double rz = r.dot(z);
  for (int it = 1; it <= kCgBudget && err > tolerance; ++it) {
    Ap.noalias() = A.transpose() * p;  // A is symmetric: its transpose is row-major, whose product Eigen runs on every thread
    const double pAp = p.dot(Ap);
    if (!(pAp > 0)) return false;  // not positive definite to working precision: factor
    const double alpha = rz / pAp;
    *x += alpha * p;
    r -= alpha * Ap;
    err = r.norm() / bn;
    *iterations = it;
    if (err <= tolerance) break;
    if (it % kCgCheck == 0) {
      const double rate = std::pow(err / err_checked, 1.0 / kCgCheck);
      if (!(rate < 1) || it + std::log(tolerance / err) / std::log(rate) > kCgBudget) return false;
      err_checked = err;
    }
    z = M.solve(r);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return err <= tolerance;
}

}  // namespace

struct NetSolver {
  NetCholesky llt;
  bool factored = false;  ///< llt holds a factor (of a round with normals: the first fit solves its own)
  bool stalled = false;  ///< the last round's conjugate gradients gave up early
  Eigen::SparseMatrix<double> A;  ///< the normal equations (both halves)
  std::vector<double> penalty_values;  ///< the penalties' share of A's values
  std::vector<int> block_slot;  ///< per patch, its 48 × 48 block's entries' indices in A's values
  std::vector<G1Border> g1;  ///< the borders held G1 (their kink rows change every round)
  std::vector<int> g1_slot;  ///< per such border, its 36 × 36 block's entries' indices in A's values
  std::vector<HangingBorder> hanging;  ///< the T-junctions' short sides, held G1 too
  std::vector<int> hanging_slot;  ///< per such side, its 48 × 48 block's entries' indices in A's values
  /// At T-junctions (PatchSkin::control_derived) the unknowns are the free control points only:
  /// every control point's coordinates are C times theirs, and the system solved is Cᵀ A C
  /// (`Ar`), its right-hand side Cᵀ b. Without T-junctions C is the identity and is not made.
  bool reduced = false;
  Eigen::SparseMatrix<double> C1;  ///< control points × free ones (one coordinate)
  Eigen::SparseMatrix<double> C;   ///< C1 ⊗ I₃, the unknowns interleaved
  Eigen::SparseMatrix<double> Ar;
  /// Cᵀ A C by a fixed scatter: A's pattern and C are the same every round, and so is Ar's
  /// pattern, so each of A's values adds, with fixed weights, into fixed entries of Ar's values:
  /// those of A's value p are `scatter[scatter_begin[p] .. scatter_begin[p + 1])`. One pass over
  /// A's values a round instead of two general sparse products (12–80 ms a round at 250–270
  /// patches on the fixture; the scatter itself is made once per fit, in ~25 ms: reduction_scatter), and Ar's
  /// pattern is analysed once per fit instead of before every factorisation (10–20 ms each).
  std::vector<int> scatter_begin;
  std::vector<std::pair<int, double>> scatter;
  bool analysed = false;  ///< llt holds the analysis of Ar's pattern
  const Eigen::SparseMatrix<double>& system() const { return reduced ? Ar : A; }
  /// The separations' bounds (PatchSkin::separations), one per constrained control point and
  /// separation: n · P <= bound, n pointing out of the point's side; a point of both sides (their
  /// border) is held on the plane (`on_plane`). A bound's penalty is on (`active`) once the
  /// point crossed it, and stays on for the rest of the fit (the bound then an equality: the
  /// rounds cannot cycle), and is always on for a point on the plane.
  struct Bound {
    int id = -1;
    Eigen::Vector3d n;
    double bound = 0;
    bool on_plane = false, active = false;
    size_t slot_base = 0;  ///< into block_slot: a patch with the point, its 48 × 48 block
    int local = 0;         ///< the point's index among that patch's 16
  };
  std::vector<Bound> bounds;
  Eigen::VectorXd x;  ///< the last solution (of the system solved)
  Eigen::VectorXd rhs;  ///< the last right-hand side (system() x = rhs)
  bool exact = false;  ///< x solves the last system directly or to kCgTolerance
};

namespace {

// Each border's kink block (made on every thread) added at its slots in A's values.
template <int M, typename Border, typename Make>
void add_kink_blocks(const std::vector<Border>& borders, const std::vector<int>& slots, Make make, double* values) {
  std::vector<Eigen::Matrix<double, M, M>> blocks(borders.size());
#pragma omp parallel for schedule(static)
  for (long k = 0; k < static_cast<long>(blocks.size()); ++k) blocks[k] = make(borders[k]);
  for (size_t k = 0; k < blocks.size(); ++k) {
    const int* slot = &slots[k * M * M];
    for (int a = 0; a < M; ++a)
      for (int b = 0; b < M; ++b) values[slot[M * a + b]] += blocks[k](a, b);
  }
}

// A direct solve of A x = b with A the solver's matrix; the factor is kept (later rounds'
// conjugate gradients are preconditioned by it).
Eigen::VectorXd solve_directly(NetSolver* solver, const Eigen::VectorXd& b) {
  if (solver->reduced && !solver->analysed) solver->llt.analyzePattern(solver->Ar), solver->analysed = true;
  solver->llt.factorize(solver->system());
  HS_CHECK(solver->llt.info() == Eigen::Success, "patch fit: the normal equations could not be factored");
  solver->factored = true;
  return solver->llt.solve(b);
}

// A solution of the solver's system (`exact`: directly or to kCgTolerance) into the net's
// control points and the patches.
void take_solution(PatchSkin* out, NetSolver* solver, Eigen::VectorXd X, bool exact) {
  solver->x = std::move(X);
  solver->exact = exact;
  const Eigen::VectorXd full = solver->reduced ? Eigen::VectorXd(solver->C * solver->x) : Eigen::VectorXd();
  const Eigen::VectorXd& all = solver->reduced ? full : solver->x;
  for (size_t k = 0; k < out->control.size(); ++k) out->control[k] = all.segment<3>(3 * static_cast<long>(k));
  rebuild_patches(out);
}

// The separations' bounds on the control points (NetSolver::bounds).
std::vector<NetSolver::Bound> separation_bounds(const PatchSkin& out) {
  std::vector<NetSolver::Bound> bounds;
  for (const Separation& sep : out.separations) {
    std::array<std::map<int, std::pair<size_t, int>>, 2> on;  // per side: control point → (its patch's block, index)
    for (int side = 0; side < 2; ++side)
      for (int f : sep.faces[side]) {
        HS_CHECK(f >= 0 && static_cast<size_t>(f) < out.patch_control.size(), "separation: no such face");
        for (int k = 0; k < 16; ++k) on[side].emplace(out.patch_control[f][k], std::make_pair(static_cast<size_t>(f) * 48 * 48, k));
      }
    for (int side = 0; side < 2; ++side)
      for (const auto& [id, where] : on[side]) {
        NetSolver::Bound b;
        b.id = id, b.slot_base = where.first, b.local = where.second;
        b.on_plane = on[1 - side].count(id) > 0;
        if (b.on_plane && side == 1) continue;  // once
        b.n = side == 0 ? sep.normal : Eigen::Vector3d(-sep.normal);
        b.bound = (side == 0 ? sep.offset : -sep.offset) - (b.on_plane ? 0.0 : kSeparationMarginMm);
        b.active = b.on_plane;
        bounds.push_back(b);
      }
  }
  return bounds;
}

// The active bounds' penalties, w (n · P - bound)², into A's values and the right-hand side.
void add_bound_penalties(const NetSolver& solver, double w, double* values, Eigen::VectorXd* R) {
  for (const auto& b : solver.bounds) {
    if (!b.active) continue;
    const int x = 3 * b.local;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) values[solver.block_slot[b.slot_base + 48 * (x + i) + (x + j)]] += w * b.n(i) * b.n(j);
      (*R)(3 * b.id + i) += w * b.bound * b.n(i);
    }
  }
}

// Switches on the bounds the control points cross now; true when one was.
bool activate_crossed_bounds(NetSolver* solver, const PatchSkin& out) {
  bool any = false;
  for (auto& b : solver->bounds)
    if (!b.active && b.n.dot(out.control[b.id]) > b.bound) b.active = any = true;
  return any;
}

// The penalties that are the same every round, as triplets: fairness, C1 across borders, G1
// at the corners where other than four patches meet.
std::vector<Eigen::Triplet<double>> net_penalties(const PatchSkin& out, const LayoutTopology& T, const PatchOptions& o,
                                                  double per_point) {
  const int patches = static_cast<int>(out.patches.size());
  std::vector<Eigen::Triplet<double>> A;
  // A penalty row Σ w_k e_k on control points (the same for x, y and z): its normal-equation entries.
  auto penalty = [&](std::initializer_list<int> ids, std::initializer_list<double> coef, double w) {
    const int* id = ids.begin();
    const double* cf = coef.begin();
    const size_t m = ids.size();
    for (size_t x = 0; x < m; ++x)
      for (size_t y = 0; y < m; ++y)
        for (int c = 0; c < 3; ++c) A.emplace_back(3 * id[x] + c, 3 * id[y] + c, w * cf[x] * cf[y]);
  };
  auto triple = [&](int i0, int i1, int i2, double w) { penalty({i0, i1, i2}, {1, -2, 1}, w); };
  // Fairness: second differences along both directions inside each patch.
  for (int f = 0; f < patches; ++f) {
    const auto& id = out.patch_control[f];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 2; ++b) {
        triple(id[4 * a + b], id[4 * a + b + 1], id[4 * a + b + 2], per_point * o.fairness);
        triple(id[4 * b + a], id[4 * (b + 1) + a], id[4 * (b + 2) + a], per_point * o.fairness);
      }
  }
  // C1: each border's control points midway between their inner neighbours on either side.
  const auto& faces = out.layout.faces;
  for (int f = 0; f < patches; ++f)
    for (int s = 0; s < 4; ++s) {
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      if (g < f || (g == f && gs < s)) continue;  // each border once
      if (T.half[f][s] >= 0) continue;  // a T-junction: held G1 (hanging_block)
      std::array<std::array<int, 2>, 4> on_f, in_f, on_g, in_g;
      border(s, &on_f, &in_f);
      border(gs, &on_g, &in_g);
      const auto& idf = out.patch_control[f];
      const auto& idg = out.patch_control[g];
      // A face halved along the border's cross direction more often than its neighbour has a
      // slower parameter there (cross_speed): C1 weighs each side's cross derivative by it.
      const double speed_f = cross_speed(out.layout, f, s), speed_g = cross_speed(out.layout, g, gs);
      const double wf = 2 * speed_g / (speed_f + speed_g), wg = 2 * speed_f / (speed_f + speed_g);  // D_f / speed_f = −D_g / speed_g
      for (int k = 0; k < 4; ++k) {
        const auto& b = on_f[k];
        const auto& a = in_f[k];
        const auto& c = in_g[3 - k];  // g runs the border the other way
        HS_CHECK(idf[4 * b[0] + b[1]] == idg[4 * on_g[3 - k][0] + on_g[3 - k][1]], "patch net: a border not shared");
        if (out.layout.is_crease(faces[f][s], faces[f][(s + 1) % 4])) break;
        // Next to a corner where other than four patches meet C1 cannot hold; from the second
        // round the border is held G1 instead (g1_block), and only the row at a regular end
        // keeps its C1 condition.
        if (k <= 2 && !T.regular(faces[f][s])) continue;
        if (k >= 1 && !T.regular(faces[f][(s + 1) % 4])) continue;
        if (speed_f == speed_g) {
          triple(idf[4 * a[0] + a[1]], idf[4 * b[0] + b[1]], idg[4 * c[0] + c[1]], per_point * (o.c1_weight + o.fairness));
        } else {
          penalty({idf[4 * a[0] + a[1]], idf[4 * b[0] + b[1]], idg[4 * c[0] + c[1]]}, {wf, -2, wg},
                  per_point * (o.c1_weight + o.fairness));
        }
      }
    }
  // C1 across a T-junction's short side: its cross differences (inner row − border) against the
  // long side's face's, cut to the same half by de Casteljau (kHalfCurve), as a split of a face
  // that was C1 with its neighbour leaves them. With the short side's border itself that half of
  // the long side's, the condition reads: each border point midway between its inner neighbour
  // and the same combination of the long side's inner row.
  for (int f = 0; f < patches; ++f)
    for (int s = 0; s < 4; ++s) {
      const int h = T.half[f][s];
      if (h < 0 || out.layout.is_crease(faces[f][s], faces[f][(s + 1) % 4])) continue;
      const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
      std::array<std::array<int, 2>, 4> on_f, in_f, on_g, in_g;
      border(s, &on_f, &in_f);
      border(gs, &on_g, &in_g);
      const double speed_f = cross_speed(out.layout, f, s), speed_g = cross_speed(out.layout, g, gs);
      const double wf = 2 * speed_g / (speed_f + speed_g), wg = 2 * speed_f / (speed_f + speed_g);  // D_f / speed_f = −D_g / speed_g
      for (int k = 0; k < 4; ++k) {
        if (k <= 2 && !T.regular(faces[f][s])) continue;
        if (k >= 1 && !T.regular(faces[f][(s + 1) % 4])) continue;
        std::vector<int> ids = {out.patch_control[f][4 * in_f[k][0] + in_f[k][1]], out.patch_control[f][4 * on_f[k][0] + on_f[k][1]]};
        std::vector<double> coef = {wf, -2};
        for (int j = 0; j < 4; ++j)
          if (const double w = kHalfCurve[h][3 - k][j]; w != 0)
            ids.push_back(out.patch_control[g][4 * in_g[j][0] + in_g[j][1]]), coef.push_back(wg * w);
        for (size_t x = 0; x < ids.size(); ++x)
          for (size_t y = 0; y < ids.size(); ++y)
            for (int c = 0; c < 3; ++c)
              A.emplace_back(3 * ids[x] + c, 3 * ids[y] + c, per_point * (o.c1_weight + o.fairness) * coef[x] * coef[y]);
      }
    }
  // Where other than four patches meet, the control points next to the corner along its
  // edges, taken in turn round it (v_i = e_i − corner), are held to an affine image of a
  // regular n-gon: v_{i−1} + v_{i+1} = 2 cos(2π/n) v_i. They then lie in one plane — one
  // tangent plane for all the patches there (G1 at the corner) — and the condition is linear
  // and the same for x, y and z (for n = 4 it is the C1 condition above). Corners on a crease
  // are left free.
  for (size_t v = 0; v < T.valence.size(); ++v) {
    if (T.regular(static_cast<int>(v)) || T.around[v].empty()) continue;
    bool on_crease = false;
    for (int w : T.around[v]) on_crease = on_crease || out.layout.is_crease(static_cast<int>(v), w);
    if (on_crease) continue;
    const int m = static_cast<int>(T.around[v].size());
    const double c = std::cos(2 * M_PI / m);
    std::vector<int> e(m);
    std::vector<double> speed(m);  // the edges' control points lie nearer the corner on a face halved along them
    bool same = true;
    for (int i = 0; i < m; ++i) {
      e[i] = net_edge_near(out, static_cast<int>(v), T.around[v][i], &speed[i]);
      same = same && speed[i] == speed[0];
    }
    for (int i = 0; i < m; ++i) {
      if (same) {
        penalty({e[(i + m - 1) % m], e[(i + 1) % m], e[i], static_cast<int>(v)}, {1, 1, -2 * c, -2 * (1 - c)},
                per_point * o.corner_weight);
        continue;
      }
      // (e − v) / speed for each edge: s₋(e₋ − v) + s₊(e₊ − v) − 2c s(e − v), s = 1 / speed.
      const double sa = 1 / speed[(i + m - 1) % m], sb = 1 / speed[(i + 1) % m], si = 1 / speed[i];
      penalty({e[(i + m - 1) % m], e[(i + 1) % m], e[i], static_cast<int>(v)}, {sa, sb, -2 * c * si, -(sa + sb - 2 * c * si)},
              per_point * o.corner_weight);
    }
  }
  return A;
}

// The unknowns (x, y, z of each) of `count` control points, in that order.
std::vector<int> unknowns_of(const int* ids, int count) {
  std::vector<int> u(3 * static_cast<size_t>(count));
  for (int a = 0; a < 3 * count; ++a) u[a] = 3 * ids[a / 3] + a % 3;
  return u;
}

// Where the entries (u[a], u[b]) of a dense block on the distinct unknowns u sit in A's values:
// slot[|u| a + b]. One walk down each of the block's columns (A's row indices are sorted in
// each column) instead of a binary search per entry: the first round's pattern took 9 ms so.
void block_slots(const Eigen::SparseMatrix<double>& A, const std::vector<int>& u, int* slot) {
  const int m = static_cast<int>(u.size());
  std::vector<int> order(m);
  for (int a = 0; a < m; ++a) order[a] = a;
  std::sort(order.begin(), order.end(), [&](int a, int b) { return u[a] < u[b]; });
  const int* inner = A.innerIndexPtr();
  for (int b = 0; b < m; ++b) {
    int p = A.outerIndexPtr()[u[b]];
    const int end = A.outerIndexPtr()[u[b] + 1];
    for (int a : order) {
      while (p < end && inner[p] < u[a]) ++p;
      HS_CHECK(p < end && inner[p] == u[a], "patch fit: a block entry is missing from the matrix's pattern");
      slot[m * a + b] = p;
    }
  }
}

// A's pattern, every dense block's entries and the penalties', and the penalties' values
// (summed in their order) in it, built column by column: a column gathers the rows of the
// blocks that hold its unknown and of its penalties, each once (a stamp per row). (The blocks'
// entries as zero triplets, ~1 million at 220–290 patches, sorted by setFromTriplets, took
// 14 ms a fit on the fixture.)
void pattern_with_penalties(int unknowns, const std::vector<std::vector<int>>& blocks,
                            const std::vector<Eigen::Triplet<double>>& penalties, Eigen::SparseMatrix<double>* A) {
  const int N = unknowns;
  // Per column, the blocks that hold it and its penalties (in their order): counting sorts.
  const auto bucket = [N](size_t count, const auto& column_of) {
    std::pair<std::vector<int>, std::vector<int>> b{std::vector<int>(N + 1, 0), std::vector<int>(count)};
    for (size_t k = 0; k < count; ++k) ++b.first[column_of(k) + 1];
    for (int c = 0; c < N; ++c) b.first[c + 1] += b.first[c];
    std::vector<int> next(b.first.begin(), b.first.end() - 1);
    for (size_t k = 0; k < count; ++k) b.second[next[column_of(k)]++] = static_cast<int>(k);
    return b;
  };
  std::vector<std::pair<int, int>> holds;  // (column, block)
  for (size_t k = 0; k < blocks.size(); ++k)
    for (int a : blocks[k]) holds.emplace_back(a, static_cast<int>(k));
  const auto [block_begin, block_of] = bucket(holds.size(), [&](size_t k) { return holds[k].first; });
  const auto [penalty_begin, penalty_of] = bucket(penalties.size(), [&](size_t k) { return static_cast<int>(penalties[k].col()); });
  std::vector<int> outer(N + 1, 0), inner;
  std::vector<double> values;
  std::vector<int> stamp(N, -1), slot(N, -1);
  for (int c = 0; c < N; ++c) {
    const size_t first = inner.size();
    const auto take = [&](int r) {
      if (stamp[r] != c) stamp[r] = c, inner.push_back(r);
    };
    for (int q = block_begin[c]; q < block_begin[c + 1]; ++q)
      for (int a : blocks[holds[block_of[q]].second]) take(a);
    for (int q = penalty_begin[c]; q < penalty_begin[c + 1]; ++q) take(static_cast<int>(penalties[penalty_of[q]].row()));
    std::sort(inner.begin() + static_cast<long>(first), inner.end());
    values.resize(inner.size(), 0.0);
    for (size_t k = first; k < inner.size(); ++k) slot[inner[k]] = static_cast<int>(k);
    for (int q = penalty_begin[c]; q < penalty_begin[c + 1]; ++q) {
      const auto& t = penalties[penalty_of[q]];
      values[slot[t.row()]] += t.value();
    }
    outer[c + 1] = static_cast<int>(inner.size());
  }
  *A = Eigen::Map<const Eigen::SparseMatrix<double>>(N, N, static_cast<long>(inner.size()), outer.data(), inner.data(), values.data());
}

// Ar's pattern (Cᵀ A C of A's pattern) and the scatter that makes its values from A's
// (NetSolver::scatter). A's value at (i, j) adds C(i, a) C(j, b) of itself to Ar(a, b).
// Made column by column of Ar: column b gathers from the columns j of A that C makes from the
// free unknown b (C's column b), each row once (a stamp per row), and its rows' slots are then
// looked up in one dense array. (Gathering every column's rows with their repeats, sorting them
// and a binary search per scatter entry took 70–80 ms a fit at 220–290 patches on the fixture.)
void reduction_scatter(NetSolver* solver) {
  const Eigen::SparseMatrix<double>& A = solver->A;
  const Eigen::SparseMatrix<double>& Ccol = solver->C;  // per free unknown, the unknowns made of it
  const Eigen::SparseMatrix<double, Eigen::RowMajor> Crow = solver->C;  // per unknown, the free unknowns it is made of
  using RowIt = Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator;
  using ColIt = Eigen::SparseMatrix<double>::InnerIterator;
  const int m = static_cast<int>(Ccol.cols());
  const int* Cro = Crow.outerIndexPtr();
  const auto fan = [&](int u) { return Cro[u + 1] - Cro[u]; };  // the free unknowns unknown u is made of
  std::vector<int> outer(m + 1, 0), inner;
  inner.reserve(static_cast<size_t>(A.nonZeros()) + static_cast<size_t>(A.nonZeros()) / 4);
  std::vector<int> stamp(m, -1);
  for (int b = 0; b < m; ++b) {
    const size_t first = inner.size();
    for (ColIt cj(Ccol, b); cj; ++cj)
      for (ColIt it(A, static_cast<int>(cj.row())); it; ++it)
        for (RowIt ci(Crow, it.row()); ci; ++ci) {
          const int a = static_cast<int>(ci.col());
          if (stamp[a] != b) stamp[a] = b, inner.push_back(a);
        }
    std::sort(inner.begin() + static_cast<long>(first), inner.end());
    outer[b + 1] = static_cast<int>(inner.size());
  }
  const std::vector<double> zeros(inner.size(), 0.0);
  solver->Ar = Eigen::Map<const Eigen::SparseMatrix<double>>(m, m, static_cast<long>(inner.size()), outer.data(), inner.data(),
                                                            zeros.data());
  // A's value p (row i, column j) has fan(i) × fan(j) scatter entries, C's entries of row i
  // outer, of row j inner.
  const int* Ao = A.outerIndexPtr();
  const int* Ai = A.innerIndexPtr();
  solver->scatter_begin.assign(static_cast<size_t>(A.nonZeros()) + 1, 0);
  for (int j = 0; j < A.outerSize(); ++j)
    for (int p = Ao[j]; p < Ao[j + 1]; ++p) solver->scatter_begin[p + 1] = solver->scatter_begin[p] + fan(Ai[p]) * fan(j);
  solver->scatter.assign(static_cast<size_t>(solver->scatter_begin.back()), {0, 0.0});
  std::vector<int> slot(m, -1);  // per row of Ar's column b, its entry's index in Ar's values
  for (int b = 0; b < m; ++b) {
    for (int q = outer[b]; q < outer[b + 1]; ++q) slot[inner[q]] = q;
    for (ColIt cj(Ccol, b); cj; ++cj) {
      const int j = static_cast<int>(cj.row());
      int k = 0;  // b's place in row j of C
      while (Crow.innerIndexPtr()[Cro[j] + k] != b) ++k;
      const int fj = fan(j);
      for (int p = Ao[j]; p < Ao[j + 1]; ++p) {
        int l = 0;
        for (RowIt ci(Crow, Ai[p]); ci; ++ci, ++l)
          solver->scatter[static_cast<size_t>(solver->scatter_begin[p] + l * fj + k)] = {slot[ci.col()], ci.value() * cj.value()};
      }
    }
  }
}

// Least squares for every control point at once (eq. 4.5): the data, C1 across every border
// but next to a corner where other than four patches meet (there it would flatten the corner's
// tangents): those borders are held G1 (g1_block) from the second round on, the corner itself
// by its own condition (net_penalties); fairness inside each patch. The normal equations are
// assembled from per-patch blocks.
//
// Once the points have foot points with normals, each point's error is measured the way
// squared-distance minimisation does (Wang, Pottmann & Liu 2006): its distance along the
// surface's normal there in full, its offset along the surface at kTangentWeight. The
// thesis's point-to-point error (eq. 4.5 with the parameters held) makes the fit drag the
// surface along with the points' old parameters: the parameter correction then creeps (on an
// ellipsoid the RMS still fell by a third from the tenth round to the thirtieth); with the
// normal error the correction settles in a few rounds. The normal term couples x, y and z,
// so the system has three unknowns per control point.
void fit_net(PatchSkin* out, const LayoutTopology& T, const std::vector<Datum>& data, const PatchOptions& o,
             NetSolver* solver) {
  const int n = static_cast<int>(out->control.size());
  const int patches = static_cast<int>(out->patches.size());
  std::vector<std::vector<int>> of_patch(patches);
  double wsum = 0;
  bool normals = false;
  for (size_t k = 0; k < data.size(); ++k)
    if (data[k].fit) {
      of_patch[data[k].patch].push_back(static_cast<int>(k)), wsum += data[k].w;
      normals = normals || data[k].n.squaredNorm() > 0.5;
    }
  // Per patch: the point term's 16 × 16 block (the same for x, y, z) and the normal term's
  // 48 × 48 block, each one product C·Cᵀ of its data's columns.
  std::vector<Eigen::Matrix<double, 16, 16>> block(patches);
  std::vector<Eigen::Matrix<double, 16, 3>> rhs(patches);
  std::vector<Eigen::Matrix<double, 48, 48>> nblock(patches);
  std::vector<Eigen::Matrix<double, 48, 1>> nrhs(patches);
#pragma omp parallel for schedule(dynamic)
  for (int f = 0; f < patches; ++f) {
    const std::vector<int>& ids = of_patch[f];
    if (ids.empty()) {  // no point on it (a small patch over a hole): the penalties alone hold it
      block[f].setZero(), rhs[f].setZero(), nblock[f].setZero(), nrhs[f].setZero();
      continue;  // (and Eigen's product blocking divides by the empty depth)
    }
    Eigen::Matrix<double, 16, Eigen::Dynamic> C(16, ids.size());
    Eigen::Matrix<double, Eigen::Dynamic, 3> Y(ids.size(), 3);
    Eigen::Matrix<double, 48, Eigen::Dynamic> Cn = Eigen::Matrix<double, 48, Eigen::Dynamic>::Zero(48, ids.size());
    Eigen::Matrix<double, Eigen::Dynamic, 1> Yn = Eigen::Matrix<double, Eigen::Dynamic, 1>::Zero(ids.size());
    for (size_t q = 0; q < ids.size(); ++q) {
      const Datum& d = data[ids[q]];
      double Bu[4], Bv[4];
      bernstein(d.s, Bu, nullptr);
      bernstein(d.t, Bv, nullptr);
      const bool with_normal = d.n.squaredNorm() > 0.5;
      const double sp = std::sqrt(d.w * (with_normal ? kTangentWeight : 1.0)), sn = std::sqrt(d.w);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
          const double b = Bu[i] * Bv[j];
          C(4 * i + j, q) = sp * b;
          if (with_normal) Cn.block<3, 1>(3 * (4 * i + j), q) = sn * b * d.n;
        }
      Y.row(q) = sp * d.p.transpose();
      if (with_normal) Yn(q) = sn * d.n.dot(d.p);
    }
    block[f].noalias() = C * C.transpose();
    rhs[f].noalias() = C * Y;
    // Cn·Cnᵀ is symmetric: its lower half by a rank update (half the products), mirrored.
    nblock[f].setZero();
    nblock[f].selfadjointView<Eigen::Lower>().rankUpdate(Cn);
    nblock[f].triangularView<Eigen::StrictlyUpper>() = nblock[f].transpose();
    // The point term's block on the diagonal of each control point pair's 3 × 3.
    for (int x = 0; x < 16; ++x)
      for (int y = 0; y < 16; ++y)
        for (int c = 0; c < 3; ++c) nblock[f](3 * x + c, 3 * y + c) += block[f](x, y);
    nrhs[f].noalias() = Cn * Yn;
  }
  Eigen::VectorXd R = Eigen::VectorXd::Zero(3 * n);
  for (int f = 0; f < patches; ++f) {
    const auto& idx = out->patch_control[f];
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 3; ++c) R(3 * idx[x] + c) += rhs[f](x, c) + nrhs[f](3 * x + c);
  }
  Eigen::SparseMatrix<double>& As = solver->A;
  if (solver->block_slot.empty()) {
    // The pattern: every patch's 48 × 48 block (as zeros) and the penalties.
    // Each dense block's unknowns: every patch's 48, then every G1 border's 36.
    solver->g1 = g1_borders(*out, T);
    solver->hanging = hanging_borders(*out, T);
    std::vector<std::vector<int>> blocks;
    for (int f = 0; f < patches; ++f) blocks.push_back(unknowns_of(out->patch_control[f].data(), 16));
    for (const G1Border& g : solver->g1) blocks.push_back(unknowns_of(g.ids.data(), 12));
    for (const HangingBorder& g : solver->hanging) blocks.push_back(unknowns_of(g.ids.data(), 16));
    pattern_with_penalties(3 * n, blocks, net_penalties(*out, T, o, wsum / n), &As);
    solver->penalty_values.assign(As.valuePtr(), As.valuePtr() + As.nonZeros());
    solver->block_slot.resize(static_cast<size_t>(patches) * 48 * 48);
    solver->g1_slot.resize(solver->g1.size() * 36 * 36);
    solver->hanging_slot.resize(solver->hanging.size() * 48 * 48);
    const size_t g1_end = patches + solver->g1.size();
    for (size_t k = 0; k < blocks.size(); ++k)
      block_slots(As, blocks[k],
                  k < static_cast<size_t>(patches) ? &solver->block_slot[k * 48 * 48]
                  : k < g1_end                     ? &solver->g1_slot[(k - patches) * 36 * 36]
                                                   : &solver->hanging_slot[(k - g1_end) * 48 * 48]);
    solver->reduced = std::any_of(out->control_derived.begin(), out->control_derived.end(),
                                  [](const auto& d) { return !d.empty(); });
    if (solver->reduced) {
      std::vector<int> free_index(n, -1);
      int m = 0;
      for (int k = 0; k < n; ++k)
        if (out->control_derived[k].empty()) free_index[k] = m++;
      std::vector<Eigen::Triplet<double>> c1, c3;
      for (int k = 0; k < n; ++k) {
        auto put = [&](int j, double w) {
          c1.emplace_back(k, j, w);
          for (int c = 0; c < 3; ++c) c3.emplace_back(3 * k + c, 3 * j + c, w);
        };
        if (free_index[k] >= 0) put(free_index[k], 1.0);
        for (const auto& [j, w] : out->control_derived[k]) {
          HS_CHECK(free_index[j] >= 0, "patch net: a T-junction's point derived from another derived one");
          put(free_index[j], w);
        }
      }
      solver->C1.resize(n, m);
      solver->C1.setFromTriplets(c1.begin(), c1.end());
      solver->C.resize(3 * n, 3 * m);
      solver->C.setFromTriplets(c3.begin(), c3.end());
      reduction_scatter(solver);
    } else {
      solver->llt.analyzePattern(As);
    }
  }
  std::copy(solver->penalty_values.begin(), solver->penalty_values.end(), As.valuePtr());
  for (int f = 0; f < patches; ++f) {
    const int* slot = &solver->block_slot[static_cast<size_t>(f) * 48 * 48];
    for (int a = 0; a < 48; ++a)
      for (int b = 0; b < 48; ++b) As.valuePtr()[slot[48 * a + b]] += nblock[f](a, b);
  }
  if (normals) {
    const double w = wsum / n * (o.c1_weight + o.fairness) * kG1Weight;
    add_kink_blocks<36>(solver->g1, solver->g1_slot, [&](const G1Border& b) { return g1_block(*out, b, w); }, As.valuePtr());
    add_kink_blocks<48>(solver->hanging, solver->hanging_slot, [&](const HangingBorder& b) { return hanging_block(*out, b, w); },
                        As.valuePtr());
  }
  // The separations' bounds (with the normals only: the first fit's system is one per
  // coordinate, and a bound couples them): the ones crossed by the surface so far are on.
  const bool bounded = normals && !out->separations.empty();
  if (bounded && solver->bounds.empty()) solver->bounds = separation_bounds(*out);
  const double bound_weight = kBoundWeight * wsum / n;
  std::vector<double> unbounded;  // A's values without the bounds' penalties, and R
  const Eigen::VectorXd R_unbounded = bounded ? R : Eigen::VectorXd();
  if (bounded) {
    activate_crossed_bounds(solver, *out);
    unbounded.assign(As.valuePtr(), As.valuePtr() + As.nonZeros());
    add_bound_penalties(*solver, bound_weight, As.valuePtr(), &R);
  }
  const auto reduce = [&](Eigen::VectorXd* rhs) {
    if (!solver->reduced) return;
    if (normals) {
      double* ar = solver->Ar.valuePtr();
      std::fill(ar, ar + solver->Ar.nonZeros(), 0.0);
      const double* a = As.valuePtr();
      for (long p = 0; p < As.nonZeros(); ++p)
        for (int q = solver->scatter_begin[p]; q < solver->scatter_begin[p + 1]; ++q)
          ar[solver->scatter[q].first] += solver->scatter[q].second * a[p];
    }
    *rhs = Eigen::VectorXd(solver->C.transpose() * *rhs);
  };
  reduce(&R);
  Eigen::VectorXd X;
  bool exact = true;  // the first fit and a factored round are direct solves
  if (!normals) {
    // The first fit (no foot point normals yet, no G1 rows) is the same system for x, y and z:
    // A = A₁ ⊗ I₃ (the unknowns interleaved). One factorisation of A₁ (n × n, ~1 ms on the
    // fixture) serves the three coordinates instead of one of A (3n × 3n, ~17 ms).
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(static_cast<size_t>(As.nonZeros()) / 9 + 1);
    for (int c = 0; c < As.outerSize(); c += 3)
      for (Eigen::SparseMatrix<double>::InnerIterator it(As, c); it; ++it)
        if (it.row() % 3 == 0) t.emplace_back(it.row() / 3, c / 3, it.value());
    Eigen::SparseMatrix<double> A1(n, n);
    A1.setFromTriplets(t.begin(), t.end());
    if (solver->reduced) A1 = solver->C1.transpose() * A1 * solver->C1;
    const int m = static_cast<int>(A1.rows());
    NetCholesky llt1(A1);
    HS_CHECK(llt1.info() == Eigen::Success, "patch fit: the normal equations could not be factored");
    const Eigen::MatrixXd X1 = llt1.solve(Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(R.data(), m, 3));
    X.resize(3 * m);
    for (int k = 0; k < m; ++k) X.segment<3>(3 * k) = X1.row(k).transpose();
  } else {
    bool direct = !solver->factored || solver->stalled;
    solver->stalled = false;
    if (!direct) {
      X = solver->x;
      int iterations = 0;
      direct = !preconditioned_cg(solver->system(), solver->llt, R, kCgRoundTolerance, &X, &iterations);
      // Given up within kCgStalled iterations: the matrices still change fast from round to
      // round (the early rounds), so the next round factors without trying.
      solver->stalled = direct && iterations <= kCgStalled;
    }
    if (direct) X = solve_directly(solver, R);
    exact = direct;
  }
  solver->rhs = std::move(R);
  take_solution(out, solver, std::move(X), exact);
  // A control point that crossed its bound in this solve: its bound on, and solved again
  // (directly: the matrix changed), until none does (a few passes: each point's bound is
  // switched on once).
  for (int pass = 0; bounded && pass < kBoundPasses && activate_crossed_bounds(solver, *out); ++pass) {
    std::copy(unbounded.begin(), unbounded.end(), As.valuePtr());
    Eigen::VectorXd Rb = R_unbounded;
    add_bound_penalties(*solver, bound_weight, As.valuePtr(), &Rb);
    reduce(&Rb);
    X = solve_directly(solver, Rb);
    solver->rhs = std::move(Rb);
    take_solution(out, solver, std::move(X), true);
  }
}

// The last system solved again to kCgTolerance (the correction rounds stop theirs at
// kCgRoundTolerance): conjugate gradients from the last solution, else a factorisation.
void polish_net(PatchSkin* out, NetSolver* solver) {
  if (solver->exact) return;
  Eigen::VectorXd X = solver->x;
  int iterations = 0;
  if (!preconditioned_cg(solver->system(), solver->llt, solver->rhs, kCgTolerance, &X, &iterations))
    X = solve_directly(solver, solver->rhs);
  take_solution(out, solver, std::move(X), true);
}

}  // namespace

NetFit::NetFit() : solver_(std::make_unique<NetSolver>()) {}
NetFit::~NetFit() = default;
void NetFit::fit(PatchSkin* out, const LayoutTopology& T, const std::vector<Datum>& data, const PatchOptions& o) {
  fit_net(out, T, data, o, solver_.get());
}
void NetFit::polish(PatchSkin* out) { polish_net(out, solver_.get()); }

}  // namespace handskin::patch_steps
