#include "posture/gaussian.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>

#include "core/errors.hpp"

// Why by hand: the statistics with gaps (pairwise-complete moments, per-recording offsets),
// the factoring into springs and synergy rows, and EM over completed frames are a few dozen
// lines of Eigen each. mlpack's GMM (Debian's libmlpack-dev) would fit the mixture but not
// the gaps or the offsets, and would add a large dependency for one EM loop.

namespace handskin {

PostureSamples PostureSamples::rows(const std::vector<long>& keep) const {
  PostureSamples o;
  o.dofs = dofs;
  o.recordings = recordings;
  o.x.resize(static_cast<Eigen::Index>(keep.size()), x.cols());
  o.recording.reserve(keep.size());
  for (size_t i = 0; i < keep.size(); ++i) {
    o.x.row(static_cast<Eigen::Index>(i)) = x.row(keep[i]);
    o.recording.push_back(recording[keep[i]]);
  }
  return o;
}

namespace {

// Per recording and column: mean over the frames that have the value (NaN: none), and the
// pooled mean weighted by the counts.
void recording_means(const PostureSamples& s, Eigen::MatrixXd* rec_mean, Eigen::VectorXd* mean) {
  const Eigen::Index m = s.x.cols();
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(s.recordings, m), cnt = Eigen::MatrixXd::Zero(s.recordings, m);
  for (Eigen::Index i = 0; i < s.x.rows(); ++i)
    for (Eigen::Index c = 0; c < m; ++c)
      if (std::isfinite(s.x(i, c))) sum(s.recording[i], c) += s.x(i, c), cnt(s.recording[i], c) += 1;
  *rec_mean = Eigen::MatrixXd::Constant(s.recordings, m, std::nan(""));
  *mean = Eigen::VectorXd::Zero(m);
  for (Eigen::Index c = 0; c < m; ++c) {
    double total = 0, n = 0;
    for (int r = 0; r < s.recordings; ++r)
      if (cnt(r, c) > 0) (*rec_mean)(r, c) = sum(r, c) / cnt(r, c), total += sum(r, c), n += cnt(r, c);
    HS_CHECK(n > 0, "a posture column without values");
    (*mean)(c) = total / n;
  }
}

// Values about their offsets: each recording's own mean (remove_offsets) or the pooled mean.
Eigen::MatrixXd centred(const PostureSamples& s, bool remove_offsets, Eigen::VectorXd* mean) {
  Eigen::MatrixXd rec_mean;
  recording_means(s, &rec_mean, mean);
  Eigen::MatrixXd z = s.x;
  for (Eigen::Index i = 0; i < z.rows(); ++i)
    for (Eigen::Index c = 0; c < z.cols(); ++c)
      if (std::isfinite(z(i, c))) z(i, c) -= remove_offsets ? rec_mean(s.recording[i], c) : (*mean)(c);
  return z;
}

// Symmetric positive definite with every eigenvalue at least floor; counts the raised ones.
Eigen::MatrixXd floored(const Eigen::MatrixXd& S, double floor, int* raised) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
  Eigen::VectorXd ev = es.eigenvalues();
  for (Eigen::Index k = 0; k < ev.size(); ++k)
    if (!(ev(k) >= floor)) ev(k) = floor, ++*raised;
  const Eigen::MatrixXd out = es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
  return 0.5 * (out + out.transpose());
}

Eigen::MatrixXd shrunk(const Eigen::MatrixXd& S, double shrink) {
  Eigen::MatrixXd out = (1 - shrink) * S;
  out.diagonal() = S.diagonal();
  return out;
}

}  // namespace

GaussianStats gaussian_stats(const PostureSamples& s, bool remove_offsets, double shrink, long min_pair, double floor_deg) {
  return shrink_stats(gaussian_moments(s, remove_offsets, min_pair, floor_deg), shrink, floor_deg);
}

GaussianStats shrink_stats(const GaussianStats& moments, double shrink, double floor_deg) {
  HS_CHECK(shrink >= 0 && shrink <= 1, "shrinkage must be in [0, 1]");
  GaussianStats g = moments;
  g.cov = floored(shrunk(moments.cov, shrink), floor_deg * floor_deg, &g.floored_eigenvalues);
  return g;
}

GaussianStats gaussian_moments(const PostureSamples& s, bool remove_offsets, long min_pair, double floor_deg) {
  HS_CHECK(s.x.cols() <= 64, "at most 64 posture columns");
  GaussianStats g;
  const Eigen::MatrixXd z = centred(s, remove_offsets, &g.mean);
  const Eigen::Index m = z.cols(), n = z.rows();
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(m, m);
  g.pair_counts = Eigen::MatrixXi::Zero(m, m);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index a = 0; a < m; ++a) {
      if (!std::isfinite(z(i, a))) continue;
      for (Eigen::Index b = a; b < m; ++b)
        if (std::isfinite(z(i, b))) S(a, b) += z(i, a) * z(i, b), g.pair_counts(a, b) += 1;
    }
  for (Eigen::Index a = 0; a < m; ++a)
    for (Eigen::Index b = a; b < m; ++b) {
      const long cnt = g.pair_counts(a, b);
      S(a, b) = cnt >= std::max(2L, a == b ? 2L : min_pair) ? S(a, b) / cnt : 0.0;
      S(b, a) = S(a, b);
      g.pair_counts(b, a) = g.pair_counts(a, b);
    }
  const double floor = floor_deg * floor_deg;
  int raised = 0;
  // Pairwise-complete moments need not form a positive semi-definite matrix: the floor
  // repairs that. They are only the start: frames with gaps are then completed by EM (the
  // maximum-likelihood Gaussian of what was measured, Little & Rubin 2002, ch. 11), the
  // gaps' conditional covariance included. Pairwise statistics alone were 2-4 % worse than
  // a regression on complete frames on the shared recording's held-out blocks.
  S = floored(S, floor, &raised);
  std::vector<std::uint64_t> pattern(static_cast<size_t>(n), 0);
  bool gaps = false;
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index c = 0; c < m; ++c)
      if (!std::isfinite(z(i, c))) pattern[i] |= std::uint64_t{1} << c, gaps = true;
  if (gaps) {
    // Per recording (or pooled) means are re-estimated with the completed frames.
    const int groups = remove_offsets ? s.recordings : 1;
    Eigen::MatrixXd mu = Eigen::MatrixXd::Zero(groups, m);  // about the first centring
    // The frames of each gap pattern, grouped once: the conditional regression is per pattern.
    std::map<std::uint64_t, std::vector<Eigen::Index>> groups_of;
    for (Eigen::Index i = 0; i < n; ++i) groups_of[pattern[i]].push_back(i);
    for (int it = 0; it < 100; ++it) {
      Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(groups, m), S2 = Eigen::MatrixXd::Zero(m, m);
      Eigen::VectorXd count = Eigen::VectorXd::Zero(groups);
      for (const auto& [pat, members] : groups_of) {
        if (pat == (m == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << m) - 1)) continue;  // nothing measured
        std::vector<Eigen::Index> o, mi;
        for (Eigen::Index c = 0; c < m; ++c) ((pat >> c) & 1 ? mi : o).push_back(c);
        Eigen::MatrixXd Soo(o.size(), o.size()), Smo(mi.size(), o.size()), Smm(mi.size(), mi.size());
        for (size_t a = 0; a < o.size(); ++a)
          for (size_t b = 0; b < o.size(); ++b) Soo(a, b) = S(o[a], o[b]);
        for (size_t a = 0; a < mi.size(); ++a) {
          for (size_t b = 0; b < o.size(); ++b) Smo(a, b) = S(mi[a], o[b]);
          for (size_t b = 0; b < mi.size(); ++b) Smm(a, b) = S(mi[a], mi[b]);
        }
        Eigen::MatrixXd B = Eigen::MatrixXd::Zero(mi.size(), o.size());  // regression of the gaps on the rest
        Eigen::MatrixXd Cm = Smm;
        if (!o.empty()) {
          B = Soo.llt().solve(Smo.transpose()).transpose();
          Cm -= B * Smo.transpose();
        }
        long rows_here = 0;
        Eigen::VectorXd xo(o.size()), xm(mi.size());
        for (const Eigen::Index i : members) {
          const int gi = remove_offsets ? s.recording[i] : 0;
          for (size_t a = 0; a < o.size(); ++a) xo(a) = z(i, o[a]) - mu(gi, o[a]);
          xm = B * xo;
          Eigen::VectorXd full(m);
          for (size_t a = 0; a < o.size(); ++a) full(o[a]) = z(i, o[a]);
          for (size_t a = 0; a < mi.size(); ++a) full(mi[a]) = xm(a) + mu(gi, mi[a]);
          sum.row(gi) += full.transpose();
          count(gi) += 1;
          const Eigen::VectorXd d = full - mu.row(gi).transpose();
          S2 += d * d.transpose();
          ++rows_here;
        }
        for (size_t a = 0; a < mi.size(); ++a)
          for (size_t b = 0; b < mi.size(); ++b) S2(mi[a], mi[b]) += static_cast<double>(rows_here) * Cm(a, b);
      }
      if (count.sum() < 2) break;
      // The deviations were taken about the old means: correct them to the new ones.
      Eigen::MatrixXd mu_new = mu;
      for (int gi = 0; gi < groups; ++gi)
        if (count(gi) > 0) {
          mu_new.row(gi) = sum.row(gi) / count(gi);
          const Eigen::VectorXd shift = (mu_new.row(gi) - mu.row(gi)).transpose();
          S2 -= count(gi) * shift * shift.transpose();
        }
      S2 /= count.sum();
      S2 = floored(0.5 * (S2 + S2.transpose()), floor, &raised);
      const double change = (S2 - S).norm() / std::max(1e-12, S.norm()) + (mu_new - mu).norm();
      S = S2;
      mu = mu_new;
      if (change < 1e-7) break;
    }
    // The pooled mean moves with the completed frames too (weighted by the groups' sizes).
    Eigen::VectorXd shift = Eigen::VectorXd::Zero(m);
    double total = 0;
    for (int gi = 0; gi < groups; ++gi) {
      double cnt = 0;
      for (Eigen::Index i = 0; i < n; ++i) cnt += (remove_offsets ? s.recording[i] : 0) == gi;
      shift += cnt * mu.row(gi).transpose();
      total += cnt;
    }
    g.mean += shift / std::max(1.0, total);
  }
  g.cov = S;
  return g;
}

namespace {
// ½ λ_min(D^-½ P D^-½) · P_ii per column: the springs at scale 1 (P = cov⁻¹).
Eigen::VectorXd unit_springs(const Eigen::MatrixXd& cov, Eigen::MatrixXd* P_out = nullptr) {
  const Eigen::Index m = cov.rows();
  const Eigen::MatrixXd P = cov.llt().solve(Eigen::MatrixXd::Identity(m, m));
  const Eigen::VectorXd isd = P.diagonal().cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd N = isd.asDiagonal() * P * isd.asDiagonal();
  const double lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(N, Eigen::EigenvaluesOnly).eigenvalues()(0);
  if (P_out) *P_out = P;
  return 0.5 * lambda * P.diagonal();
}
}  // namespace

double energy_scale_for(const std::vector<Eigen::MatrixXd>& covs) {
  HS_CHECK(!covs.empty(), "energy scale of no covariance");
  const Eigen::MatrixXd P = covs[0].llt().solve(Eigen::MatrixXd::Identity(covs[0].rows(), covs[0].cols()));
  std::vector<double> d(P.diagonal().data(), P.diagonal().data() + P.rows());
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  double scale = 1.0 / d[d.size() / 2];
  for (const auto& c : covs) scale = std::max(scale, 1.0001 * kMinStiffness / unit_springs(c).minCoeff());
  return scale;
}

std::vector<double> factor_precision(const Eigen::MatrixXd& cov, const Eigen::VectorXd& mean, const std::vector<int>& dofs,
                                     double scale, const std::string& source, std::vector<LinearConstraint>* rows) {
  const Eigen::Index m = cov.rows();
  Eigen::MatrixXd P;
  const Eigen::VectorXd k1 = unit_springs(cov, &P);
  P *= scale;
  std::vector<double> k(static_cast<size_t>(m));
  Eigen::MatrixXd R = P;
  for (Eigen::Index i = 0; i < m; ++i) {
    // Lowering a spring keeps R positive semi-definite; the scale keeps it above the floor.
    k[i] = std::clamp(k1(i) * scale, kMinStiffness, kMaxStiffness);
    R(i, i) -= k[i];
  }
  // R = P − K is positive semi-definite (K ≤ ½λ_min of the normalised precision); its eigen
  // directions are the constraint rows.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (R + R.transpose()));
  const double top = es.eigenvalues().maxCoeff();
  for (Eigen::Index e = m - 1; e >= 0; --e) {  // strongest first
    double w = es.eigenvalues()(e);
    if (!(w > 1e-9 * top)) continue;
    Eigen::VectorXd a = es.eigenvectors().col(e);
    Eigen::Index big;
    a.cwiseAbs().maxCoeff(&big);
    if (a(big) < 0) a = -a;  // a definite sign, so that the same data writes the same file
    const double sd = std::sqrt(a.dot(cov * a));
    if (w > kMaxWeight) a *= std::sqrt(w / kMaxWeight), w = kMaxWeight;
    LinearConstraint c;
    for (Eigen::Index i = 0; i < m; ++i)
      if (a(i) != 0) c.terms.emplace_back(dofs[i], a(i));
    c.offset = -a.dot(mean);
    c.weight = w;
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s: synergy %d of %d, %.2f deg sd along it", source.c_str(), static_cast<int>(m - e),
                  static_cast<int>(m), sd);
    c.source = buf;
    rows->push_back(std::move(c));
  }
  return k;
}

GaussianMixtureFit fit_mixture(const PostureSamples& s, const GaussianStats& single, bool remove_offsets, int C, double shrink,
                               unsigned seed, int max_iterations, double floor_deg, long max_frames) {
  HS_CHECK(C >= 1 && C <= kMaxMixtureComponents, "mixture components out of range");
  GaussianMixtureFit f;
  // Every frame complete and about the pooled mean: offsets removed as in the single fit,
  // gaps filled by the single Gaussian's conditional mean.
  Eigen::VectorXd mean;
  Eigen::MatrixXd X = centred(s, remove_offsets, &mean);
  if (X.rows() > max_frames) {  // every k-th frame, k = ⌈n / max_frames⌉
    const Eigen::Index k = (X.rows() + max_frames - 1) / max_frames;
    Eigen::MatrixXd kept((X.rows() + k - 1) / k, X.cols());
    for (Eigen::Index i = 0; i < kept.rows(); ++i) kept.row(i) = X.row(i * k);
    X = kept;
  }
  const Eigen::Index m = X.cols(), n = X.rows();
  HS_CHECK(n >= C * (m + 1), "too few frames for the mixture");
  for (Eigen::Index i = 0; i < n; ++i) {
    std::vector<Eigen::Index> have, miss;
    for (Eigen::Index c = 0; c < m; ++c) (std::isfinite(X(i, c)) ? have : miss).push_back(c);
    if (!miss.empty()) {
      ++f.imputed_frames;
      Eigen::VectorXd fill = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(miss.size()));
      if (!have.empty()) {
        Eigen::MatrixXd Shh(have.size(), have.size()), Smh(miss.size(), have.size());
        Eigen::VectorXd zh(have.size());
        for (size_t a = 0; a < have.size(); ++a) {
          zh(a) = X(i, have[a]);
          for (size_t b = 0; b < have.size(); ++b) Shh(a, b) = single.cov(have[a], have[b]);
          for (size_t b = 0; b < miss.size(); ++b) Smh(b, a) = single.cov(miss[b], have[a]);
        }
        fill = Smh * Shh.llt().solve(zh);
      }
      for (size_t b = 0; b < miss.size(); ++b) X(i, miss[b]) = fill(b);
    }
    X.row(i) += mean.transpose();
  }
  // k-means++ start.
  std::mt19937 rng(seed);
  std::vector<Eigen::VectorXd> centre;
  centre.push_back(X.row(std::uniform_int_distribution<Eigen::Index>(0, n - 1)(rng)).transpose());
  Eigen::VectorXd d2 = Eigen::VectorXd::Constant(n, 1e300);
  while (static_cast<int>(centre.size()) < C) {
    for (Eigen::Index i = 0; i < n; ++i) d2(i) = std::min(d2(i), (X.row(i).transpose() - centre.back()).squaredNorm());
    double r = std::uniform_real_distribution<double>(0, d2.sum())(rng);
    Eigen::Index pick = n - 1;
    for (Eigen::Index i = 0; i < n; ++i)
      if ((r -= d2(i)) <= 0) {
        pick = i;
        break;
      }
    centre.push_back(X.row(pick).transpose());
  }
  Eigen::MatrixXd resp = Eigen::MatrixXd::Zero(n, C);
  for (Eigen::Index i = 0; i < n; ++i) {
    int best = 0;
    double bd = 1e300;
    for (int c = 0; c < C; ++c) {
      const double d = (X.row(i).transpose() - centre[c]).squaredNorm();
      if (d < bd) bd = d, best = c;
    }
    resp(i, best) = 1;
  }
  const double floor = floor_deg * floor_deg;
  f.weight.assign(C, 0);
  f.mean.assign(C, Eigen::VectorXd::Zero(m));
  f.cov.assign(C, Eigen::MatrixXd::Identity(m, m));
  double last = -1e300;
  for (int it = 1; it <= max_iterations; ++it) {
    f.iterations = it;
    // M step (from the current responsibilities).
    for (int c = 0; c < C; ++c) {
      const double nc = resp.col(c).sum() + 1e-9;
      f.weight[c] = nc / static_cast<double>(n);
      f.mean[c] = X.transpose() * resp.col(c) / nc;
      const Eigen::MatrixXd D = X.rowwise() - f.mean[c].transpose();
      Eigen::MatrixXd S = D.transpose() * resp.col(c).asDiagonal() * D / nc;
      // A component with few frames leans on the single Gaussian's shape.
      const double t = std::min(1.0, static_cast<double>(m + 1) / nc);
      S = (1 - t) * S + t * single.cov;
      int raised = 0;
      f.cov[c] = floored(shrunk(S, shrink), floor, &raised);
    }
    // E step.
    Eigen::MatrixXd logp(n, C);
    for (int c = 0; c < C; ++c) {
      const Eigen::LLT<Eigen::MatrixXd> llt(f.cov[c]);
      const Eigen::MatrixXd L = llt.matrixL();
      const double half_logdet = L.diagonal().array().log().sum();
      const Eigen::MatrixXd Y = L.triangularView<Eigen::Lower>().solve((X.rowwise() - f.mean[c].transpose()).transpose());
      logp.col(c) = (-0.5 * Y.colwise().squaredNorm().array() - half_logdet + std::log(f.weight[c])).matrix().transpose();
    }
    double ll = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double top = logp.row(i).maxCoeff();
      const Eigen::ArrayXd e = (logp.row(i).array() - top).exp();
      const double sum = e.sum();
      resp.row(i) = (e / sum).matrix().transpose();
      ll += top + std::log(sum);
    }
    ll /= static_cast<double>(n);
    f.log_likelihood = ll - 0.5 * static_cast<double>(m) * std::log(2 * M_PI);
    if (std::abs(ll - last) < 1e-7 * std::max(1.0, std::abs(ll))) break;
    last = ll;
  }
  return f;
}

}  // namespace handskin
