#include "posture/calibrate.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "core/errors.hpp"

namespace handskin {

bool CalibrationOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(min_correlation >= 0 && min_correlation <= 1)) return bad("min_correlation must be in [0, 1]");
  if (max_pairs < 0 || max_pairs > 100) return bad("max_pairs must be in [0, 100]");
  if (weights != "thesis" && weights != "inverse") return bad("weights must be 'thesis' or 'inverse'");
  if (grid_cells < 4 || grid_cells > 1000) return bad("grid_cells must be in [4, 1000]");
  if (!(grid_weight > 0 && grid_weight <= kMaxWeight)) return bad("grid_weight must be in (0, 1e3]");
  for (const auto& [a, b] : pairs)
    if (a == b) return bad("a pair needs two different DOFs (got " + dofs()[a].name + " twice)");
  if (!(limit_margin_deg <= kMaxAngle)) return bad("limit_margin_deg must be in [0, 1000]");
  if (max_grid_samples < 1) return bad("max_grid_samples must be >= 1");
  if (!(limit_margin_deg >= 0)) return bad("limit_margin_deg must be >= 0");
  if (min_rows < 3) return bad("min_rows must be >= 3");
  return true;
}

namespace {

std::string fmt(const char* f, double a, double b = 0, double c = 0, double d = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c, d);
  return buf;
}

struct Column {
  std::vector<double> v;  ///< per row, NaN = missing
  size_t n = 0;
};

// Rows where both columns have a value.
void common(const Column& a, const Column& b, std::vector<double>* x, std::vector<double>* y) {
  x->clear();
  y->clear();
  for (size_t i = 0; i < a.v.size(); ++i)
    if (std::isfinite(a.v[i]) && std::isfinite(b.v[i])) x->push_back(a.v[i]), y->push_back(b.v[i]);
}

double correlation(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double mx = 0, my = 0;
  for (size_t i = 0; i < x.size(); ++i) mx += x[i], my += y[i];
  mx /= n, my /= n;
  double sxx = 0, syy = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i)
    sxx += (x[i] - mx) * (x[i] - mx), syy += (y[i] - my) * (y[i] - my), sxy += (x[i] - mx) * (y[i] - my);
  return (sxx > 0 && syy > 0) ? sxy / std::sqrt(sxx * syy) : 0.0;
}

}  // namespace

PostureModel calibrate(const AngleTable& t, const CalibrationOptions& o, const std::string& file, Json* report) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("calibration options", err);
  PostureModel m;
  m.name = "calibrated";
  m.description = "Calibrated from " + file + " (" + std::to_string(t.rows.size()) + " rows)";
  m.dof = default_dof_params();

  std::map<int, Column> cols;
  for (size_t c = 0; c < t.columns.size(); ++c) {
    Column col;
    for (const auto& row : t.rows) {
      col.v.push_back(row[c]);
      if (std::isfinite(row[c])) ++col.n;
    }
    cols[t.columns[c]] = std::move(col);
  }
  size_t usable = 0;
  for (const auto& row : t.rows) {
    int given = 0;
    for (double v : row) given += std::isfinite(v);
    if (given >= 2) ++usable;
  }
  if (static_cast<long>(usable) < o.min_rows)
    throw InputError(file, "only " + std::to_string(usable) + " rows with two or more angles; calibration needs at least " +
                               std::to_string(o.min_rows));

  Json rep;
  rep["rows"] = t.rows.size();
  Json cover = Json::object(), widened = Json::array();
  // --- relaxed posture (median) and limits that cover the data ---
  for (auto& [d, col] : cols) {
    if (static_cast<long>(col.n) < o.min_rows) continue;  // too few values: keep the defaults
    std::vector<double> v;
    for (double x : col.v)
      if (std::isfinite(x)) v.push_back(x);
    std::sort(v.begin(), v.end());
    DofParams& p = m.dof[d];
    const double lo = v.front(), hi = v.back(), median = v[v.size() / 2];
    if (lo < p.lo || hi > p.hi) {
      const double nlo = std::min(p.lo, lo - o.limit_margin_deg), nhi = std::max(p.hi, hi + o.limit_margin_deg);
      const std::string note = dofs()[d].name + fmt(": limits widened from [%.1f, %.1f] to [%.1f, %.1f]", p.lo, p.hi, nlo, nhi) +
                               fmt(" to cover the data (min %.1f, max %.1f)", lo, hi);
      m.notes.push_back(note);
      widened.push_back(note);
      p.lo = nlo;
      p.hi = nhi;
    }
    p.relaxed = median;
    cover[dofs()[d].name] = {{"values", col.n}, {"min", lo}, {"max", hi}, {"relaxed_median", median}};
  }
  rep["dofs"] = cover;
  rep["widened_limits"] = widened;

  // --- pairs: given, or the most correlated ---
  std::vector<std::pair<int, int>> pairs = o.pairs;
  std::vector<double> x, y;
  if (pairs.empty()) {
    std::vector<std::tuple<double, int, int>> cand;
    for (auto a = cols.begin(); a != cols.end(); ++a)
      for (auto b = std::next(a); b != cols.end(); ++b) {
        common(a->second, b->second, &x, &y);
        if (static_cast<long>(x.size()) < o.min_rows) continue;
        const double r = correlation(x, y);
        if (std::abs(r) >= o.min_correlation) cand.emplace_back(-std::abs(r), a->first, b->first);
      }
    std::sort(cand.begin(), cand.end());
    for (size_t k = 0; k < cand.size() && static_cast<int>(pairs.size()) < o.max_pairs; ++k)
      pairs.emplace_back(std::get<1>(cand[k]), std::get<2>(cand[k]));
    if (pairs.empty())
      m.notes.push_back(fmt("no DOF pair correlates with |r| >= %.2f: the model has springs only", o.min_correlation));
  }
  struct Fit {
    PairLine line;
    double r, spread;
    size_t n;
  };
  std::vector<Fit> fits;
  for (const auto& [a, b] : pairs) {
    const std::string name = dofs()[a].name + " / " + dofs()[b].name;
    if (!cols.count(a) || !cols.count(b)) throw InputError(file, "pair " + name + ": a DOF is not in the table");
    common(cols[a], cols[b], &x, &y);
    if (static_cast<long>(x.size()) < o.min_rows)
      throw InputError(file, "pair " + name + ": only " + std::to_string(x.size()) + " rows give both angles (need " +
                                 std::to_string(o.min_rows) + ")");
    // Least-squares line in the sense of the thesis's l_i (the Euclidean distance of a data
    // point to the line): total least squares, the normal is the covariance's minor axis.
    const double n = static_cast<double>(x.size());
    double mx = 0, my = 0;
    for (size_t i = 0; i < x.size(); ++i) mx += x[i], my += y[i];
    mx /= n, my /= n;
    Eigen::Matrix2d C = Eigen::Matrix2d::Zero();
    for (size_t i = 0; i < x.size(); ++i) {
      const Eigen::Vector2d d(x[i] - mx, y[i] - my);
      C += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(C);
    Eigen::Vector2d nrm = es.eigenvectors().col(0);
    if (nrm(1) > 0) nrm = -nrm;  // β < 0: the line reads θ_b = slope·θ_a + c
    Fit f;
    f.line.a = a;
    f.line.b = b;
    f.line.alpha = nrm(0);
    f.line.beta = nrm(1);
    f.line.gamma = -(nrm(0) * mx + nrm(1) * my);
    f.spread = std::max(es.eigenvalues()(0) / n, 1e-9);  // Σ l_i² / n
    f.r = correlation(x, y);
    f.n = x.size();
    fits.push_back(f);
  }
  double max_w = 0;
  for (auto& f : fits) {
    f.line.weight = o.weights == "thesis" ? f.spread : 1.0 / f.spread;
    max_w = std::max(max_w, f.line.weight);
  }
  Json pr = Json::array();
  for (auto& f : fits) {
    f.line.weight /= max_w;  // eq. 3.18: normalised by the largest
    f.line.source = fmt("calibration: r = %.3f, n = %.0f, spread %.2f deg rms", f.r, static_cast<double>(f.n), std::sqrt(f.spread));
    m.pairs.push_back(f.line);
    const bool vertical = std::abs(f.line.beta) < 1e-9;
    pr.push_back({{"a", dofs()[f.line.a].name},
                  {"b", dofs()[f.line.b].name},
                  {"r", f.r},
                  {"n", f.n},
                  {"slope", vertical ? Json(nullptr) : Json(-f.line.alpha / f.line.beta)},
                  {"intercept", vertical ? Json(nullptr) : Json(-f.line.gamma / f.line.beta)},
                  {"spread_rms_deg", std::sqrt(f.spread)},
                  {"weight", f.line.weight}});
  }
  rep["pairs"] = pr;
  rep["weights"] = o.weights;

  // --- optional non-linear grids: the measured samples of each pair, thinned ---
  if (o.grids) {
    for (const auto& f : fits) {
      common(cols[f.line.a], cols[f.line.b], &x, &y);
      std::set<std::pair<long, long>> seen;
      PairGrid g;
      g.a = f.line.a;
      g.b = f.line.b;
      g.weight = o.grid_weight;
      g.cells = o.grid_cells;
      for (size_t i = 0; i < x.size(); ++i)
        if (seen.insert({std::lround(x[i]), std::lround(y[i])}).second) g.samples.push_back({x[i], y[i]});
      if (static_cast<int>(g.samples.size()) > o.max_grid_samples) {
        std::vector<std::array<double, 2>> kept;
        const double step = static_cast<double>(g.samples.size()) / o.max_grid_samples;
        for (int k = 0; k < o.max_grid_samples; ++k) kept.push_back(g.samples[static_cast<size_t>(k * step)]);
        g.samples = kept;
      }
      const auto [xa0, xa1] = std::minmax_element(x.begin(), x.end());
      const auto [ya0, ya1] = std::minmax_element(y.begin(), y.end());
      const double pa = std::max(5.0, 0.1 * (*xa1 - *xa0)), pb = std::max(5.0, 0.1 * (*ya1 - *ya0));
      g.lo_a = *xa0 - pa, g.hi_a = *xa1 + pa, g.lo_b = *ya0 - pb, g.hi_b = *ya1 + pb;
      m.grids.push_back(std::move(g));
    }
    rep["grids"] = m.grids.size();
  }
  for (const auto& l : m.pairs)
    HS_CHECK(std::isfinite(l.alpha) && std::isfinite(l.beta) && std::isfinite(l.gamma) && std::isfinite(l.weight),
             "calibration produced a non-finite line");
  if (report) *report = rep;
  // What calibration writes, its own loader must read: the same checks, by a round trip
  // (limits widened beyond ±360, a degenerate fit, ...) refuse the table here, not later.
  parse_model(model_to_json(m), file + " (the calibrated model)");
  return m;
}

}  // namespace handskin
