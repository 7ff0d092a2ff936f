#include "pipeline/patch_report.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "mesh/point_grid.hpp"
#include "render/preview.hpp"

namespace handskin {

namespace {

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) | (static_cast<unsigned char>(in[i + 1]) << 8) |
                       static_cast<unsigned char>(in[i + 2]);
    out += t[v >> 18], out += t[(v >> 12) & 63], out += t[(v >> 6) & 63], out += t[v & 63];
  }
  if (i + 1 == in.size()) {
    const unsigned v = static_cast<unsigned char>(in[i]) << 16;
    out += t[v >> 18], out += t[(v >> 12) & 63], out += "==";
  } else if (i + 2 == in.size()) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) | (static_cast<unsigned char>(in[i + 1]) << 8);
    out += t[v >> 18], out += t[(v >> 12) & 63], out += t[(v >> 6) & 63], out += '=';
  }
  return out;
}

// Error colour: blue (0) → green → yellow → red (at `top` mm and beyond).
Eigen::Vector3f heat(double e, double top) {
  const double x = std::clamp(e / top, 0.0, 1.0);
  const Eigen::Vector3f stops[4] = {{0.15f, 0.3f, 0.85f}, {0.2f, 0.75f, 0.35f}, {0.95f, 0.85f, 0.2f}, {0.85f, 0.1f, 0.1f}};
  const double s = x * 3;
  const int k = std::min(2, static_cast<int>(s));
  const float f = static_cast<float>(s - k);
  return (1 - f) * stops[k] + f * stops[k + 1];
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else o += c;
  }
  return o;
}

}  // namespace

PatchReportFigures patch_report_figures(const PatchSkin& s, int error_grid) {
  const auto t0 = std::chrono::steady_clock::now();
  PatchReportFigures f;
  f.error_grid = error_grid;
  // Table 4.1 the thesis's way: each patch as error_grid² cell samples; a point's error is
  // its distance to the nearest cell sample of its patch around its foot point (±2 cells).
  // One patch's cells at a time (its samples listed first): a thread holds n² cells (240 kB at
  // the default 100), not every patch's at once (23.5 MB for the fixture's 98 patches).
  const int n = error_grid;
  std::vector<std::vector<int>> on_patch(s.patches.size());
  for (size_t k = 0; k < s.samples.size(); ++k)
    if (s.samples[k].patch >= 0) on_patch[s.samples[k].patch].push_back(static_cast<int>(k));
  std::vector<double> d(s.samples.size(), 0);
#pragma omp parallel
  {
    std::vector<Eigen::Vector3d> cells(static_cast<size_t>(n) * n);
#pragma omp for schedule(dynamic)
    for (long q = 0; q < static_cast<long>(s.patches.size()); ++q) {
      if (on_patch[q].empty()) continue;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) cells[static_cast<size_t>(i) * n + j] = s.patches[q].eval((i + 0.5) / n, (j + 0.5) / n);
      for (const int k : on_patch[q]) {
        const auto& x = s.samples[k];
        const int ci = std::clamp(static_cast<int>(x.s * n), 0, n - 1), cj = std::clamp(static_cast<int>(x.t * n), 0, n - 1);
        double best = 1e300;
        for (int i = std::max(0, ci - 2); i <= std::min(n - 1, ci + 2); ++i)
          for (int j = std::max(0, cj - 2); j <= std::min(n - 1, cj + 2); ++j)
            best = std::min(best, (cells[static_cast<size_t>(i) * n + j] - x.p).squaredNorm());
        d[k] = std::sqrt(best);
      }
    }
  }
  std::array<double, 2> sum{};
  std::array<size_t, 2> count{};
  for (size_t k = 0; k < s.samples.size(); ++k) {
    const int side = s.samples[k].side;
    sum[side] += d[k], ++count[side];
    f.cell_max_mm[side] = std::max(f.cell_max_mm[side], d[k]);
  }
  for (int side = 0; side < 2; ++side) f.cell_mean_mm[side] = count[side] ? sum[side] / count[side] : 0;
  // The noise floor: local planes (PCA of the neighbours within 1.5 mm, same scan), every
  // 20th point, RMS of the point's distance to its neighbours' plane.
  for (int side = 0; side < 2; ++side) {
    std::vector<Eigen::Vector3d> pts;
    for (const auto& q : s.samples)
      if (q.side == side) pts.push_back(q.p);
    if (pts.size() < 100) continue;
    const PointGrid hash(pts, 1.5);
    double ss = 0;
    size_t n = 0;
    for (size_t k = 0; k < pts.size(); k += 20) {
      std::vector<int> nb;
      hash.within(pts[k], 1.5, [&](int j) {
        if (j != static_cast<int>(k)) nb.push_back(j);
      });
      if (nb.size() < 8) continue;
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int j : nb) c += pts[j];
      c /= static_cast<double>(nb.size());
      Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
      for (int j : nb) C += (pts[j] - c) * (pts[j] - c).transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
      const double r = es.eigenvectors().col(0).dot(pts[k] - c);
      ss += r * r, ++n;
    }
    f.noise_floor_mm[side] = n ? std::sqrt(ss / n) : 0;
  }
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return f;
}

Json to_json(const PatchReportFigures& f) {
  return {{"error_grid", f.error_grid},
          {"cell_grid_mm", {{"palm", {{"mean", f.cell_mean_mm[0]}, {"max", f.cell_max_mm[0]}}},
                            {"back", {{"mean", f.cell_mean_mm[1]}, {"max", f.cell_max_mm[1]}}}}},
          {"noise_floor_mm", {{"palm", f.noise_floor_mm[0]}, {"back", f.noise_floor_mm[1]}}},
          {"seconds", f.seconds}};
}

namespace {

constexpr double kTop = 0.5;  // the error colours' top, mm

// The data coloured by error, seen from `view` (points of scan `side` only).
std::string error_view(const PatchSkin& s, const Eigen::Matrix3d& hand, int side, const char* view) {
  std::vector<Eigen::Vector3d> p, n;
  std::vector<Eigen::Vector3f> c;
  const size_t count = static_cast<size_t>(
      std::count_if(s.samples.begin(), s.samples.end(), [side](const PatchSkin::Sample& q) { return q.side == side; }));
  p.reserve(count), n.reserve(count), c.reserve(count);
  for (const auto& q : s.samples)
    if (q.side == side) p.push_back(q.p), n.push_back(Eigen::Vector3d::Zero()), c.push_back(heat(q.error, kTop));
  RenderOptions ro;
  ro.width = 720;
  ro.height = 480;
  ro.view = named_view(view) * hand;
  return p.empty() ? std::string() : render_points_png(p, n, c, ro);
}

// The layout: the tessellation's samples, each patch its own colour (a checkerboard); the
// same samples for either view, which turns each normal to face it.
struct LayoutSamples {
  std::vector<Eigen::Vector3d> p, n;  // n: the surface's normal as the patch's (u, v) orient it
  std::vector<Eigen::Vector3f> c;
};

LayoutSamples layout_samples(const PatchSkin& s) {
  LayoutSamples L;
  constexpr int kPerSpan = 36;  // samples per patch side: dense enough for the splats to close
  // Neighbouring patches in different colours: a greedy colouring over the layout's edges.
  const LayoutTopology T = layout_topology(s.layout, "patch layout");
  std::vector<int> colour(s.patches.size(), -1);
  for (size_t f = 0; f < s.patches.size(); ++f) {
    int used = 0;
    for (int g : T.faces_across(static_cast<int>(f)))
      if (colour[g] >= 0) used |= 1 << colour[g];
    colour[f] = 0;
    while (used >> colour[f] & 1) ++colour[f];
  }
  static const Eigen::Vector3f palette[5] = {{0.85f, 0.62f, 0.48f}, {0.55f, 0.68f, 0.85f}, {0.62f, 0.80f, 0.55f},
                                              {0.85f, 0.80f, 0.50f}, {0.75f, 0.60f, 0.82f}};
  // Patches split by the refinement to a tolerance (their names carry "/…") in deeper colours.
  static const Eigen::Vector3f refined[5] = {{0.70f, 0.30f, 0.18f}, {0.20f, 0.38f, 0.72f}, {0.25f, 0.58f, 0.22f},
                                             {0.72f, 0.58f, 0.10f}, {0.52f, 0.25f, 0.65f}};
  const size_t count = s.patches.size() * (kPerSpan + 1) * (kPerSpan + 1);
  L.p.reserve(count), L.n.reserve(count), L.c.reserve(count);
  for (size_t f = 0; f < s.patches.size(); ++f) {
    // By pointer and by value: GCC 12 took `(split ? refined : palette)[i]` for an element of
    // an uninitialised copy of the array, and every patch came out in one colour.
    const Eigen::Vector3f* tones = s.patches[f].name.find('/') != std::string::npos ? refined : palette;
    const Eigen::Vector3f tone = tones[std::min(colour[f], 4)];
    for (int i = 0; i <= kPerSpan; ++i)
      for (int j = 0; j <= kPerSpan; ++j) {
        Eigen::Vector3d S, Su, Sv;
        s.patches[f].derivatives(static_cast<double>(i) / kPerSpan, static_cast<double>(j) / kPerSpan, &S, &Su, &Sv);
        Eigen::Vector3d nn = Su.cross(Sv);
        if (nn.norm() < 1e-12) continue;
        nn.normalize();
        L.p.push_back(S), L.n.push_back(nn);
        L.c.push_back(tone);
      }
  }
  return L;
}

std::string layout_view(const LayoutSamples& L, const Eigen::Matrix3d& hand, const char* view) {
  const Eigen::Matrix3d V = named_view(view) * hand;
  std::vector<Eigen::Vector3d> n = L.n;
  for (Eigen::Vector3d& nn : n)
    if ((V * nn).z() < 0) nn = -nn;  // facing the viewer, for the shading
  RenderOptions ro;
  ro.width = 720;
  ro.height = 480;
  ro.view = V;
  return render_points_png(L.p, n, L.c, ro);
}

std::string img(const std::string& png, const std::string& alt) {
  return png.empty() ? std::string("<p>(no points)</p>")
                     : "<img alt=\"" + alt + "\" src=\"data:image/png;base64," + base64(png) + "\">";
}

std::string row(std::initializer_list<std::string> cells, bool head = false) {
  std::string o = "<tr>";
  for (const auto& c : cells) o += (head ? "<th>" : "<td>") + c + (head ? "</th>" : "</td>");
  return o + "</tr>\n";
}

// Histogram of the foot-point errors, 0–0.5 mm in 0.025 mm bins, the rest in one bin (SVG).
std::string error_histogram_svg(const PatchSkin& s) {
  std::array<std::array<size_t, 21>, 2> hist{};
  for (const auto& q : s.samples) ++hist[q.side][std::min<size_t>(20, static_cast<size_t>(q.error / 0.025))];
  size_t hmax = 1;
  for (const auto& h : hist)
    for (size_t v : h) hmax = std::max(hmax, v);
  std::string svg = "<svg viewBox=\"0 0 640 220\" width=\"640\" height=\"220\" role=\"img\" aria-label=\"error histogram\">";
  for (int side = 0; side < 2; ++side)
    for (int b = 0; b < 21; ++b) {
      const double h = 180.0 * hist[side][b] / hmax;
      svg += "<rect x=\"" + fmt("%.1f", 20 + b * 29.0 + side * 13.0) + "\" y=\"" + fmt("%.1f", 190 - h) +
             "\" width=\"12\" height=\"" + fmt("%.1f", h) + "\" fill=\"" + (side ? "#d9a07a" : "#7f9ed9") + "\"/>";
    }
  for (int b = 0; b <= 20; b += 4)
    svg += "<text x=\"" + fmt("%.0f", 20 + b * 29.0) + "\" y=\"208\" font-size=\"11\">" + fmt("%.2f", b * 0.025) + "</text>";
  svg += "<text x=\"600\" y=\"208\" font-size=\"11\">&gt;0.5</text></svg>";

  return svg;
}

// The quality gates, measured on the outputs as written (pipeline/gates.hpp); a failed one in red.
std::string gates_section(const Json& run_report) {
  std::string h;
  if (!run_report.is_object() || !run_report.contains("gates") || !run_report["gates"].is_array()) return h;
  // Measured on the outputs as written (pipeline/gates.hpp); a failed gate in red.
  h += "<h2>Quality gates</h2>\n<p>Measured on the files as written (skin.ply read back); each limit is a pipeline "
       "key, or fixed for the skin's structure.</p>\n<table>\n" +
       row({"gate", "value", "limit", "unit", "", "measured"}, true);
  for (const auto& g : run_report["gates"]) {
    const bool pass = g.value("pass", false);
    const std::string key = g.contains("key") && g["key"].is_string() ? " (" + g["key"].get<std::string>() + ")" : "";
    h += row({html_escape(g.value("name", "")), fmt("%.4g", g.value("value", 0.0)),
              fmt("%.4g", g.value("limit", 0.0)) + html_escape(key), html_escape(g.value("unit", "")),
              pass ? "pass" : "<b style=\"color:#c00\">FAIL</b>", html_escape(g.value("measure", ""))});
  }
  h += "</table>\n";
  return h;
}

// Table 4.1 per side, beside the thesis's figures, and the error pictures and layout.
std::string table_4_1_section(const PatchStageResult& r) {
  const PatchSkin& s = r.patches;
  const PatchReportFigures& f = r.figures;
  const PatchReportPictures& pics = r.pictures;
  std::string h;
  h += "<h2>Table 4.1: fitting error per side</h2>\n<table>\n";
  h += row({"side", "points", "mean (foot points)", "max (foot points)",
            "mean (" + std::to_string(f.error_grid) + "×" + std::to_string(f.error_grid) + " cells)", "max (cells)",
            "p95", "scanner noise floor", "the thesis: mean / max"},
           true);
  const char* names[2] = {"palm", "back"};
  const char* thesis[2] = {"0.030 / 3.6", "0.027 / 0.43"};
  for (int side = 0; side < 2; ++side) {
    const auto& d = s.side[side];
    h += row({names[side], std::to_string(d.points), fmt("%.3f", d.mean), fmt("%.3f", d.max), fmt("%.3f", f.cell_mean_mm[side]),
              fmt("%.3f", f.cell_max_mm[side]), fmt("%.3f", d.p95), fmt("%.3f", f.noise_floor_mm[side]), thesis[side]});
  }
  h += "</table>\n<p>The thesis (Table 4.1): 96 patches of its own layout, 48 on each scan, fitted each alone (gaps "
       "allowed); its palm's maximum at the thumb's base. Here: " +
       std::to_string(s.patches.size()) + " patches over the closed hand, borders shared.</p>\n";
  if (const auto& rf = s.refinement) {
    h += "<h2>Refinement to " + fmt("%.3g", rf->tolerance_mm) + " mm</h2>\n<table>\n";
    h += row({"fit", "patches", "patches over the tolerance", "worst point (mm)", "fit time (s)"}, true);
    for (size_t k = 0; k < rf->patches.size(); ++k)
      h += row({k == 0 ? std::string("the layout") : "split " + std::to_string(k), std::to_string(rf->patches[k]),
                std::to_string(rf->over[k]), fmt("%.3f", rf->worst_mm[k]),
                k < rf->seconds.size() ? fmt("%.2f", rf->seconds[k]) : std::string("")});
    h += "</table>\n<p>" +
         std::string(rf->held ? "Every patch holds the tolerance." : "Not every patch holds the tolerance: " + rf->stopped + ".") +
         " A patch that missed was split at its midpoints (the same surface), the split carried along its quad strip so "
         "that no border meets a split one (no T-junction), and the net fitted again; the split patches are drawn in deeper "
         "colours in the layout below.</p>\n";
  }
  h += "<h2>The error on the hand</h2>\n<div class=\"bar\" aria-hidden=\"true\"></div><div class=\"ticks\"><span>0</span><span>" +
       fmt("%.2f", kTop / 2) + "</span><span>≥ " + fmt("%.2f", kTop) + " mm</span></div>\n";
  h += "<div class=\"pics\"><figure>" + img(pics.palm_error, "palm-scan points coloured by error, palm view") +
       "<figcaption>palm (palm scan)</figcaption></figure><figure>" +
       img(pics.back_error, "back-scan points coloured by error, back view") +
       "<figcaption>back (back scan)</figcaption></figure></div>\n";
  h += "<h2>Patch layout</h2>\n<div class=\"pics\"><figure>" + img(pics.layout_back, "patch layout, back view") +
       "<figcaption>back</figcaption></figure><figure>" + img(pics.layout_palm, "patch layout, palm view") +
       "<figcaption>palm</figcaption></figure></div>\n";
  return h;
}

// The correction rounds, continuity, the distances to the skin and the truth, the posed skin
// and the run.
std::string fit_sections(const PatchStageResult& r, const std::string& svg, const Json& run_report,
                         const std::vector<ReportPicture>& posed) {
  const PatchSkin& s = r.patches;
  const PatchReportFigures& f = r.figures;
  std::string h;
  h += "<h2>Error histogram</h2>\n<p>Blue: palm scan; orange: back scan; bins of 0.025 mm.</p>\n" + svg + "\n";
  h += "<h2>Parameter correction</h2>\n<p>Each round: every point's foot point on the current surface (Newton), then the "
       "refit, until 99.9 % of the points move less than " + fmt("%.3f", r.options.correction_tolerance) + " mm. Round 0 starts on the first fit; the RMS is the fitted points' distance at that round's foot points.</p>\n<table>\n" + row({"round", "largest foot-point move (mm)", "99.9 % moved less than (mm)", "points reassigned", "RMS (mm)"}, true);
  for (size_t k = 0; k < s.rms_per_round.size(); ++k)
    h += row({std::to_string(k), k < s.max_update_per_round.size() ? fmt("%.4f", s.max_update_per_round[k]) : "–",
              k < s.update_p999_per_round.size() ? fmt("%.4f", s.update_p999_per_round[k]) : "–",
              k < s.reassigned_per_round.size() ? std::to_string(s.reassigned_per_round[k]) : "–",
              fmt("%.4f", s.rms_per_round[k])});
  h += "</table>\n<h2>Continuity</h2>\n<table>\n" + row({"figure", "value"}, true);
  h += row({"G0 gap on shared borders (mm)", fmt("%.2g", s.g0_gap_mm)});
  h += row({"G1 normal jump, median (deg)", fmt("%.3f", s.g1_median_deg)});
  h += row({"G1 normal jump, p95 (deg)", fmt("%.3f", s.g1_p95_deg)});
  h += row({"G1 normal jump, max (deg)", fmt("%.3f", s.g1_max_deg)});
  h += row({"corners where 3, 5 or 6 patches meet", std::to_string(s.irregular_corners)});
  h += row({"G1 jump next to those corners, median / max (deg)",
            fmt("%.2f", s.g1_near_median_deg) + " / " + fmt("%.2f", s.g1_near_max_deg)});
  h += "</table>\n";
  {
    const OneWayDistance& d = r.surface_to_skin;
    auto signed_rings = [](int v) { return (v > 0 ? "+" : "") + std::to_string(v); };
    h += "<h2>Against the polygon skin</h2>\n<p>How far the patches lie from the polygon skin they were laid on "
         "(no truth needed): where they stray from it, a patch bridges what the skin follows.";
    if (s.layout_tries.size() > 1) {
      const auto crossed = [&](size_t k) {
        return k < s.layout_try_crossings.size() && s.layout_try_crossings[k] > 0
                   ? ", " + std::to_string(s.layout_try_crossings[k]) + " pairs of crossing triangles"
                   : std::string();
      };
      const bool folded = !s.layout_try_folds.empty() && s.layout_try_folds[0].first > 30;
      h += " The first layout's patches strayed (p95 of " + fmt("%.2f", s.layout_tries[0].second) +
           " mm over 5 × 5 samples per patch" + crossed(0) +
           (folded ? ", folded by " + fmt("%.0f", s.layout_try_folds[0].first) + "° at " + s.layout_try_folds[0].second
                   : std::string()) +
           "): the palm ring the thumb's base ends at was moved, and where that did not help the base turned round "
           "the palm,";
      const auto turned = [](double deg) {
        return deg == 0 ? std::string() : ", its base turned " + fmt("%.0f", std::abs(deg)) + "° toward the " + (deg > 0 ? "palm" : "back");
      };
      for (size_t k = 1; k < s.layout_tries.size(); ++k)
        h += std::string(k == 1 ? " " : ", ") + signed_rings(s.layout_tries[k].first) + " rings" +
             turned(k < s.layout_try_turns.size() ? s.layout_try_turns[k] : 0.0) + " (" +
             fmt("%.2f", s.layout_tries[k].second) + " mm" + crossed(k) + ")";
      h += "; kept: " + signed_rings(s.thumb_ring_shift) + " rings" + turned(s.thumb_turn_deg) +
           " (the fewest crossings, then one not folded over 30°, then the nearest the skin).";
    }
    if (!s.separations.empty()) {
      h += " Two fingers' tubes passed through each other (" + std::to_string(s.crossings_before_separation) +
           " pairs of crossing triangles, at";
      for (size_t k = 0; k < s.separations.size(); ++k) h += (k ? ", " : " ") + s.separations[k].between;
      h += ": fingers pressed together); the net was fitted again with each pair held apart by the plane through "
           "their shared border.";
    }
    h += "</p>\n<table>\n" + row({"direction", "mean", "p95", "max", "within 1 mm"}, true);
    h += row({"surface → skin", fmt("%.3f", d.mean), fmt("%.3f", d.p95), fmt("%.3f", d.max), fmt("%.2f %%", 100 * d.within_1mm)});
    h += "</table>\n";
  }
  if (r.surface_to_truth) {
    h += "<h2>Against the true skin</h2>\n<table>\n" + row({"direction", "mean", "p95", "max", "within 1 mm"}, true);
    for (const auto& [name, d] : {std::pair<const char*, OneWayDistance>{"surface → truth", *r.surface_to_truth},
                                  {"truth → surface", *r.truth_to_surface}})
      h += row({name, fmt("%.3f", d.mean), fmt("%.3f", d.p95), fmt("%.3f", d.max), fmt("%.2f %%", 100 * d.within_1mm)});
    h += "</table>\n";
  }
  if (!posed.empty()) {
    h += "<h2>The rigged skin, posed</h2>\n<p>skin.glb posed by the solver (docs/rigging.md): smooth (bone-heat) weights with "
         "dual quaternions and the crease guard, and the thesis's rigid binding, which folds the skin into the finger at bent joints.</p>\n"
         "<div class=\"pics\">";
    for (const auto& p : posed)
      h += "<figure>" + img(p.png, html_escape(p.caption)) + "<figcaption>" + html_escape(p.caption) + "</figcaption></figure>";
    h += "</div>\n";
  }
  if (run_report.is_object() && run_report.contains("stages")) {
    h += "<h2>The run</h2>\n<table>\n" + row({"stage", "seconds"}, true);
    for (const auto& st : run_report["stages"])
      h += row({html_escape(st.value("name", "")), fmt("%.3f", st.value("seconds", 0.0))});
    h += "</table>\n";
    for (const auto& st : run_report["stages"])
      if (st.value("name", "") == "registration")
        h += "<p>Registration: " + html_escape(st.value("method", "")) + ", " +
             std::to_string(st.value("markers_matched", 0)) + " markers matched, marker RMS " +
             fmt("%.4f", st.value("refined_rms_mm", 0.0)) + " mm, marker radius " +
             fmt("%.3f", st["marker_radius_mm"].value("value", 0.0)) + " mm" +
             (st.contains("uncertainty") && st["uncertainty"].is_object()
                  ? "; its own error estimate (1σ): rotation " + fmt("%.3f", st["uncertainty"].value("rotation_deg", 0.0)) +
                        "°, skin displacement " + fmt("%.3f", st["uncertainty"].value("displacement_mm", 0.0)) + " mm"
                  : std::string()) +
             ".</p>\n";
  }
  h += "<p>Fit: " + fmt("%.0f", 1000 * s.seconds) + " ms; this report's figures: " + fmt("%.0f", 1000 * f.seconds) +
       " ms. Made by handskin (docs/patches.md).</p>\n</body></html>\n";
  return h;
}

}  // namespace

PatchReportPictures patch_report_pictures(const PatchSkin& s, const Rig& rig) {
  const Eigen::Matrix3d hand = hand_frame_from_rig(rig).linear();
  // The four pictures are independent: drawn at once (the layout's samples made once, for both).
  const LayoutSamples layout = layout_samples(s);
  std::string pics[4];
#pragma omp parallel for schedule(dynamic)
  for (int k = 0; k < 4; ++k)
    pics[k] = k == 0   ? error_view(s, hand, 0, "palm")
              : k == 1 ? error_view(s, hand, 1, "back")
                       : layout_view(layout, hand, k == 2 ? "back" : "palm");
  return {pics[0], pics[1], pics[2], pics[3]};
}

std::string patch_report_html(const PatchStageResult& r, const Json& run_report, const std::vector<ReportPicture>& posed) {
  const PatchSkin& s = r.patches;
  std::string h;
  h += "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>handskin: patch fitting error</title>\n";
  h += "<style>body{font-family:sans-serif;max-width:1500px;margin:1em auto;padding:0 1em;color:#222}"
       "table{border-collapse:collapse;margin:.5em 0 1.2em}td,th{border:1px solid #bbb;padding:.25em .6em;text-align:right}"
       "th{background:#eee}td:first-child,th:first-child{text-align:left}img{max-width:100%;border:1px solid #ccc}"
       ".pics{display:flex;flex-wrap:wrap;gap:1em}.pics figure{margin:0}"
       ".bar{width:360px;height:14px;background:linear-gradient(to right,#264dd9,#33bf59,#f2d933,#d91a1a)}"
       ".ticks{display:flex;justify-content:space-between;width:360px;font-size:.85em}</style></head><body>\n";
  h += "<h1>Bézier patch fitting error</h1>\n";
  h += "<p>" + std::to_string(s.patches.size()) + " bicubic patches, " + std::to_string(s.control_points) +
       " control points over the whole closed hand, neighbours sharing their borders' control points (thesis §4.1.4, Table 4.1). Distances in mm, from the measured points to the surface.</p>\n";
  h += gates_section(run_report);
  h += table_4_1_section(r);
  h += fit_sections(r, error_histogram_svg(s), run_report, posed);
  return h;
}

}  // namespace handskin
