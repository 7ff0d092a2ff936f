#include "posture/evaluate.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "posture/solver.hpp"

namespace handskin {

std::vector<PostureTask> standard_tasks(const std::vector<int>& measured, std::vector<std::string>* skipped) {
  auto col_of = [&](const std::string& name) {
    const int d = dof_index(name).value();
    for (size_t c = 0; c < measured.size(); ++c)
      if (measured[c] == d) return static_cast<int>(c);
    return -1;
  };
  auto is_wrist = [&](int c) { return dofs()[measured[c]].name.rfind("wrist.", 0) == 0; };
  auto ends = [&](int c, const std::string& suffix) {
    const std::string& n = dofs()[measured[c]].name;
    return n.size() >= suffix.size() && n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  const int ncol = static_cast<int>(measured.size());
  std::vector<PostureTask> tasks;
  auto rest_of = [&](const std::vector<int>& given) {
    std::vector<int> out;
    for (int c = 0; c < ncol; ++c)
      if (!is_wrist(c) && std::find(given.begin(), given.end(), c) == given.end()) out.push_back(c);
    return out;
  };
  // One joint → the rest: the middle finger's MCP flexion where measured (the thesis drives
  // one finger and watches the others), else the first measured MCP flexion.
  int one = col_of("middle.mcp.flex");
  for (int c = 0; c < ncol && one < 0; ++c)
    if (ends(c, ".mcp.flex")) one = c;
  if (one >= 0 && !rest_of({one}).empty())
    tasks.push_back({dofs()[measured[one]].name + " -> the rest", {one}, rest_of({one})});
  else if (skipped)
    skipped->push_back("one joint -> the rest: no MCP flexion measured");
  std::vector<int> pips, dips, mcps;
  for (const char* f : {"index", "middle", "ring", "little"}) {
    const int p = col_of(std::string(f) + ".pip.flex"), d = col_of(std::string(f) + ".dip.flex");
    if (p >= 0) pips.push_back(p);
    if (d >= 0) dips.push_back(d);
  }
  if (!pips.empty() && !dips.empty())
    tasks.push_back({"PIPs -> DIPs", pips, dips});
  else if (skipped)
    skipped->push_back("PIPs -> DIPs: the recordings give no separate PIP and DIP flexion");
  for (int c = 0; c < ncol; ++c)
    if (ends(c, ".mcp.flex")) mcps.push_back(c);
  if (mcps.size() >= 2 && !rest_of(mcps).empty())
    tasks.push_back({"MCPs -> the rest", mcps, rest_of(mcps)});
  else if (skipped)
    skipped->push_back("MCPs -> the rest: fewer than two MCP flexions measured");
  return tasks;
}

std::vector<Split> block_splits(const PostureSamples& s, int folds) {
  HS_CHECK(folds >= 2, "block cross-validation needs two or more folds");
  std::vector<std::vector<long>> per_rec(static_cast<size_t>(s.recordings));
  for (long i = 0; i < static_cast<long>(s.recording.size()); ++i) per_rec[s.recording[i]].push_back(i);
  std::vector<Split> out(static_cast<size_t>(folds));
  for (const auto& rows : per_rec)
    for (size_t k = 0; k < rows.size(); ++k) {
      const size_t fold = k * static_cast<size_t>(folds) / rows.size();
      for (int f = 0; f < folds; ++f) (f == static_cast<int>(fold) ? out[f].test : out[f].train).push_back(rows[k]);
    }
  return out;
}

std::vector<Split> recording_splits(const PostureSamples& s) {
  std::vector<Split> out(static_cast<size_t>(s.recordings));
  for (long i = 0; i < static_cast<long>(s.recording.size()); ++i)
    for (int r = 0; r < s.recordings; ++r) (r == s.recording[i] ? out[r].test : out[r].train).push_back(i);
  return out;
}

double TaskErrors::rms(size_t t) const { return cells[t] ? std::sqrt(sse[t] / static_cast<double>(cells[t])) : std::nan(""); }

namespace {

bool all_given(const Eigen::MatrixXd& x, long i, const std::vector<int>& cols) {
  for (int c : cols)
    if (!std::isfinite(x(i, c))) return false;
  return true;
}

TaskErrors zeros(size_t n) { return {std::vector<double>(n, 0.0), std::vector<long>(n, 0)}; }

}  // namespace

TaskErrors model_errors(const PostureSamples& s, const std::vector<PostureTask>& tasks, const std::vector<Split>& splits,
                        const ModelFit& fit) {
  TaskErrors e = zeros(tasks.size());
  for (size_t k = 0; k < splits.size(); ++k) {
    const Split& sp = splits[k];
    if (sp.test.empty() || sp.train.empty()) continue;
    const PostureSolver solver(fit(s.rows(sp.train), k));
    for (size_t t = 0; t < tasks.size(); ++t) {
      PostureInputs in;
      for (long i : sp.test) {
        if (!all_given(s.x, i, tasks[t].given)) continue;
        in.pins.clear();
        for (int c : tasks[t].given) in.pins.emplace_back(s.dofs[c], s.x(i, c));
        const PostureSolution sol = solver.solve(in);
        for (int c : tasks[t].predicted)
          if (std::isfinite(s.x(i, c))) {
            const double d = sol.angles[s.dofs[c]] - s.x(i, c);
            e.sse[t] += d * d;
            ++e.cells[t];
          }
      }
    }
  }
  return e;
}

void baseline_errors(const PostureSamples& s, const std::vector<PostureTask>& tasks, const std::vector<Split>& splits,
                     TaskErrors* mean, TaskErrors* linreg) {
  *mean = zeros(tasks.size());
  *linreg = zeros(tasks.size());
  for (const Split& sp : splits) {
    if (sp.test.empty() || sp.train.empty()) continue;
    for (size_t t = 0; t < tasks.size(); ++t) {
      const auto& g = tasks[t].given;
      const Eigen::Index q = static_cast<Eigen::Index>(g.size()) + 1;
      for (int c : tasks[t].predicted) {
        // Training frames with the given joints and this one: its mean and its regression.
        Eigen::MatrixXd XtX = Eigen::MatrixXd::Zero(q, q);
        Eigen::VectorXd Xty = Eigen::VectorXd::Zero(q), row(q);
        double sum = 0;
        long n = 0, nm = 0;
        for (long i : sp.train) {
          if (!std::isfinite(s.x(i, c))) continue;
          sum += s.x(i, c), ++nm;
          if (!all_given(s.x, i, g)) continue;
          row(0) = 1;
          for (size_t k = 0; k < g.size(); ++k) row(static_cast<Eigen::Index>(k) + 1) = s.x(i, g[k]);
          XtX += row * row.transpose();
          Xty += row * s.x(i, c);
          ++n;
        }
        if (nm == 0) continue;
        const double mu = sum / static_cast<double>(nm);
        Eigen::VectorXd beta = Eigen::VectorXd::Zero(q);
        beta(0) = mu;
        if (n > q) {
          XtX.diagonal().array() += 1e-9 * (1 + XtX.diagonal().maxCoeff());
          beta = XtX.ldlt().solve(Xty);
        }
        for (long i : sp.test) {
          if (!all_given(s.x, i, g) || !std::isfinite(s.x(i, c))) continue;
          row(0) = 1;
          for (size_t k = 0; k < g.size(); ++k) row(static_cast<Eigen::Index>(k) + 1) = s.x(i, g[k]);
          const double dm = mu - s.x(i, c), dl = row.dot(beta) - s.x(i, c);
          mean->sse[t] += dm * dm, ++mean->cells[t];
          linreg->sse[t] += dl * dl, ++linreg->cells[t];
        }
      }
    }
  }
}

}  // namespace handskin
