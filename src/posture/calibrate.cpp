#include "posture/calibrate.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>
#include <functional>
#include <set>

#include "core/errors.hpp"
#include "posture/evaluate.hpp"
#include "posture/gaussian.hpp"
#include "posture/solver.hpp"

namespace handskin {

bool CalibrationOptions::IsValid(std::string* error) const {
  if (!(min_correlation >= 0 && min_correlation <= 1)) return invalid(error, "min_correlation must be in [0, 1]");
  if (max_pairs < 0 || max_pairs > 100) return invalid(error, "max_pairs must be in [0, 100]");
  if (weights != "thesis" && weights != "inverse") return invalid(error, "weights must be 'thesis' or 'inverse'");
  if (grid_cells < 4 || grid_cells > 1000) return invalid(error, "grid_cells must be in [4, 1000]");
  if (!(grid_weight > 0 && grid_weight <= kMaxWeight)) return invalid(error, "grid_weight must be in (0, 1e3]");
  for (const auto& [a, b] : pairs)
    if (a == b) return invalid(error, "a pair needs two different DOFs (got " + dofs()[a].name + " twice)");
  if (!(limit_margin_deg <= kMaxAngle)) return invalid(error, "limit_margin_deg must be in [0, 1000]");
  if (max_grid_samples < 1) return invalid(error, "max_grid_samples must be >= 1");
  if (!(limit_margin_deg >= 0)) return invalid(error, "limit_margin_deg must be >= 0");
  if (min_rows < 3) return invalid(error, "min_rows must be >= 3");
  if (method != "gaussian" && method != "mixture" && method != "thesis-pairs")
    return invalid(error, "method must be 'gaussian', 'mixture' or 'thesis-pairs'");
  if (offsets != "auto" && offsets != "remove" && offsets != "keep") return invalid(error, "offsets must be 'auto', 'remove' or 'keep'");
  if (!(shrinkage < 0 || shrinkage <= 1)) return invalid(error, "shrinkage must be in [0, 1] (or negative: chosen by cross-validation)");
  if (components != 0 && (components < 2 || components > kMaxMixtureComponents))
    return invalid(error, "components must be 0 (chosen) or in [2, " + std::to_string(kMaxMixtureComponents) + "]");
  if (folds < 2 || folds > 50) return invalid(error, "folds must be in [2, 50]");
  if (method != "thesis-pairs" && (grids || !pairs.empty()))
    return invalid(error, "pairs and grids belong to the thesis's pairwise calibration: add --method thesis-pairs");
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

// Whether the values vary at all (a joint held still gives the same number in every row).
bool varies(const std::vector<double>& v) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return lo != v.end() && *hi - *lo > 1e-9;
}

double correlation(const std::vector<double>& x, const std::vector<double>& y) {
  // A constant column correlates with nothing: its deviations from the computed mean are the
  // mean's rounding, the same in every row, and would give r = ±1 with any other such column.
  if (!varies(x) || !varies(y)) return 0.0;
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

namespace {

using Columns = std::map<int, Column>;

// The table's columns by DOF, with their value counts.
Columns table_columns(const AngleTable& t) {
  std::map<int, Column> cols;
  for (size_t c = 0; c < t.columns.size(); ++c) {
    Column col;
    for (const auto& row : t.rows) {
      col.v.push_back(row[c]);
      if (std::isfinite(row[c])) ++col.n;
    }
    cols[t.columns[c]] = std::move(col);
  }
  return cols;
}

// --- relaxed posture (median) and limits that cover the data (report: "dofs", "widened_limits") ---
void relaxed_and_limits(const Columns& cols, const CalibrationOptions& o, PostureModel* mp, Json* rep) {
  PostureModel& m = *mp;
  Json cover = Json::object(), widened = Json::array();
  for (const auto& [d, col] : cols) {
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
  (*rep)["dofs"] = cover;
  (*rep)["widened_limits"] = widened;

}

// --- pairs: given, or the most correlated ---
std::vector<std::pair<int, int>> choose_pairs(const Columns& cols, const CalibrationOptions& o, PostureModel* m) {
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
      m->notes.push_back(fmt("no DOF pair correlates with |r| >= %.2f: the model has springs only", o.min_correlation));
  }
  return pairs;
}

struct Fit {
  PairLine line;
  double r, spread;
  size_t n;
};

// Each pair's least-squares line in the sense of the thesis's l_i.
std::vector<Fit> fit_pair_lines(Columns& cols, const std::vector<std::pair<int, int>>& pairs,
                                const CalibrationOptions& o, const std::string& file) {
  std::vector<double> x, y;
  std::vector<Fit> fits;
  for (const auto& [a, b] : pairs) {
    const std::string name = dofs()[a].name + " / " + dofs()[b].name;
    if (!cols.count(a) || !cols.count(b)) throw InputError(file, "pair " + name + ": a DOF is not in the table");
    common(cols[a], cols[b], &x, &y);
    if (static_cast<long>(x.size()) < o.min_rows)
      throw InputError(file, "pair " + name + ": only " + std::to_string(x.size()) + " rows give both angles (need " +
                                 std::to_string(o.min_rows) + ")");
    if (!varies(x) || !varies(y))
      throw InputError(file, "pair " + name + ": " + dofs()[varies(x) ? b : a].name +
                                 " has the same value in every row that gives both angles: no line to fit");
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
  return fits;
}

// The lines' weights (eq. 3.18), normalised by the largest, into the model (report: "pairs").
void weigh_lines(std::vector<Fit>* fits, const CalibrationOptions& o, PostureModel* mp, Json* rep) {
  PostureModel& m = *mp;
  double max_w = 0;
  for (auto& f : *fits) {
    f.line.weight = o.weights == "thesis" ? f.spread : 1.0 / f.spread;
    max_w = std::max(max_w, f.line.weight);
  }
  Json pr = Json::array();
  for (auto& f : *fits) {
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
  (*rep)["pairs"] = pr;
  (*rep)["weights"] = o.weights;

}

// --- optional non-linear grids: the measured samples of each pair, thinned ---
void pair_grids(Columns& cols, const std::vector<Fit>& fits, const CalibrationOptions& o, PostureModel* mp) {
  PostureModel& m = *mp;
  std::vector<double> x, y;
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
}

}  // namespace

// Thesis §3.2.2–3.2.3 on one (merged) table: `--method thesis-pairs`.
PostureModel calibrate_pairs(const AngleTable& t, const CalibrationOptions& o, const std::string& file, Json* report) {
  PostureModel m;
  m.name = "calibrated";
  m.description = "Calibrated from " + file + " (" + std::to_string(t.rows.size()) + " rows)";
  m.dof = default_dof_params();
  Columns cols = table_columns(t);
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
  relaxed_and_limits(cols, o, &m, &rep);
  const std::vector<std::pair<int, int>> pairs = choose_pairs(cols, o, &m);
  std::vector<Fit> fits = fit_pair_lines(cols, pairs, o, file);
  weigh_lines(&fits, o, &m, &rep);
  if (o.grids) {
    pair_grids(cols, fits, o, &m);
    rep["grids"] = m.grids.size();
  }
  for (const auto& l : m.pairs)
    HS_CHECK(std::isfinite(l.alpha) && std::isfinite(l.beta) && std::isfinite(l.gamma) && std::isfinite(l.weight),
             "calibration produced a non-finite line");
  if (report) *report = rep;
  return m;
}

namespace {

constexpr double kShrinkGrid[] = {0.0, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3};
constexpr int kComponentGrid[] = {2, 3, 4, 6, 8};
constexpr double kAngleCap = 180;  ///< a joint angle beyond ±180° is drift: clamped, never a limit

// All tables in one: the union of their columns, rows one after the other.
AngleTable merged(const std::vector<AngleTable>& tables, std::vector<int>* recording) {
  AngleTable out;
  for (const auto& t : tables)
    for (int d : t.columns)
      if (std::find(out.columns.begin(), out.columns.end(), d) == out.columns.end()) out.columns.push_back(d);
  for (size_t r = 0; r < tables.size(); ++r)
    for (size_t i = 0; i < tables[r].rows.size(); ++i) {
      std::vector<double> row(out.columns.size(), std::nan(""));
      for (size_t c = 0; c < tables[r].columns.size(); ++c) {
        const size_t k = std::find(out.columns.begin(), out.columns.end(), tables[r].columns[c]) - out.columns.begin();
        row[k] = tables[r].rows[i][c];
      }
      out.rows.push_back(std::move(row));
      out.lines.push_back(tables[r].lines.empty() ? 0 : tables[r].lines[i]);
      recording->push_back(static_cast<int>(r));
    }
  return out;
}

AngleTable as_table(const PostureSamples& s) {
  AngleTable t;
  t.columns = s.dofs;
  for (Eigen::Index i = 0; i < s.x.rows(); ++i) {
    t.rows.emplace_back();
    for (Eigen::Index c = 0; c < s.x.cols(); ++c) t.rows.back().push_back(s.x(i, c));
  }
  return t;
}

struct GaussianChoice {
  bool remove_offsets = true;
  double shrinkage = 0.01;
};

// The linear (single Gaussian) model on these samples: springs and synergy rows for the
// measured DOFs, their mean as the rest posture; DOFs the samples lack keep the base's
// springs and rest, and the anatomical lines among them only (a line that touched a measured
// DOF would change its fitted statistics).
PostureModel gaussian_model(const PostureModel& base, const PostureSamples& s, const GaussianStats& st, double* scale_out = nullptr,
                            const GaussianMixtureFit* mix = nullptr) {
  PostureModel m = base;
  std::vector<Eigen::MatrixXd> covs{st.cov};
  if (mix) covs.insert(covs.end(), mix->cov.begin(), mix->cov.end());
  const double scale = energy_scale_for(covs);
  const std::vector<double> k = factor_precision(st.cov, st.mean, s.dofs, scale, "Gaussian calibration", &m.constraints);
  for (size_t c = 0; c < s.dofs.size(); ++c) {
    DofParams& p = m.dof[s.dofs[c]];
    p.stiffness = k[c];
    p.relaxed = std::clamp(st.mean(static_cast<Eigen::Index>(c)), p.lo, p.hi);
  }
  for (const PairLine& l : builtin_model("anatomical").pairs)
    if (std::find(s.dofs.begin(), s.dofs.end(), l.a) == s.dofs.end() && std::find(s.dofs.begin(), s.dofs.end(), l.b) == s.dofs.end()) {
      PairLine line = l;
      line.source = "anatomical (not measured): " + l.source;
      m.pairs.push_back(line);
    }
  if (mix) {
    m.mixture.energy_scale = scale;
    double total = 0;
    for (double w : mix->weight) total += w;
    for (size_t c = 0; c < mix->weight.size(); ++c) {
      MixtureComponent comp;
      comp.weight = mix->weight[c] / total;
      const std::vector<double> kc = factor_precision(mix->cov[c], mix->mean[c], s.dofs, scale,
                                                      "mixture component " + std::to_string(c + 1), &comp.constraints);
      for (size_t i = 0; i < s.dofs.size(); ++i) {
        const DofParams& p = m.dof[s.dofs[i]];
        comp.relaxed.emplace_back(s.dofs[i], std::clamp(mix->mean[c](static_cast<Eigen::Index>(i)), p.lo, p.hi));
        comp.stiffness.emplace_back(s.dofs[i], kc[i]);
      }
      m.mixture.components.push_back(std::move(comp));
    }
  }
  if (scale_out) *scale_out = scale;
  return m;
}

PostureModel mixture_model(const PostureModel& base, const PostureSamples& s, const GaussianChoice& g, const GaussianStats& moments,
                           int C, int* iterations = nullptr) {
  const GaussianStats st = shrink_stats(moments, g.shrinkage);
  const GaussianMixtureFit f = fit_mixture(s, st, g.remove_offsets, C, g.shrinkage);
  if (iterations) *iterations = f.iterations;
  return gaussian_model(base, s, st, nullptr, &f);
}

// The moments of each split's training rows, per offsets choice, computed once: shrinkage
// candidates, mixture candidates and the final evaluation all start from them.
class MomentCache {
 public:
  MomentCache(const PostureSamples& s, long min_pair) : s_(s), min_pair_(min_pair) {}
  const GaussianStats& get(const std::vector<Split>* splits, size_t k, bool remove_offsets, const PostureSamples& train) {
    const auto key = std::make_tuple(static_cast<const void*>(splits), k, remove_offsets);
    auto it = cache_.find(key);
    if (it == cache_.end()) it = cache_.emplace(key, gaussian_moments(train, remove_offsets, min_pair_)).first;
    return it->second;
  }
  const GaussianStats& all(bool remove_offsets) { return get(nullptr, 0, remove_offsets, s_); }

 private:
  const PostureSamples& s_;
  long min_pair_;
  std::map<std::tuple<const void*, size_t, bool>, GaussianStats> cache_;
};

// How a candidate ranks: the mean and the worst over the tasks of its held-out RMS over the
// linear regression's, averaged — a candidate that beats the regression on most tasks but
// loses on one does not win on the mean alone.
double score(const TaskErrors& model, const TaskErrors& linreg) {
  double sum = 0, worst = 0;
  int n = 0;
  for (size_t t = 0; t < model.sse.size(); ++t)
    if (model.cells[t] && linreg.cells[t] && linreg.rms(t) > 0) {
      const double r = model.rms(t) / linreg.rms(t);
      sum += r, worst = std::max(worst, r), ++n;
    }
  return n ? 0.5 * (sum / n + worst) : std::nan("");
}

Json json_number(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

Json cv_json(const std::vector<PostureTask>& tasks, const PostureSamples& s, const TaskErrors& model, const TaskErrors& mean,
             const TaskErrors& linreg, const TaskErrors* linear_model) {
  Json out = Json::array();
  for (size_t t = 0; t < tasks.size(); ++t) {
    Json given = Json::array(), pred = Json::array();
    for (int c : tasks[t].given) given.push_back(dofs()[s.dofs[c]].name);
    for (int c : tasks[t].predicted) pred.push_back(dofs()[s.dofs[c]].name);
    Json j = {{"task", tasks[t].name},          {"given", given},
              {"predicted", pred},              {"cells", model.cells[t]},
              {"model_rms_deg", json_number(model.rms(t))},
              {"mean_posture_rms_deg", json_number(mean.rms(t))},
              {"linear_regression_rms_deg", json_number(linreg.rms(t))},
              {"model_over_regression", json_number(model.rms(t) / linreg.rms(t))}};
    if (linear_model) j["linear_model_rms_deg"] = json_number(linear_model->rms(t));
    out.push_back(j);
  }
  return out;
}

}  // namespace

namespace {

// The measured columns of the merged table: enough values, not constant; values clamped into
// the model's limits (report: "dofs_not_used", "frames", "frames_complete",
// "values_clamped_to_limits").
PostureSamples measured_samples(const AngleTable& all, const std::vector<int>& rec, int recordings,
                                const PostureModel& m, const CalibrationOptions& o, Json* rep) {
  PostureSamples s;
  s.recordings = recordings;
  s.recording = rec;
  std::vector<size_t> keep;
  Json unused = Json::array();
  for (size_t c = 0; c < all.columns.size(); ++c) {
    double lo = 1e300, hi = -1e300;
    long n = 0;
    for (const auto& row : all.rows)
      if (std::isfinite(row[c])) lo = std::min(lo, row[c]), hi = std::max(hi, row[c]), ++n;
    if (n >= o.min_rows && hi - lo > 1e-9) keep.push_back(c), s.dofs.push_back(all.columns[c]);
    else unused.push_back(dofs()[all.columns[c]].name);
  }
  (*rep)["dofs_not_used"] = unused;
  s.x.resize(static_cast<Eigen::Index>(all.rows.size()), static_cast<Eigen::Index>(keep.size()));
  long clamped = 0, complete = 0;
  for (size_t i = 0; i < all.rows.size(); ++i) {
    bool full = true;
    for (size_t k = 0; k < keep.size(); ++k) {
      double v = all.rows[i][keep[k]];
      if (std::isfinite(v)) {
        const DofParams& p = m.dof[s.dofs[k]];
        const double c = std::clamp(v, p.lo, p.hi);
        clamped += c != v;
        v = c;
      } else {
        full = false;
      }
      s.x(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k)) = v;
    }
    complete += full;
  }
  (*rep)["frames"] = all.rows.size();
  (*rep)["frames_complete"] = complete;
  (*rep)["values_clamped_to_limits"] = clamped;
  return s;
}

// One calibration's state: the samples, the tasks, the held-out schemes and the errors and
// moments computed so far (each once).
class Calibration {
 public:
  using FitFor = std::function<ModelFit(const std::vector<Split>&)>;

  Calibration(const PostureSamples& s, const std::vector<PostureTask>& tasks, const PostureModel& base,
              const CalibrationOptions& o)
      : s(s), tasks(tasks), base(base), o(o), moments(s, o.min_rows) {}

  // Held-out errors per (scheme, model), computed once: the selection's figures are reused
  // by the report.
  const TaskErrors& errors(const std::vector<Split>& splits, const std::string& key, const FitFor& fit_for) {
    const auto k = std::make_pair(static_cast<const void*>(&splits), key);
    auto it = done.find(k);
    if (it == done.end()) it = done.emplace(k, model_errors(s, tasks, splits, fit_for(splits))).first;
    return it->second;
  }
  FitFor gaussian_fit(const GaussianChoice& c) {
    return [this, c](const std::vector<Split>& splits) -> ModelFit {
      return [this, c, sp = &splits](const PostureSamples& tr, size_t k) {
        return gaussian_model(base, tr, shrink_stats(moments.get(sp, k, c.remove_offsets, tr), c.shrinkage));
      };
    };
  }
  FitFor mixture_fit(const GaussianChoice& c, int C) {
    return [this, c, C](const std::vector<Split>& splits) -> ModelFit {
      return [this, c, C, sp = &splits](const PostureSamples& tr, size_t k) {
        return mixture_model(base, tr, c, moments.get(sp, k, c.remove_offsets, tr), C);
      };
    };
  }
  static std::string key_of(const GaussianChoice& c) {
    return fmt("gaussian %g ", c.shrinkage) + (c.remove_offsets ? "remove" : "keep");
  }

  const PostureSamples& s;
  const std::vector<PostureTask>& tasks;
  const PostureModel& base;
  const CalibrationOptions& o;
  MomentCache moments;

 private:
  std::map<std::pair<const void*, std::string>, TaskErrors> done;
};

// The model the calibration ends with, and how to fit it again on a split's training rows.
struct Chosen {
  Calibration::FitFor fit;
  std::string fit_key, linear_key;
  GaussianChoice g;
};

// Shrinkage and offsets: given, or the candidate with the best held-out score relative to the
// linear regression; the Gaussian model of the whole table with them (report: "selection",
// "offsets", "shrinkage", "gaussian", "dofs_used").
Chosen choose_gaussian(Calibration& cal, const std::vector<Split>& select, const TaskErrors& sel_linreg, bool several,
                       const std::string& label, size_t rows, PostureModel* mp, Json* rep) {
  const CalibrationOptions& o = cal.o;
  const PostureSamples& s = cal.s;
  const std::vector<PostureTask>& tasks = cal.tasks;
  PostureModel& m = *mp;
  Chosen ch;
  GaussianChoice& g = ch.g;
  std::vector<GaussianChoice> cands;
  const std::vector<bool> offs = o.offsets == "auto" ? (several ? std::vector<bool>{true, false} : std::vector<bool>{true})
                                                    : std::vector<bool>{o.offsets == "remove"};
  for (bool off : offs) {
    if (o.shrinkage >= 0) cands.push_back({off, o.shrinkage});
    else
      for (double r : kShrinkGrid) cands.push_back({off, r});
  }
  Json sel = Json::array();
  double best = 1e300;
  g = cands.front();
  if (cands.size() > 1 && !select.empty() && !tasks.empty()) {
    for (const auto& c : cands) {
      const double sc = score(cal.errors(select, Calibration::key_of(c), cal.gaussian_fit(c)), sel_linreg);
      sel.push_back({{"offsets", c.remove_offsets ? "remove" : "keep"}, {"shrinkage", c.shrinkage}, {"score", json_number(sc)}});
      if (sc < best) best = sc, g = c;
    }
  } else if (o.shrinkage < 0) {
    g.shrinkage = 0.01;
    m.notes.push_back("no standard task to cross-validate on: shrinkage 0.01, not chosen");
  }
  rep->erase("pairs");
  rep->erase("weights");
  (*rep)["selection"] = {{"scheme", several ? "leave one recording out" : "held-out blocks"},
                      {"score", "(mean + worst) / 2 over the tasks of model RMS / linear regression RMS"},
                      {"candidates", sel}};
  (*rep)["offsets"] = g.remove_offsets ? "removed per recording" : "kept";
  (*rep)["shrinkage"] = g.shrinkage;
  const GaussianStats st = shrink_stats(cal.moments.all(g.remove_offsets), g.shrinkage);
  double scale = 1;
  PostureModel lin = gaussian_model(cal.base, s, st, &scale);
  Json syn = Json::array();
  for (const auto& c : lin.constraints) syn.push_back({{"weight", c.weight}, {"source", c.source}});
  (*rep)["gaussian"] = {{"dofs", s.dofs.size()},
                     {"energy_scale", scale},
                     {"floored_eigenvalues", st.floored_eigenvalues},
                     {"synergy_rows", syn}};
  Json cover = Json::object();
  for (size_t c = 0; c < s.dofs.size(); ++c) {
    long n = 0;
    for (Eigen::Index i = 0; i < s.x.rows(); ++i) n += std::isfinite(s.x(i, static_cast<Eigen::Index>(c)));
    cover[dofs()[s.dofs[c]].name] = {{"values", n}, {"mean", st.mean(static_cast<Eigen::Index>(c))},
                                     {"sd", std::sqrt(st.cov(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(c)))}};
  }
  (*rep)["dofs_used"] = cover;
  lin.name = "calibrated";
  lin.description = "Gaussian calibration from " + label + " (" + std::to_string(rows) + " rows, " +
                    std::to_string(s.dofs.size()) + " DOFs, shrinkage " + fmt("%g", g.shrinkage) + ")";
  m = lin;
  ch.fit = cal.gaussian_fit(g);
  ch.fit_key = ch.linear_key = Calibration::key_of(g);
  return ch;
}

// Components: given, or chosen by the same held-out score; eligible only if no task gets
// worse than with the single Gaussian (report: "mixture").
void choose_mixture(Calibration& cal, const std::vector<Split>& select, const TaskErrors& sel_linreg,
                    const std::string& label, size_t rows, Chosen* ch, PostureModel* mp, Json* rep) {
  const CalibrationOptions& o = cal.o;
  const PostureSamples& s = cal.s;
  const std::vector<PostureTask>& tasks = cal.tasks;
  PostureModel& m = *mp;
  const GaussianChoice& g = ch->g;
  std::vector<int> comps;
  if (o.components) comps.push_back(o.components);
  else
    for (int c : kComponentGrid) comps.push_back(c);
  const long m_cols = static_cast<long>(s.dofs.size());
  comps.erase(std::remove_if(comps.begin(), comps.end(), [&](int c) { return s.x.rows() < 4L * c * (m_cols + 1); }), comps.end());
  Json mx = Json::array();
  int chosen = 1;
  if (!select.empty() && !tasks.empty()) {
    const TaskErrors& lin_err = cal.errors(select, ch->linear_key, cal.gaussian_fit(g));
    double best_mx = score(lin_err, sel_linreg);
    for (int c : comps) {
      const TaskErrors& e = cal.errors(select, "mixture " + std::to_string(c), cal.mixture_fit(g, c));
      bool no_worse = true;
      for (size_t t = 0; t < tasks.size(); ++t) no_worse = no_worse && !(e.rms(t) > lin_err.rms(t));
      const double sc = score(e, sel_linreg);
      mx.push_back({{"components", c}, {"score", json_number(sc)}, {"no_task_worse_than_linear", no_worse}});
      if (no_worse && sc < best_mx) best_mx = sc, chosen = c;
    }
  }
  Json mrep = {{"candidates", mx}, {"components", chosen}};
  if (chosen > 1) {
    int its = 0;
    m = mixture_model(cal.base, s, g, cal.moments.all(g.remove_offsets), chosen, &its);
    m.description = "Mixture of " + std::to_string(chosen) + " Gaussians from " + label + " (" + std::to_string(rows) +
                    " rows, " + std::to_string(s.dofs.size()) + " DOFs)";
    mrep["em_iterations"] = its;
    ch->fit = cal.mixture_fit(g, chosen);
    ch->fit_key = "mixture " + std::to_string(chosen);
  } else {
    m.notes.push_back("mixture: no number of components beat the single Gaussian on held-out frames; the linear model is kept");
  }
  (*rep)["mixture"] = mrep;
}

// The model's held-out errors on every scheme, beside the mean posture's and the linear
// regression's (report: "cross_validation").
void cross_validate(Calibration& cal, const Chosen& ch, const std::vector<Split>& blocks,
                    const std::vector<Split>& leave_out, const PostureModel& m, Json* rep) {
  const CalibrationOptions& o = cal.o;
  const PostureSamples& s = cal.s;
  const std::vector<PostureTask>& tasks = cal.tasks;
  Json cv = Json::object();
  auto scheme = [&](const std::vector<Split>& splits, const char* name, Json extra) {
    if (splits.empty()) return;
    TaskErrors mean, linreg;
    baseline_errors(s, tasks, splits, &mean, &linreg);
    const TaskErrors& model = cal.errors(splits, ch.fit_key, ch.fit);
    const TaskErrors* linear = nullptr;
    if (!m.mixture.components.empty()) linear = &cal.errors(splits, ch.linear_key, cal.gaussian_fit(ch.g));
    extra["tasks"] = cv_json(tasks, s, model, mean, linreg, linear);
    cv[name] = extra;
  };
  scheme(blocks, "blocks", {{"folds", o.folds}});
  scheme(leave_out, "recordings", {{"folds", leave_out.size()}});
  (*rep)["cross_validation"] = cv;
}

}  // namespace

PostureModel calibrate(const std::vector<AngleTable>& tables, const std::vector<std::string>& files,
                       const CalibrationOptions& o, Json* report) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("calibration options", err);
  HS_CHECK(!tables.empty() && tables.size() == files.size(), "calibrate needs one name per table");
  // Angles are in degrees. A recording whose every angle lies within ±π over many rows is in
  // radians (a hand that moves no joint by more than 3° gives nothing to calibrate either):
  // taken as degrees it would calibrate a hand that barely moves, and every solve would be wrong.
  for (size_t r = 0; r < tables.size(); ++r) {
    double largest = 0;
    size_t values = 0;
    for (const auto& row : tables[r].rows)
      for (double v : row)
        if (std::isfinite(v)) largest = std::max(largest, std::abs(v)), ++values;
    if (tables[r].rows.size() >= static_cast<size_t>(std::max<long>(o.min_rows, 20)) && values > 0 && largest <= M_PI + 1e-9)
      throw InputError(files[r], "every angle lies within ±π (the largest is " + std::to_string(largest) +
                                     "): radians? Joint-angle tables are in degrees (multiply by 57.2958)");
  }
  std::vector<int> rec;
  const AngleTable all = merged(tables, &rec);
  std::string label = files[0];
  for (size_t r = 1; r < files.size(); ++r) label += ", " + files[r];
  Json rep;
  PostureModel m = calibrate_pairs(all, o, label, &rep);  // also the checks, limits and coverage
  rep["method"] = o.method;
  Json recs = Json::array();
  for (size_t r = 0; r < tables.size(); ++r) recs.push_back({{"file", files[r]}, {"rows", tables[r].rows.size()}});
  rep["recordings"] = recs;
  const PostureSamples s = measured_samples(all, rec, static_cast<int>(tables.size()), m, o, &rep);
  if (s.dofs.size() < 2 && (o.method != "thesis-pairs" || o.pairs.empty()))
    throw InputError(label, "fewer than two DOFs have " + std::to_string(o.min_rows) + " or more varying values; nothing to correlate");

  std::vector<std::string> skipped;
  const std::vector<PostureTask> tasks = standard_tasks(s.dofs, &skipped);
  rep["tasks_skipped"] = skipped;
  const bool several = tables.size() >= 2;
  std::vector<Split> blocks, leave_out;
  bool blocks_ok = true;
  for (size_t r = 0; r < tables.size(); ++r) blocks_ok = blocks_ok && tables[r].rows.size() >= static_cast<size_t>(4 * o.folds);
  if (blocks_ok) blocks = block_splits(s, o.folds);
  if (several) leave_out = recording_splits(s);
  const std::vector<Split>& select = several ? leave_out : blocks;
  TaskErrors sel_mean, sel_linreg;
  if (!select.empty() && !tasks.empty()) baseline_errors(s, tasks, select, &sel_mean, &sel_linreg);

  PostureModel base;  // limits and defaults from the pairs pass, none of its lines
  base.name = "calibrated";
  base.description = m.description;
  base.dof = default_dof_params();
  for (int d : s.dofs) base.dof[d] = m.dof[d];
  for (int d = 0; d < kDofCount; ++d) base.dof[d].lo = m.dof[d].lo, base.dof[d].hi = m.dof[d].hi;
  base.notes = m.notes;

  Calibration cal(s, tasks, base, o);
  Chosen ch;
  if (o.method == "thesis-pairs") {
    ch.fit = [&](const std::vector<Split>&) -> ModelFit {
      return [&](const PostureSamples& train, size_t) { return calibrate_pairs(as_table(train), o, label, nullptr); };
    };
    ch.fit_key = "thesis-pairs";
  } else {
    ch = choose_gaussian(cal, select, sel_linreg, several, label, all.rows.size(), &m, &rep);
    if (o.method == "mixture") choose_mixture(cal, select, sel_linreg, label, all.rows.size(), &ch, &m, &rep);
  }
  if (o.evaluate && !tasks.empty()) cross_validate(cal, ch, blocks, leave_out, m, &rep);
  for (const auto& n : base.notes)
    if (std::find(m.notes.begin(), m.notes.end(), n) == m.notes.end()) m.notes.push_back(n);
  if (report) *report = rep;
  // What calibration writes, its own loader must read: the same checks, by a round trip
  // (limits widened beyond ±360, a degenerate fit, ...) refuse the table here, not later.
  parse_model(model_to_json(m), label + " (the calibrated model)");
  return m;
}

PostureModel calibrate(const AngleTable& table, const CalibrationOptions& options, const std::string& file, Json* report) {
  return calibrate({table}, {file}, options, report);
}

}  // namespace handskin
