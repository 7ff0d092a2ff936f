#include "register/registration.hpp"

#include <algorithm>
#include <exception>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/parallel_jobs.hpp"
#include "core/transform.hpp"
#include "scan/cloud.hpp"
#include "scan/cloud_file.hpp"

namespace handskin {

bool RegistrationOptions::IsValid(std::string* error) const {
  if (!prepare.IsValid(error) || !spheres.IsValid(error) || !refine.IsValid(error)) return false;
  if (expected_markers < 3) return invalid(error, "expected_markers must be >= 3");
  if (estimate_radius && radius_candidates_mm.empty()) return invalid(error, "radius_candidates_mm must not be empty");
  for (double rc : radius_candidates_mm)
    if (!(rc >= 1 && rc <= 20)) return invalid(error, "radius_candidates_mm must lie in [1, 20]");
  if (!(match_tolerance_mm > 0 && match_tolerance_mm <= 10)) return invalid(error, "match_tolerance_mm must be in (0, 10]");
  if (!(accept_residual_mm >= 0 && accept_residual_mm <= 10)) return invalid(error, "accept_residual_mm must be in [0, 10]");
  if (!(marker_clearance_mm >= 0 && marker_clearance_mm <= 10)) return invalid(error, "marker_clearance_mm must be in [0, 10]");
  if (!(warn_rotation_sigma_deg > 0 && warn_rotation_sigma_deg <= 10)) return invalid(error, "warn_rotation_sigma_deg must be in (0, 10]");
  if (!(warn_displacement_sigma_mm > 0 && warn_displacement_sigma_mm <= 10))
    return invalid(error, "warn_displacement_sigma_mm must be in (0, 10]");
  return true;
}

MarkerHints load_marker_hints(const std::string& file) {
  const Json j = load_json_object(file);
  if (get_string(j, "format", file) != "handskin-markers/1")
    throw InputError(file, "key 'format' must be \"handskin-markers/1\"");
  reject_unknown_keys(j, {"format", "description", "back", "palm"}, file, "");
  MarkerHints h;
  h.file = file;
  for (const char* side : {"back", "palm"}) {
    if (!j.contains(side)) continue;
    if (!j[side].is_array()) throw InputError(file, std::string("key '") + side + "' must be an array of [x, y, z]");
    std::vector<Eigen::Vector3d> v;
    for (size_t k = 0; k < j[side].size(); ++k)
      v.push_back(to_vec3(j[side][k], std::string(side) + "[" + std::to_string(k) + "]", file));
    if (v.size() < 3) throw InputError(file, std::string("key '") + side + "' lists fewer than 3 markers");
    if (v.size() > 30) throw InputError(file, std::string("key '") + side + "' lists more than 30 markers");
    (std::string(side) == "back" ? h.back : h.palm) = v;
  }
  if (!h.back && !h.palm) throw InputError(file, "neither 'back' nor 'palm' is given");
  return h;
}

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

template <typename... Args>
std::string fmt(const char* f, Args... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

std::string where(const Eigen::Vector3d& p) { return fmt("(%.1f, %.1f, %.1f)", p.x(), p.y(), p.z()); }

// Samples that are not within (radius + clearance) of any of `centres` (scan frame).
std::vector<char> skin_mask(const PreparedScan& s, const std::vector<Eigen::Vector3d>& centres, double reach) {
  std::vector<char> skin(s.points.size(), 1);
  for (size_t k = 0; k < s.points.size(); ++k)
    for (const auto& c : centres)
      if ((s.points[k] - c).squaredNorm() < reach * reach) {
        skin[k] = 0;
        break;
      }
  return skin;
}

// Markers of one scan: fitted at the hint file's positions for this side, else detected (the
// strongest expected + 6). Fills the side's marker fields of `d`.
void find_markers(const PreparedScan& s, const RegistrationOptions& o,
                  const std::optional<std::vector<Eigen::Vector3d>>& hints, const std::string& hints_file,
                  const std::string& scan_file, ScanRegistrationDetail* d) {
  std::vector<SphereFit> found;
  if (hints) {
    for (size_t k = 0; k < hints->size(); ++k) {
      std::string why;
      auto f = fit_sphere_near(s, (*hints)[k], o.spheres.hint_search_mm, o.spheres, &why);
      if (!f)
        throw InputError(hints_file, std::string(side_name(s.side)) + "[" + std::to_string(k) + "] at " +
                                         where((*hints)[k]) + ": " + why);
      f->manual = true;
      found.push_back(std::move(*f));
    }
    d->manual_markers = true;
  } else {
    std::vector<SphereCandidateReport> cands;
    found = detect_spheres(s, o.spheres, &cands);
    d->candidates_examined = cands.size();
    for (auto& c : cands)
      if (!c.rejected_because.empty() && d->rejected.size() < 20) d->rejected.push_back(std::move(c));
  }
  if (found.size() < 3)
    throw InputError(scan_file, "found " + std::to_string(found.size()) + " marker sphere(s) of radius " +
                                    fmt("%.2f", o.spheres.radius_mm) +
                                    (o.estimate_radius ? " mm (estimated from the scans)" : " mm (markers.radius_mm)") +
                                    ", need at least 3 (set markers.radius_mm in the pipeline file, or give approximate "
                                    "positions with --markers)");
  // Matching tries every triangle pair, so its cost grows with the sixth power of the count:
  // keep the strongest candidates when a bumpy object yields many sphere-like bumps.
  const size_t keep = static_cast<size_t>(o.expected_markers) + 6;
  if (!hints && found.size() > keep) {
    d->candidates_dropped = found.size() - keep;
    found.resize(keep);
  }
  d->markers = std::move(found);
}

// The marker caps of one scan at `so`'s radius: fitted at the manual positions when the
// hints give this scan's, else detected (the strongest `max_found`). A hint with no sphere
// near it is left out here; find_markers names it.
std::vector<SphereFit> caps_in_scan(const PreparedScan& s, const std::optional<std::vector<Eigen::Vector3d>>* hints,
                                    const SphereOptions& so, size_t max_found = static_cast<size_t>(-1)) {
  if (!hints || !*hints) return detect_spheres(s, so, nullptr, max_found);
  std::vector<SphereFit> out;
  for (const auto& g : **hints) {
    std::string why;
    if (auto f = fit_sphere_near(s, g, so.hint_search_mm, so, &why)) out.push_back(*f);
  }
  return out;
}

// job(0) and job(1) at once (independent, each into its own slot); the first one's error first.
template <typename Job>
void both_sides(const Job& job) {
  parallel_jobs(2, [&](long side) { job(static_cast<int>(side)); });
}

// The marker radius's first estimate from the scans (fills radius_mm, spread_mm,
// candidate_mm, caps and tried of `d`): every candidate radius is tried in both scans (the back
// scan only where it could still win, below; hints: at the hinted positions) and the bumps found are matched between the scans by
// their distance pattern. Markers are the bumps that are spheres of one radius *and* sit in
// the same pattern in both scans; a fingertip or a knuckle of about the candidate's size is
// sphere-like too, but seen from the other side it fits elsewhere and matches nothing. The
// candidate with the most matched markers wins (ties: the tighter cluster of free-radius
// fits); the estimate is the median free-radius fit over its matched caps.
void estimate_marker_radius(const PreparedScan& back, const PreparedScan& palm, const RegistrationOptions& o,
                            const MarkerHints* hints, MarkerRadiusDetail* d) {
  double best_score = -1;
  const size_t keep = static_cast<size_t>(o.expected_markers) + 6;  // as find_markers: matching cost grows fast
  const size_t nc = o.radius_candidates_mm.size();
  std::vector<std::array<std::vector<SphereFit>, 2>> detected(nc);
  auto options_for = [&](double rc) {
    SphereOptions so = o.spheres;
    so.radius_mm = rc;
    so.radius_tolerance = 0.15;  // candidates ≤ 0.5 mm apart below 5 mm: every radius between them is caught
    so.inlier_mm = std::min(so.inlier_mm, 0.5 * rc);
    return so;
  };
  // The searches are independent: each runs into its own slot, in parallel, so the result does
  // not depend on the threads.
  auto search = [&](const std::vector<std::pair<size_t, int>>& jobs) {
    parallel_jobs(static_cast<long>(jobs.size()), [&](long j) {
      const auto [c, side] = jobs[static_cast<size_t>(j)];
      const SphereOptions so = options_for(o.radius_candidates_mm[c]);
      const std::optional<std::vector<Eigen::Vector3d>>* h = hints ? (side == 0 ? &hints->palm : &hints->back) : nullptr;
      detected[c][side] = caps_in_scan(side == 0 ? palm : back, h, so, keep);
    });
  };
  // Matched markers between the two scans' bumps of candidate c (0 below 3 bumps a side).
  std::vector<MarkerMatch> matches(nc);
  auto match = [&](size_t c) {
    const std::vector<SphereFit>* fits = detected[c].data();
    if (fits[0].size() < 3 || fits[1].size() < 3) return size_t{0};
    std::vector<Eigen::Vector3d> cb, cp;
    for (const auto& f : fits[1]) cb.push_back(f.centre);
    for (const auto& f : fits[0]) cp.push_back(f.centre);
    matches[c] = match_markers(cb, cp, o.match_tolerance_mm);
    return matches[c].pairs.size();
  };
  // 1. Every candidate in the palm scan.
  std::vector<std::pair<size_t, int>> palm_jobs;
  for (size_t c = 0; c < nc; ++c) palm_jobs.push_back({c, 0});
  search(palm_jobs);
  // 2. The back scan, two candidates at a time (fixed, whatever the threads), those with the
  // most palm bumps first. A candidate matches at most as many markers as its palm search found
  // bumps, and a score is its matched count less under 1: one whose palm bumps are fewer than
  // the best matched count so far cannot win, and is not searched in the back scan (on the
  // fixture 8 of the 10 candidates; their searches were half the estimate's time).
  std::vector<size_t> order(nc);
  for (size_t c = 0; c < nc; ++c) order[c] = c;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return detected[a][0].size() > detected[b][0].size(); });
  std::vector<char> searched(nc, 0);
  size_t best_matched = 0;
  for (size_t next = 0; next < nc;) {
    std::vector<std::pair<size_t, int>> round;
    for (; next < nc && round.size() < 2; ++next) {
      const size_t c = order[next];
      if (detected[c][0].size() >= 3 && detected[c][0].size() >= best_matched) round.push_back({c, 1});
    }
    if (round.empty()) break;
    search(round);
    for (const auto& [c, side] : round) searched[c] = 1, best_matched = std::max(best_matched, match(c));
  }
  for (size_t c = 0; c < nc; ++c) {
    const double rc = o.radius_candidates_mm[c];
    const std::vector<SphereFit>* fits = detected[c].data();
    RadiusTry row{rc, fits[0].size(), fits[1].size(), 0, searched[c] != 0};
    if (fits[0].size() < 3 || fits[1].size() < 3) {
      d->tried.push_back(row);
      continue;
    }
    const MarkerMatch& m = matches[c];
    row.matched = m.pairs.size();
    d->tried.push_back(row);
    if (m.pairs.size() < 3) continue;
    std::vector<double> radii;
    for (const auto& [b, p] : m.pairs) radii.push_back(fits[1][b].radius_free), radii.push_back(fits[0][p].radius_free);
    // Median and median absolute deviation, then once more over the caps within 3 robust
    // sigmas: a matched fingertip's cap, not quite a sphere, fits another radius.
    double med = 0, mad = 0;
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<double> r;
      for (double x : radii)
        if (pass == 0 || std::abs(x - med) <= std::max(3 * 1.4826 * mad, 0.01 * med)) r.push_back(x);
      std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
      const double m = r[r.size() / 2];
      std::vector<double> dev;
      for (double x : r) dev.push_back(std::abs(x - m));
      std::nth_element(dev.begin(), dev.begin() + dev.size() / 2, dev.end());
      med = m, mad = dev[dev.size() / 2];
    }
    const double score = static_cast<double>(m.pairs.size()) - std::min(0.99, mad / med);
    if (score > best_score) {
      best_score = score;
      d->radius_mm = med;
      d->spread_mm = mad;
      d->candidate_mm = rc;
      d->caps = static_cast<int>(radii.size());
    }
  }
}

// One shared radius refitted to the caps detected at the current radius (o.spheres) that agree
// with it: the next estimate, or none when fewer than 6 caps agree (then `*sd` is left as is).
std::optional<double> refit_shared_radius(const PreparedScan& back, const PreparedScan& palm, const RegistrationOptions& o,
                                          const MarkerHints* hints, double* sd) {
  const double rc = o.spheres.radius_mm;
  std::vector<SphereFit> fits[2];  // both scans at once: independent, each into its own slot
  both_sides([&](int side) {
    // With manual positions, the same caps as the final fit will take.
    const std::optional<std::vector<Eigen::Vector3d>>* h = hints ? (side == 0 ? &hints->back : &hints->palm) : nullptr;
    fits[side] = caps_in_scan(side == 0 ? back : palm, h, o.spheres);
  });
  std::vector<double> radii;
  for (const auto& side : fits)
    for (const SphereFit& f : side)
      if (std::abs(f.radius_free - rc) <= 0.04 * rc) radii.push_back(f.radius_free);
  if (radii.size() < 6) return std::nullopt;
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  const double median = radii[radii.size() / 2];
  // One radius fitted to all the caps that agree with the median (within 3 robust sigmas;
  // a bump that is not a marker lies outside), each cap its own centre: on the family's 48
  // pairs its error scattered 0.0073 mm against the median's 0.0097.
  std::vector<double> dev;
  for (double x : radii) dev.push_back(std::abs(x - median));
  std::nth_element(dev.begin(), dev.begin() + dev.size() / 2, dev.end());
  const double agree = std::max(3 * 1.4826 * dev[dev.size() / 2], 0.002 * rc);
  std::vector<SharedRadiusCap> caps;
  for (int side = 0; side < 2; ++side)
    for (const SphereFit& f : fits[side])
      if (std::abs(f.radius_free - rc) <= 0.04 * rc && std::abs(f.radius_free - median) <= agree)
        caps.push_back({side == 0 ? &back : &palm, &f});
  return fit_shared_radius(caps, median, o.spheres.steep_floor, sd);
}

// --- 1. table, speckle, normals: both scans at once (PCL's RANSAC has its own fixed seed
// per model); the back scan's error first. ---
std::array<PreparedScan, 2> prepare_both(const RangeScan& back_scan, const RangeScan& palm_scan,
                                         const std::string& back_file, const std::string& palm_file,
                                         const PrepareOptions& o) {
  std::array<PreparedScan, 2> prepared;
  both_sides([&](int side) {
    prepared[side] = side == 0 ? prepare_scan(back_scan, o, back_file) : prepare_scan(palm_scan, o, palm_file);
  });
  return prepared;
}

// --- 2. the markers' radius: given (o->spheres.radius_mm), or estimated from the scans and
// set there ---
void settle_radius(const PreparedScan& back, const PreparedScan& palm, RegistrationOptions* o, const MarkerHints* hints,
                   const std::string& both, const RegisterProgress& progress, MarkerRadiusDetail* d) {
  d->estimated = o->estimate_radius;
  if (o->estimate_radius) {
    progress("estimating the marker radius");
    estimate_marker_radius(back, palm, *o, hints, d);
    if (d->caps == 0) {
      std::string tried;
      for (double rc : o->radius_candidates_mm) tried += (tried.empty() ? "" : ", ") + fmt("%.1f", rc);
      // With positions given, the caps are looked for at them only: positions of another pair,
      // or of one scan given as the other's, found nothing, and the message told the user to
      // give the positions they had given.
      if (hints)
        throw InputError(hints->file, "at the positions it gives no radius finds 3 marker spheres in both scans (tried " +
                                          tried + " mm): are they this pair's markers, each side's in its own scan's "
                                          "frame (mm), within 3 mm of the bumps?");
      throw InputError(both, "no radius finds 3 marker spheres in both scans (tried " + tried +
                                 " mm); set markers.radius_mm in the pipeline file or give approximate positions with "
                                 "--markers");
    }
    o->spheres.radius_mm = d->radius_mm;
    // The candidate's inlier gate pulls the caps' free fits toward it: detect again at the
    // estimate and fit one radius to the caps that agree with it (within 4 %), until it
    // settles. (A radius error moves every centre along its scan's view, the back scan's
    // opposite to the palm scan's: the back scan lands twice that off along the hand's
    // normal, docs/registration.md.)
    d->refinement_mm = {d->radius_mm};
    for (int it = 0; it < 5; ++it) {
      const double rc = o->spheres.radius_mm;
      const std::optional<double> refit = refit_shared_radius(back, palm, *o, hints, &d->sd_mm);
      if (!refit) break;  // too few caps agree
      const double next = *refit;
      d->refinement_mm.push_back(next);
      o->spheres.radius_mm = next;
      if (std::abs(next - rc) < 0.002) break;
    }
  }
  d->radius_mm = o->spheres.radius_mm;
}

// --- 3. markers in each scan (both at once; the back scan's error first); with the radius
// estimated, a bump whose own free fit strays from it (a fingertip of about the markers'
// size) is not a marker: the markers share one radius ---
void find_both_markers(const PreparedScan& back, const PreparedScan& palm, const RegistrationOptions& o,
                       const MarkerHints* hints, const std::string& back_file, const std::string& palm_file,
                       RegistrationDetail* d, std::vector<std::string>* warnings) {
  const std::string hints_file = hints ? hints->file : "";
  both_sides([&](int side) {
    if (side == 0)
      find_markers(back, o, hints ? hints->back : std::nullopt, hints_file, back_file, &d->back);
    else
      find_markers(palm, o, hints ? hints->palm : std::nullopt, hints_file, palm_file, &d->palm);
  });
  const double r = o.spheres.radius_mm;
  if (o.estimate_radius && !hints) {
    const double tol = std::max(0.04 * r, 5 * 1.4826 * d->radius.spread_mm);
    for (auto* side : {&d->back.markers, &d->palm.markers}) {
      std::vector<SphereFit> kept;
      for (auto& f : *side)
        if (std::abs(f.radius_free - r) <= tol) kept.push_back(std::move(f));
      if (kept.size() >= 3) *side = std::move(kept);
    }
    d->radius.free_fit_tolerance_mm = tol;
  }
  for (const auto* side : {&d->back, &d->palm})
    if (static_cast<long>(side->markers.size()) != o.expected_markers)
      warnings->push_back(std::string(side == &d->back ? "back" : "palm") + " scan: " +
                          std::to_string(side->markers.size()) + " marker spheres found, " +
                          std::to_string(o.expected_markers) + " expected");
}

std::vector<Eigen::Vector3d> centres_of(const std::vector<SphereFit>& fits) {
  std::vector<Eigen::Vector3d> c;
  for (const auto& f : fits) c.push_back(f.centre);
  return c;
}

// --- 4. matching by distance pattern and the rigid fit; a match that a mirror image,
// another object or a regular layout could give stops the registration ---
MarkerMatch match_checked(const std::vector<Eigen::Vector3d>& cb, const std::vector<Eigen::Vector3d>& cp,
                          double tolerance_mm, const std::string& both) {
  MarkerMatch match = match_markers(cb, cp, tolerance_mm);
  if (match.pairs.size() < 3)
    throw InputError(both, "the marker patterns do not match: no 3 of the back scan's " + std::to_string(cb.size()) +
                               " markers have the distances of 3 of the palm scan's " + std::to_string(cp.size()) +
                               fmt(" within %.2f mm (scans of two different objects?)", tolerance_mm));
  // Most markers seen on both sides must take part: a match of a small subset is what a
  // mirror image or another object's pattern can give by chance.
  const size_t seen_both = std::min(cb.size(), cp.size());
  if (match.pairs.size() + 2 < seen_both)
    throw InputError(both, "only " + std::to_string(match.pairs.size()) + " of " + std::to_string(seen_both) +
                               " markers agree in their distance pattern (scans of two different objects, or a "
                               "mirrored scan?)");
  if (match.runner_up_pairs == match.pairs.size())
    throw InputError(both, "ambiguous marker pattern: two different matchings each pair " +
                               std::to_string(match.pairs.size()) +
                               fmt(" markers (residual %.3f and %.3f mm); give the markers an irregular layout",
                                   match.rms_mm, match.runner_up_rms_mm));
  return match;
}

// --- 5. a marker found in one scan but not the other (its cap there partly hidden by the
// flank it sits on, or its free fit strayed from the estimated radius) is looked for where
// the pattern's fit puts it: a fixed-radius fit within the matching tolerance of that spot.
// On the family's 48 pairs 4 lost one or two markers this way (H04-s1 kept 7 of 9). The
// found ones join `d`'s markers and its match, whose fit is redone. Returns their count. ---
int recover_missed(const PreparedScan& back, const PreparedScan& palm, const RegistrationOptions& o,
                   std::vector<Eigen::Vector3d>* cb, std::vector<Eigen::Vector3d>* cp, RegistrationDetail* d) {
  MarkerMatch& match = d->match;
  const double r = o.spheres.radius_mm;
  // The free radius only within the detector's own ±10 %: where the pattern puts a marker
  // within the matching tolerance, a cap half hidden by its flank (free fits 4-5 % large on
  // the family's H03-s3 and H10-s2) is still that marker.
  const double tol_r = 0.1 * r;
  auto recover = [&](bool in_palm) {
    const auto& from = in_palm ? *cb : *cp;
    auto& to = in_palm ? *cp : *cb;
    auto& fits = in_palm ? d->palm.markers : d->back.markers;
    const PreparedScan& scan = in_palm ? palm : back;
    const Eigen::Isometry3d T = in_palm ? match.back_to_palm : match.back_to_palm.inverse();
    std::vector<char> paired(from.size(), 0);
    for (const auto& [b, p] : match.pairs) paired[static_cast<size_t>(in_palm ? b : p)] = 1;
    int found_here = 0;
    for (size_t k = 0; k < from.size(); ++k) {
      if (paired[k]) continue;
      const Eigen::Vector3d guess = T * from[k];
      bool taken = false;  // a bump already there (one matching left unpaired) is not a new marker
      for (const auto& c : to) taken = taken || (c - guess).norm() < r;
      std::string why;
      const auto f = taken ? std::nullopt : fit_sphere_near(scan, guess, o.match_tolerance_mm, o.spheres, &why);
      if (!f || (f->centre - guess).norm() > o.match_tolerance_mm || std::abs(f->radius_free - r) > tol_r) continue;
      fits.push_back(*f);
      to.push_back(f->centre);
      const int j = static_cast<int>(to.size()) - 1;
      match.pairs.emplace_back(in_palm ? static_cast<int>(k) : j, in_palm ? j : static_cast<int>(k));
      ++found_here;
    }
    return found_here;
  };
  const int recovered = recover(true) + recover(false);
  if (recovered > 0) {
    std::sort(match.pairs.begin(), match.pairs.end());
    match.back_to_palm = fit_rigid(*cb, *cp, match.pairs);
  }
  return recovered;
}

// The markers' residuals (each pair's, their RMS and largest) at the transform T.
MarkerResiduals marker_residuals(const Eigen::Isometry3d& T, const MarkerMatch& match,
                                 const std::vector<Eigen::Vector3d>& cb, const std::vector<Eigen::Vector3d>& cp) {
  MarkerResiduals m;
  double ss = 0;
  for (const auto& [b, p] : match.pairs) {
    const double d = (T * cb[b] - cp[p]).norm();
    m.per_pair_mm.push_back(d);
    ss += d * d;
    m.max_mm = std::max(m.max_mm, d);
  }
  m.rms_mm = std::sqrt(ss / static_cast<double>(match.pairs.size()));
  return m;
}

// --- 5b. More matched pairs than the replica carries markers (expected_markers): one is a
// bump of the hand that looks like a marker from both sides and keeps its place between them
// — a round fingertip of the markers' radius (the flat, thin-fingered hand of
// scripts/unusual_hands_study.py, P06: 10 pairs of 9, the fit 0.098 deg off the truth, and the
// refinement 0.148). Every subset of expected_markers pairs is fitted and the one with the
// lowest residual kept, if that falls below kSurplusRmsShare of the whole set's: left out,
// P06's fingertip took the residual from 0.101 to 0.027 mm and the rotation error to 0.021
// deg, where leaving out any real marker changed it by under 10 % (0.092-0.106 mm). A real
// marker more than the options say changes the residual as little, and stays. Returns the
// pairs left out. ---
int drop_surplus_pairs(const RegistrationOptions& o, const std::vector<Eigen::Vector3d>& cb,
                       const std::vector<Eigen::Vector3d>& cp, MarkerMatch* match, double* rms_before) {
  constexpr double kSurplusRmsShare = 0.5;
  const int n = static_cast<int>(match->pairs.size()), k = o.expected_markers;
  if (n <= k || k < 3) return 0;
  const auto rms_of = [&](const MarkerMatch& m) { return marker_residuals(fit_rigid(cb, cp, m.pairs), m, cb, cp).rms_mm; };
  const double all = rms_of(*match);
  *rms_before = all;
  // The subsets in a fixed order (a bit mask of the pairs kept): the same choice every run.
  std::vector<char> keep(static_cast<size_t>(n), 0);
  std::fill(keep.end() - k, keep.end(), 1);
  double best = std::numeric_limits<double>::infinity();
  MarkerMatch best_subset;
  do {
    MarkerMatch sub;
    for (int i = 0; i < n; ++i)
      if (keep[static_cast<size_t>(i)]) sub.pairs.push_back(match->pairs[static_cast<size_t>(i)]);
    const double r = rms_of(sub);
    if (r < best) best = r, best_subset = std::move(sub);
  } while (std::next_permutation(keep.begin(), keep.end()));
  if (!(best < kSurplusRmsShare * all)) return 0;
  match->pairs = std::move(best_subset.pairs);
  match->back_to_palm = fit_rigid(cb, cp, match->pairs);
  const MarkerResiduals r = marker_residuals(match->back_to_palm, *match, cb, cp);
  match->rms_mm = r.rms_mm, match->max_mm = r.max_mm;
  return n - k;
}

// Each marker's partner in the other scan (-1: none), and a warning for each marker unused.
void pair_partners(const std::vector<Eigen::Vector3d>& cb, const std::vector<Eigen::Vector3d>& cp,
                   RegistrationDetail* d, std::vector<std::string>* warnings) {
  d->back.partner.assign(cb.size(), -1);
  d->palm.partner.assign(cp.size(), -1);
  for (const auto& [b, p] : d->match.pairs) {
    d->back.partner[b] = p;
    d->palm.partner[p] = b;
  }
  for (size_t k = 0; k < cb.size(); ++k)
    if (d->back.partner[k] < 0)
      warnings->push_back("back marker " + std::to_string(k) + " at " + where(cb[k]) +
                          " has no partner in the palm scan and is not used");
  for (size_t k = 0; k < cp.size(); ++k)
    if (d->palm.partner[k] < 0)
      warnings->push_back("palm marker " + std::to_string(k) + " at " + where(cp[k]) +
                          " has no partner in the back scan and is not used");
}

// --- 6. the guarded refinement from the marker-only fit (markers as anchors, gated ICP on
// the skin: `skin_b` / `skin_p`), then the check against the marker radius and the
// scanner's resolution. Sets out's transform, markers and warnings. ---
void refine_checked(const PreparedScan& back, const PreparedScan& palm, const std::vector<char>& skin_b,
                    const std::vector<char>& skin_p, const std::vector<MarkerSamples>& samples,
                    const std::vector<Eigen::Vector3d>& cb, const std::vector<Eigen::Vector3d>& cp,
                    const std::string& both, Registration* out) {
  RegistrationDetail& d = out->detail;
  const RegistrationOptions& o = d.used;
  const double r = o.spheres.radius_mm;
  RefineOptions ro = o.refine;
  if (!o.refine_enabled) ro.max_iterations = 0;
  d.refinement = refine_registration(back, palm, skin_b, skin_p, samples, out->marker_only, r, o.spheres.steep_floor, ro);
  const RefineResult& ref = d.refinement;
  out->refined = o.refine_enabled && ref.accepted;
  out->back_to_palm = out->refined ? ref.T : out->marker_only;
  if (o.refine_enabled && !ref.accepted) out->warnings.push_back("refinement refused, marker-only fit kept: " + ref.note);
  transform_difference(ref.T, out->marker_only, &d.change_rotation_deg, &d.change_translation_mm);

  d.accept_residual_mm = o.accept_residual_mm > 0 ? o.accept_residual_mm : std::max(2.0 * palm.z_step, 0.1 * r);
  d.marker_only = marker_residuals(out->marker_only, d.match, cb, cp);
  d.refined = marker_residuals(ref.T, d.match, cb, cp);
  const double max_final = out->refined ? d.refined.max_mm : d.marker_only.max_mm;
  if (max_final > d.accept_residual_mm)
    throw InputError(both, fmt("registration rejected: a matched marker's centres disagree by %.3f mm after the fit "
                               "(allowed %.3f mm: 2 depth steps or 10%% of the marker radius)",
                               max_final, d.accept_residual_mm));
  // Marker centres in the palm frame: the joint fit's when refined, else the midpoint of
  // each pair's two centres.
  if (out->refined) {
    out->markers_palm = ref.centres;
  } else {
    for (const auto& [b, p] : d.match.pairs) out->markers_palm.push_back(0.5 * (out->marker_only * cb[b] + cp[p]));
  }
}

// --- 7. the fit's own error estimate (1σ): the joint marker fit's covariance at the chosen
// transform, mapped onto the back scan's skin samples; with the radius estimated, its error
// moves the back scan 2δr along the palm scanner's view on top (step 3 of
// docs/registration.md). A warning when the scans cannot hold the transform to the bounds. ---
void estimate_uncertainty(const PreparedScan& back, const std::vector<char>& skin_b,
                          const std::vector<MarkerSamples>& samples, Registration* out) {
  RegistrationDetail& d = out->detail;
  const RegistrationOptions& o = d.used;
  const double r = o.spheres.radius_mm;
  // The refinement's centres are the joint fit's at its transform already.
  std::vector<Eigen::Vector3d> joint_centres = d.refinement.centres;
  if (!out->refined) marker_sphere_rms(samples, out->back_to_palm, r, o.spheres.steep_floor, &joint_centres);
  const PoseCovariance pc = pose_covariance(samples, out->back_to_palm, joint_centres, r, o.spheres.steep_floor);
  if (!pc.valid) return;
  std::vector<Eigen::Vector3d> skin_points;
  for (size_t k = 0; k < back.points.size(); k += 25)
    if (skin_b[k]) skin_points.push_back(back.points[k]);
  const double fit_mm = displacement_sigma(out->back_to_palm, pc.covariance, skin_points);
  const double along_normal = 2.0 * d.radius.sd_mm;
  RegistrationUncertainty& u = d.uncertainty;
  u.valid = true;
  u.rotation_deg = rotation_sigma_deg(out->back_to_palm, pc.covariance);
  u.displacement_mm = std::sqrt(fit_mm * fit_mm + along_normal * along_normal);
  u.displacement_markers_mm = fit_mm;
  u.radius_mm = d.radius.sd_mm;
  u.residual_sigma_mm = pc.sigma_mm;
  out->figures.rotation_sigma_deg = u.rotation_deg;
  out->figures.displacement_sigma_mm = u.displacement_mm;
  // The scans cannot hold the transform to the bounds: say so, and what would help. The
  // radius is named only where its share dominates (it moves the back scan along the
  // normal; the rotation is the centres' sideways noise over their lever arms).
  const double rot = u.rotation_deg, disp = u.displacement_mm;
  if (rot > o.warn_rotation_sigma_deg || disp > o.warn_displacement_sigma_mm) {
    const bool radius_dominates = disp > o.warn_displacement_sigma_mm && along_normal > fit_mm;
    out->warnings.push_back(
        fmt("the scans hold this registration to %.3f deg / %.3f mm only (1 sigma, the fit's own estimate; "
            "warned above %.3f deg / %.3f mm): %d markers of radius %.2f mm matched; %s (docs/registration.md)",
            rot, disp, o.warn_rotation_sigma_deg, o.warn_displacement_sigma_mm,
            static_cast<int>(d.match.pairs.size()), r,
            radius_dominates ? "most of it is the estimated radius's: give the markers' radius if it is known "
                               "(markers.radius_mm)"
                             : "more or larger markers, spread wider, would tighten it"));
  }
}

// --- 8. merge: palm frame, side labels, marker samples out (each scan's own markers and the
// other's mapped across, within `reach` of a centre) ---
void merge_scans(const PreparedScan& back, const PreparedScan& palm, const std::vector<Eigen::Vector3d>& cb,
                 const std::vector<Eigen::Vector3d>& cp, double reach, Registration* out) {
  std::vector<Eigen::Vector3d> all_b = cb, all_p = cp;
  for (const auto& c : cp) all_b.push_back(out->back_to_palm.inverse() * c);
  for (const auto& c : cb) all_p.push_back(out->back_to_palm * c);
  const std::vector<char> keep_b = skin_mask(back, all_b, reach), keep_p = skin_mask(palm, all_p, reach);
  out->merged.reset(new MergedCloud);
  out->merged->reserve(static_cast<size_t>(std::count(keep_b.begin(), keep_b.end(), 1) +
                                           std::count(keep_p.begin(), keep_p.end(), 1)));
  auto add = [&](const PreparedScan& s, const std::vector<char>& keep, const Eigen::Isometry3d& T, std::uint32_t label) {
    size_t count = 0;
    for (size_t k = 0; k < s.points.size(); ++k) {
      if (!keep[k]) continue;
      const Eigen::Vector3d p = T * s.points[k];
      const Eigen::Vector3d n = T.linear() * s.normals[k];
      pcl::PointXYZLNormal q;
      q.x = static_cast<float>(p.x());
      q.y = static_cast<float>(p.y());
      q.z = static_cast<float>(p.z());
      q.normal_x = static_cast<float>(n.x());
      q.normal_y = static_cast<float>(n.y());
      q.normal_z = static_cast<float>(n.z());
      q.curvature = 0;
      q.label = label;
      out->merged->push_back(q);
      ++count;
    }
    return count;
  };
  RegistrationDetail& d = out->detail;
  d.merged_palm = add(palm, keep_p, Eigen::Isometry3d::Identity(), kSidePalm);
  d.merged_back = add(back, keep_b, out->back_to_palm, kSideBack);
  d.marker_samples_removed = (back.points.size() - d.merged_back) + (palm.points.size() - d.merged_palm);
}

// A scan's preparation figures into its detail.
void describe_scan(const PreparedScan& s, ScanRegistrationDetail* d) {
  d->returns = s.returns;
  d->table_plane = s.table_plane;
  d->table_tilt_deg = s.table_tilt_deg;
  d->table_rms_mm = s.table_rms_mm;
  d->table_points = s.table_points;
  d->below_table = s.below_table;
  d->speckle_islands = s.speckle_islands;
  d->speckle_points = s.speckle_points;
  d->object_points = s.points.size();
}

// The run report's summary figures from the detail.
void sum_up(Registration* out, const std::vector<std::pair<std::string, double>>& timings) {
  const RegistrationDetail& d = out->detail;
  RegistrationFigures& f = out->figures;
  f.radius_estimated = d.used.estimate_radius;
  f.markers_back = d.back.markers.size();
  f.markers_palm = d.palm.markers.size();
  f.markers_matched = d.match.pairs.size();
  f.marker_only_rms_mm = d.marker_only.rms_mm;
  f.refined_rms_mm = d.refined.rms_mm;
  f.sphere_rms_marker_only_mm = d.refinement.marker_rms_start;
  f.sphere_rms_refined_mm = d.refinement.marker_rms_end;
  f.icp_overlap_fraction = d.refinement.overlap_fraction;
  f.merged_points = out->merged->size();
  f.timings_ms = timings;
  std::sort(f.timings_ms.begin(), f.timings_ms.end());
}

}  // namespace

Registration register_scans(const RangeScan& back_scan, const RangeScan& palm_scan, const std::string& back_file,
                            const std::string& palm_file, const RegistrationOptions& options, const MarkerHints* hints,
                            const RegisterProgress& progress) {
  std::string err;
  if (!options.IsValid(&err)) throw InputError("registration options", err);
  Registration out;
  RegistrationDetail& d = out.detail;
  d.used = options;
  RegistrationOptions& o = d.used;
  const std::string both = back_file + " + " + palm_file;
  std::vector<std::pair<std::string, double>> timings;

  progress("removing the table and speckle");
  auto t = Clock::now();
  const std::array<PreparedScan, 2> prepared = prepare_both(back_scan, palm_scan, back_file, palm_file, o.prepare);
  const PreparedScan& back = prepared[0];
  const PreparedScan& palm = prepared[1];
  describe_scan(back, &d.back);
  describe_scan(palm, &d.palm);
  timings.emplace_back("prepare_ms", ms_since(t));

  // The markers and their match; when no 3 markers match (none of the radii finds them, or the
  // patterns do not agree), once more with the Hough search's vote threshold lowered to
  // kFewVotes: small markers on a noisy scan leave caps of ~20 samples whose normals scatter
  // their votes (R02 of scripts/random_hands_study.py --draw 75: 2.5 mm markers, σ 0.086 mm,
  // 22-34 returns per cap in the palm scan, of which 10 votes found 3 caps and 6 found 7). A
  // pair whose markers match at the usual threshold is not searched again: its result is the
  // same. The first error is the one reported when the second search fails too.
  constexpr long kFewVotes = 6;
  const RegistrationDetail d_before = d;
  const size_t warnings_before = out.warnings.size();
  const auto timings_before = timings;
  std::exception_ptr first_error;
  std::vector<Eigen::Vector3d> cb, cp;
  double r = 0;
  const auto t_markers = Clock::now();  // markers_ms: both searches' when there are two
  for (;;) {
    try {
      settle_radius(back, palm, &o, hints, both, progress, &d.radius);
      r = o.spheres.radius_mm;
      out.marker_radius_mm = r;
      progress("finding the marker spheres (radius " + fmt("%.2f", r) + " mm)");
      find_both_markers(back, palm, o, hints, back_file, palm_file, &d, &out.warnings);
      timings.emplace_back("markers_ms", ms_since(t_markers));

      progress("matching the markers");
      t = Clock::now();
      cb = centres_of(d.back.markers), cp = centres_of(d.palm.markers);
      d.match = match_checked(cb, cp, o.match_tolerance_mm, both);
      timings.emplace_back("match_ms", ms_since(t));
      break;
    } catch (const InputError&) {
      if (first_error) std::rethrow_exception(first_error);
      if (hints || options.spheres.min_votes <= kFewVotes) throw;
      first_error = std::current_exception();
    }
    progress("no 3 markers matched: searching the scans again with fewer votes per sphere (" +
             std::to_string(kFewVotes) + ")");
    d = d_before;  // its `used` the options as given
    d.used.spheres.min_votes = kFewVotes;
    out.warnings.resize(warnings_before);
    timings = timings_before;
  }
  if (first_error)
    out.warnings.push_back("the markers were found with " + std::to_string(kFewVotes) + " votes per sphere, not " +
                           std::to_string(options.spheres.min_votes) +
                           " (small or noisy marker caps): check the registration's own error estimate");
  if (!hints) d.recovered = recover_missed(back, palm, o, &cb, &cp, &d);
  if (d.recovered > 0)
    out.warnings.push_back(std::to_string(d.recovered) + " marker(s) found in one scan were found in the other where " +
                           "the others' fit put them");
  {
    double before = 0;
    if ((d.left_out = drop_surplus_pairs(o, cb, cp, &d.match, &before)) > 0)
      out.warnings.push_back(std::to_string(d.left_out) + " matched pair(s) left out: the replica carries " +
                             std::to_string(o.expected_markers) + " markers, and without them the markers' residual " +
                             fmt("falls from %.3f to %.3f mm", before, d.match.rms_mm) +
                             " (a bump of the hand that looks like a marker from both sides)");
  }
  if (d.match.pairs.size() == 3) out.warnings.push_back("only 3 markers matched: the fit has no redundancy to check it");
  pair_partners(cb, cp, &d, &out.warnings);
  out.marker_only = d.match.back_to_palm;

  std::vector<MarkerSamples> samples;
  for (const auto& [b, p] : d.match.pairs) {
    MarkerSamples m;
    for (int k : d.back.markers[b].inliers) m.back.push_back(back.points[k]);
    for (int k : d.palm.markers[p].inliers) m.palm.push_back(palm.points[k]);
    samples.push_back(std::move(m));
  }
  // Marker neighbourhoods are not skin, in either scan: own detections and the other side's
  // mapped across (a marker missed on one side still must not pass for skin).
  const double reach = r + o.marker_clearance_mm;
  std::vector<Eigen::Vector3d> all_b = cb, all_p = cp;
  for (const auto& c : cp) all_b.push_back(out.marker_only.inverse() * c);
  for (const auto& c : cb) all_p.push_back(out.marker_only * c);
  const std::vector<char> skin_b = skin_mask(back, all_b, reach), skin_p = skin_mask(palm, all_p, reach);

  progress("refining (markers as anchors, gated ICP)");
  t = Clock::now();
  refine_checked(back, palm, skin_b, skin_p, samples, cb, cp, both, &out);
  timings.emplace_back("refine_ms", ms_since(t));
  estimate_uncertainty(back, skin_b, samples, &out);

  progress("merging");
  t = Clock::now();
  merge_scans(back, palm, cb, cp, reach, &out);
  timings.emplace_back("merge_ms", ms_since(t));
  sum_up(&out, timings);
  return out;
}

MergedArrays merged_arrays(const MergedCloud& cloud) {
  MergedArrays a;
  a.points.reserve(cloud.size());
  a.normals.reserve(cloud.size());
  a.sides.reserve(cloud.size());
  for (const auto& q : cloud) {
    a.points.push_back(q.getVector3fMap().cast<double>());
    a.normals.push_back(q.getNormalVector3fMap().cast<double>());
    a.sides.push_back(q.label);
  }
  return a;
}

RegistrationError registration_error(const Eigen::Isometry3d& est, const Eigen::Isometry3d& truth,
                                     const std::vector<Eigen::Vector3d>& skin) {
  RegistrationError e;
  double mm;
  transform_difference(est, truth, &e.rotation_deg, &mm);
  // A true back sample lands at est·truth⁻¹·x instead of at x.
  const Eigen::Isometry3d E = est * truth.inverse();
  for (const auto& x : skin) {
    const double d = (E * x - x).norm();
    e.mean_mm += d;
    e.max_mm = std::max(e.max_mm, d);
  }
  if (!skin.empty()) e.mean_mm /= static_cast<double>(skin.size());
  return e;
}

MergedArrays read_merged(const std::string& path) {
  PointCloudFile f = read_point_cloud(path);
  if (f.normals.empty()) throw InputError(path, "no normals (nx ny nz): not a merged cloud of handskin's (for another scanner's cloud: run --cloud)");
  if (f.labels.empty()) throw InputError(path, "no side label per point: not a merged cloud of handskin's (for another scanner's cloud: run --cloud)");
  MergedArrays a;
  a.points = std::move(f.points);
  a.normals = std::move(f.normals);
  a.sides = std::move(f.labels);
  for (size_t i = 0; i < a.points.size(); ++i) {
    if (!a.normals[i].allFinite()) throw InputError(path, "point " + std::to_string(i) + " is not finite (x y z nx ny nz)");
    if (a.sides[i] != kSidePalm && a.sides[i] != kSideBack)
      throw InputError(path, "point " + std::to_string(i) + " has side label " + std::to_string(a.sides[i]) +
                                 " (0 palm, 1 back)");
  }
  return a;
}

void save_merged(const std::string& path, const MergedCloud& cloud) { save_cloud(path, cloud); }

}  // namespace handskin
