#include "pipeline/cloud_stage.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>

#include "core/errors.hpp"
#include "core/transform.hpp"
#include "skin/auto_rig.hpp"

namespace handskin {

namespace {

// Below this mean bend (the fingers' mid-line's drop from PIP to near the tip over its run)
// the fingers are too straight to tell the palm from the back (docs/clouds.md: the synthetic
// family's relaxed hands bend 0.36-0.43, its curled one 0.7, its flat one and the fixture's
// straight hand 0.02 at most either way).
constexpr double kFlexionCue = 0.05;

std::string fixed(double v, int digits) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// A deterministic sign for an axis found up to its sign.
Eigen::Vector3d canonical(Eigen::Vector3d a) {
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(a(i)) > std::abs(a(k))) k = i;
  return a(k) < 0 ? Eigen::Vector3d(-a) : a;
}

// 3. Which way the back faces. The skeleton placed with the sides labelled both ways is a
// right hand one way and its mirror image, a left hand, the other: the silhouette cannot tell
// them apart, the fingers' bend can (they flex toward the palm: their mid-line drops toward
// the palm from the knuckle on), and so can the user.
CloudOrientation orient(const PreparedCloud& c, const CloudStageInputs& in, const std::string& file,
                        const std::function<void(const std::string&)>& progress) {
  CloudOrientation o;
  if (in.rig) {
    o.by = "rig";
    o.back = hand_frame_from_rig(*in.rig).linear().row(2).transpose();
    o.side = rig_side(*in.rig);
    o.note = in.rig->palm_normal ? "the back faces the rig's palm_normal"
                                 : "the back faces the rig's Z (its joints, as a right hand's: no palm_normal given)";
    return o;
  }
  const Eigen::Vector3d axis = canonical(thickness_axis(c.points));
  std::optional<AutoRig> placed[2];
  std::string first_error;
  for (int s = 0; s < 2; ++s) {
    const Eigen::Vector3d back = s ? Eigen::Vector3d(-axis) : axis;
    try {
      placed[s] = place_skeleton(c.points, label_sides(c.points, back, nullptr));
    } catch (const InputError& e) {
      if (first_error.empty()) first_error = e.detail();
    }
  }
  if (!placed[0] && !placed[1]) throw InputError(file, "no hand found: " + first_error);
  const double f0 = placed[0] ? finger_flexion(c.points, placed[0]->rig) : 0,
               f1 = placed[1] ? finger_flexion(c.points, placed[1]->rig) : 0;
  // The bend's answer: the way the fingers bend toward the palm, when they clearly do one way
  // and not (or clearly less) the other.
  int pick = placed[0] ? 0 : 1;
  if (placed[0] && placed[1]) pick = f0 <= f1 ? 0 : 1;
  const double f = pick ? f1 : f0, other = pick ? f0 : f1;
  const bool told = f <= -kFlexionCue && (!placed[1 - pick] || other >= f + 2 * kFlexionCue);
  if (in.hand) {
    o.by = "hand";
    if (told && placed[pick]->side != *in.hand)
      throw InputError("--hand", std::string(hand_side_name(*in.hand)) + ": the fingers of " + file +
                                     " bend toward the palm of a " + hand_side_name(placed[pick]->side) + " hand (" +
                                     fixed(-f, 3) + ")");
    for (int s = 0; s < 2; ++s)
      if (placed[s] && placed[s]->side == *in.hand) pick = s;
    if (!placed[pick] || placed[pick]->side != *in.hand)
      throw InputError("--hand", std::string("no ") + hand_side_name(*in.hand) + " hand found in " + file);
    o.note = std::string("--hand ") + hand_side_name(*in.hand);
  } else {
    o.by = "flexion";
    if (!told)
      throw InputError(file, "cannot tell the palm from the back: the fingers are nearly straight (bend " + fixed(-f, 3) +
                                 " one way, " + fixed(-other, 3) + " the other; " + fixed(kFlexionCue, 2) +
                                 " needed); give --hand left or --hand right, or a --rig");
    o.note = std::string("the fingers bend toward the palm (") + fixed(-f, 3) + "): a " +
             hand_side_name(placed[pick]->side) + " hand";
  }
  o.back = pick ? Eigen::Vector3d(-axis) : axis;
  o.flexion = pick ? f1 : f0;  // of the interpretation kept
  o.side = placed[pick]->side;
  progress("orientation: " + o.note);
  return o;
}

}  // namespace

std::vector<std::uint32_t> sheet_labels(const std::vector<Eigen::Vector3d>& normals, const Eigen::Vector3d& back) {
  std::vector<std::uint32_t> s(normals.size(), 2);
  for (size_t i = 0; i < normals.size(); ++i) {
    const double c = normals[i].dot(back);
    if (c > kSheetCos) s[i] = 1;
    if (c < -kSheetCos) s[i] = 0;
  }
  return s;
}

double finger_flexion(const std::vector<Eigen::Vector3d>& points, const Rig& rig) {
  const Eigen::Isometry3d T = hand_frame_from_rig(rig);
  std::vector<Eigen::Vector3d> h;
  h.reserve(points.size());
  for (const auto& p : points) h.push_back(T * p);
  // The hand's mid-depth (halfway between its back and palm surfaces) over a 3 mm disc about
  // (x, y): the same whichever side the frame calls the back, so the cue has no bias.
  const auto mid_depth = [&](const Eigen::Vector3d& at) -> std::optional<double> {
    double lo = 1e300, hi = -1e300;
    int n = 0;
    for (const auto& q : h)
      if ((q.head<2>() - at.head<2>()).squaredNorm() < 9.0) lo = std::min(lo, q.z()), hi = std::max(hi, q.z()), ++n;
    if (n < 10) return std::nullopt;
    return 0.5 * (lo + hi);
  };
  double sum = 0;
  int fingers = 0;
  for (const char* f : {"index", "middle", "ring", "pinky"}) {
    const std::string base = std::string(f) + "-finger-";
    const Eigen::Vector3d pip = T * rig.joints[joint_index(base + "phalanx-intermediate").value()];
    const Eigen::Vector3d dip = T * rig.joints[joint_index(base + "phalanx-distal").value()];
    const Eigen::Vector3d tip = T * rig.joints[joint_index(base + "tip").value()];
    const Eigen::Vector3d end = dip + 0.6 * (tip - dip);
    const auto a = mid_depth(pip), b = mid_depth(end);
    const double run = (end - pip).head<2>().norm();
    if (!a || !b || run < 10) continue;
    sum += (*b - *a) / run, ++fingers;
  }
  return fingers ? sum / fingers : 0.0;
}

MergedArrays CloudStageResult::merged() const { return {prepared.points, prepared.normals, sides}; }

MergedCloud::Ptr merged_cloud(const MergedArrays& a) {
  auto c = std::make_shared<MergedCloud>();
  c->resize(a.points.size());
  for (size_t k = 0; k < a.points.size(); ++k) {
    pcl::PointXYZLNormal& q = (*c)[k];
    q.getVector3fMap() = a.points[k].cast<float>();
    q.getNormalVector3fMap() = (k < a.normals.size() ? a.normals[k] : Eigen::Vector3d::Zero()).cast<float>();
    q.label = k < a.sides.size() ? a.sides[k] : 0;
    q.curvature = 0;
  }
  return c;
}

namespace {
// 2. Two halves: each cleaned, the first registered into the second; their raw points merged
// in the second's frame (the merge is then cleaned as one cloud).
PointCloudFile register_halves(const PointCloudFile& a, const PointCloudFile& b, const CloudStageInputs& in,
                               CloudStageResult* r, const std::function<void(const std::string&)>& progress) {
  progress("cleaning each half");
  const PreparedCloud pa = prepare_cloud(a.points, a.normals, a.path, r->units, in.prep);
  const PreparedCloud pb = prepare_cloud(b.points, b.normals, b.path, r->units, in.prep);
  progress("registering " + a.path + " into " + b.path + " (no markers)");
  HalvesRegistration h;
  h.alignment = align_halves(pa.points, pb.points, pb.normals, a.path, b.path, in.align);
  h.kept_a = pa.points.size(), h.kept_b = pb.points.size();
  progress("registered: " + fixed(100 * h.alignment.overlap_share, 0) + " % of the first half on the second, RMS " +
           fixed(h.alignment.rms_mm, 3) + " mm, 1 sigma " + fixed(h.alignment.rotation_sigma_deg, 4) + " deg / " +
           fixed(h.alignment.displacement_sigma_mm, 4) + " mm");
  PointCloudFile m;
  m.path = b.path;
  m.points.reserve(a.points.size() + b.points.size());
  for (const auto& p : a.points) m.points.push_back(h.alignment.a_to_b * p);
  m.points.insert(m.points.end(), b.points.begin(), b.points.end());
  if (!a.normals.empty() && !b.normals.empty()) {
    for (const auto& n : a.normals) m.normals.push_back(h.alignment.a_to_b.linear() * n);
    m.normals.insert(m.normals.end(), b.normals.begin(), b.normals.end());
  }
  r->halves = h;
  return m;
}
}  // namespace

CloudStageResult run_cloud_stage(const CloudStageInputs& in, const std::function<void(const std::string&)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  CloudStageResult r;
  r.units = length_unit_name(in.units);
  HS_CHECK(in.files.size() == 1 || in.files.size() == 2, "run_cloud_stage takes one merged cloud or two halves");
  std::vector<PointCloudFile> read;
  for (const auto& file : in.files) {
    progress("reading " + file);
    read.push_back(read_point_cloud(file, in.units));
    make_normals_unit(&read.back());
    const size_t vertices = read.back().points.size(), faces = read.back().faces.size();
    const size_t sampled = sample_sparse_mesh(&read.back());  // a coarse mesh's surface, as a scanner would see it
    if (sampled) progress(file + ": a mesh of " + std::to_string(vertices) + " vertices, sparser than a scanner's points: its surface sampled, " +
                          std::to_string(sampled) + " points in their place");
    const PointCloudFile& f = read.back();
    r.files.push_back({f.path, f.format, vertices, f.no_return, !f.normals.empty(), faces, sampled});
  }
  const PointCloudFile f = read.size() == 2 ? register_halves(read[0], read[1], in, &r, progress) : std::move(read[0]);
  const std::string& file = in.files.back();
  progress("cleaning " + std::to_string(f.points.size()) + " points: outliers, the support, other parts");
  r.prepared = prepare_cloud(f.points, f.normals, file, r.units, in.prep);
  progress("the hand: " + std::to_string(r.prepared.points.size()) + " points (" + std::to_string(r.prepared.outliers) +
           " outliers, " + std::to_string(r.prepared.support) + " support, " + std::to_string(r.prepared.other_parts) +
           " in other parts)");
  r.orientation = orient(r.prepared, in, file, progress);
  r.sides = label_sides(r.prepared.points, r.orientation.back, &r.prepared.normals);
  // A cloud seen from one side only (one depth camera's view, a scan of the back alone), or
  // from its flanks only (synth cloud --views 2), holds no closed hand: 8 % and 39 % of the
  // columns against 92-98 % for clouds seen from 3 views or more and for the fixture's and the
  // family's. Before, the first went on to the skeleton's placement and stopped there with "the
  // automatic placement missed this hand: give its rig"; the second, with its rig, with "joint
  // 'ring-finger-metacarpal' lies outside the merged cloud".
  r.two_sided_share = two_sided_share(r.prepared.points, r.orientation.back);
  constexpr double kMinTwoSided = 0.5;
  if (r.two_sided_share < kMinTwoSided)
    throw InputError(file, "the cloud does not hold both the back and the palm of the hand: only " +
                               fixed(100 * r.two_sided_share, 0) +
                               " % of its 2 mm columns across the hand hold both (a hand seen all round: over 90 %); "
                               "scan it from both sides, or give its two halves (--cloud twice)");
  r.sheets = sheet_labels(r.prepared.normals, r.orientation.back);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

Json halves_against_truth(const CloudStageResult& r, const TruthSkin& truth) {
  HS_CHECK(r.halves.has_value(), "no halves");
  const RegistrationError e = registration_error(r.halves->alignment.a_to_b, truth.back_to_palm, truth.skin.vertices);
  return {{"rotation_deg", e.rotation_deg}, {"skin_mean_mm", e.mean_mm}, {"skin_max_mm", e.max_mm}, {"file", truth.path}};
}

Json halves_registration_json(const CloudStageResult& r) {
  HS_CHECK(r.halves.has_value(), "no halves");
  const CloudAlignment& a = r.halves->alignment;
  Json timings = Json::object();
  for (const auto& [step, ms] : a.timings_ms) timings[step] = ms;
  return {{"format", "handskin-registration/1"},
          {"method", "markerless"},
          {"back", r.files[0].path},
          {"palm", r.files[1].path},
          {"back_to_palm", isometry_to_json(a.a_to_b)},
          {"candidates", a.candidates},
          {"overlap_share", a.overlap_share},
          {"rms_mm", a.rms_mm},
          {"uncertainty", {{"rotation_deg", a.rotation_sigma_deg}, {"displacement_mm", a.displacement_sigma_mm}}},
          {"kept", {{"back", r.halves->kept_a}, {"palm", r.halves->kept_b}}},
          {"timings_ms", timings}};
}

Json to_json(const CloudStageResult& r) {
  const PreparedCloud& p = r.prepared;
  Json files = Json::array();
  for (const auto& f : r.files)
    files.push_back({{"path", f.path}, {"format", f.format}, {"points", f.points}, {"no_return", f.no_return},
                     {"normals", f.normals}, {"faces", f.faces}, {"surface_samples", f.surface_samples}});
  size_t back = 0;
  for (auto s : r.sides) back += s == 1;
  Json j = {{"name", "cloud"},
            {"seconds", r.seconds},
            {"files", files},
            {"units", r.units},
            {"cleaning", {{"read", p.read}, {"downsampled", p.downsampled}, {"voxel_mm", p.voxel_mm}, {"outliers", p.outliers}, {"support", p.support},
                          {"support_found", p.support_found}, {"other_parts", p.other_parts}, {"parts", p.parts},
                          {"kept", p.points.size()}, {"spacing_mm", p.spacing_mm}, {"part_gap_mm", p.part_gap_mm},
                          {"noise_mm", p.noise_mm}, {"support_band_mm", p.support_band_mm}}},
            {"extent_mm", {p.extent_mm(0), p.extent_mm(1), p.extent_mm(2)}},
            {"normals", p.normals_from_file ? "file" : "estimated"},
            {"orientation", {{"by", r.orientation.by}, {"back", {r.orientation.back(0), r.orientation.back(1), r.orientation.back(2)}},
                             {"finger_flexion", r.orientation.flexion}, {"hand", hand_side_name(r.orientation.side)},
                             {"note", r.orientation.note}}},
            {"sides", {{"palm", r.sides.size() - back}, {"back", back}}},
            {"two_sided_share", r.two_sided_share}};
  Json timings = Json::object();
  for (const auto& [step, ms] : p.timings_ms) timings[step] = ms;
  j["timings_ms"] = timings;
  if (r.halves) j["registration"] = halves_registration_json(r);
  if (p.support_found)
    j["cleaning"]["support_plane"] = {p.support_plane(0), p.support_plane(1), p.support_plane(2), p.support_plane(3)};
  return j;
}

}  // namespace handskin
