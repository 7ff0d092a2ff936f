#include "pipeline/skin_stage.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <future>
#include <optional>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/threads.hpp"
#include "patches/layout.hpp"
#include "render/preview.hpp"
#include "pipeline/figures_json.hpp"
#include "pipeline/skin_grid.hpp"
#include "pipeline/stage_options.hpp"

namespace handskin {

namespace {
// A fingertip the traced lines put farther than this from the placed skeleton's has the skin
// built on both (on none of the family's 96 runs, the WebXR hand's 32 or the unusual hands' 16).
constexpr double kTracedTipGapMm = 6.0;
// ... and their skin is kept when it lies nearer the cloud by more than this share of the first
// skin's mean distance: a random hand's curled index (R12 of `random_hands_study.py --draw 69`,
// 27/44/22 deg) gave a traced skin 2.8 % nearer (0.0774 against 0.0796 mm) whose patches folded
// by 166 deg at its tip; the curled middle finger the traced lines are for (R05 of draw 70)
// gave one 25 % nearer.
constexpr double kTracedNearerShare = 0.05;

// The largest distance between two rigs' fingertips (the thumb's left out).
double tip_gap(const Rig& a, const Rig& b) {
  double gap = 0;
  for (int f = 1; f < kFingerCount; ++f) {
    const int tip = finger_chain(static_cast<Finger>(f)).back();
    gap = std::max(gap, (a.joints[tip] - b.joints[tip]).norm());
  }
  return gap;
}

// What an error caught in flight says (an InputError's detail, else its message).
std::string error_line(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const InputError& x) {
    return x.detail();
  } catch (const std::exception& x) {
    return x.what();
  } catch (...) {
    return "an unknown error";
  }
}
}  // namespace

Json slicing_to_json(const Slicing& s) {
  Json j;
  j["format"] = "handskin-slices/1";
  j["spacing_mm"] = s.spacing;
  j["plane_x_mm"] = s.plane_x;
  j["hand_from_rig"] = Json::array();
  for (int r = 0; r < 4; ++r) {
    Json row = Json::array();
    for (int c = 0; c < 4; ++c) row.push_back(s.T_hand_rig.matrix()(r, c));
    j["hand_from_rig"].push_back(row);
  }
  Json bones = Json::array();
  for (const auto& b : s.bones) bones.push_back(b.name());
  j["bones"] = bones;
  Json secs = Json::array();
  for (const auto& sec : s.sections) {
    Json pts = Json::array(), phi = Json::array(), rho = Json::array();
    for (size_t i = 0; i < sec.points.size(); ++i) {
      pts.push_back(to_json(sec.points[i]));
      phi.push_back(sec.phi[i] * 180.0 / M_PI);
      rho.push_back(sec.rho[i]);
    }
    secs.push_back({{"plane", sec.plane}, {"bone", sec.bone}, {"closed", sec.closed}, {"measured", sec.measured},
                    {"largest_gap_deg", sec.largest_gap_deg}, {"centre", to_json(sec.centre)}, {"phi_deg", phi},
                    {"rho_mm", rho}, {"points", pts}});
  }
  j["sections"] = secs;
  return j;
}


namespace {

double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

Json health_json(const MeshHealth& h) {
  return {{"vertices", h.vertices}, {"triangles", h.faces}, {"closed", h.closed()}, {"manifold", h.manifold()},
          {"components", h.components}, {"outward", h.volume_mm3 > 0}, {"volume_mm3", h.volume_mm3},
          {"area_mm2", h.area_mm2}};
}

std::string mm(double v) { return std::to_string(v).substr(0, std::to_string(v).find('.') + 2); }

}  // namespace

Rig load_palm_rig(const std::string& path) {
  Rig rig = load_rig(path);
  if (rig.frame != "palm")
    throw InputError(path, "key 'frame' is \"" + rig.frame +
                               "\"; the skin needs joints in the palm frame (the palm scan's, as `synth scan` writes "
                               "rig.json; a rig in a cloud's own frame goes with `run --cloud`)");
  return rig;
}

std::optional<std::string> orient_rig_to_cloud(Rig* rig, const std::vector<Eigen::Vector3d>& points,
                                               const std::vector<std::uint32_t>& sides) {
  const Eigen::Vector3d z = hand_frame_from_rig(*rig).linear().row(2).transpose();
  double back = 0, palm = 0;
  size_t nb = 0, np = 0;
  for (size_t k = 0; k < points.size() && k < sides.size(); ++k)
    (sides[k] == 1 ? back : palm) += points[k].dot(z), ++(sides[k] == 1 ? nb : np);
  if (nb < 100 || np < 100) return std::nullopt;
  const bool agrees = back / nb > palm / np;
  const bool given = rig->palm_normal.has_value();
  rig->palm_normal = agrees ? z : Eigen::Vector3d(-z);
  if (agrees) return given ? std::string() : std::string("palm_normal not given: taken from the joints, as the scans agree");
  return given ? std::string("its palm_normal points into the palm (the back scan's points lie the other way): turned")
               : std::string("palm_normal not given: taken from the scans (the joints alone point it into the palm, "
                             "as for a left hand)");
}

namespace {

// The automatic skeleton against the given rig: a rig of another hand or scan is refused
// (unless --auto-rig), one a little off is warned about.
void check_given_rig(const SkinStageInputs& in, const SkinOptions& so,
                     const std::function<void(const std::string&)>& progress, SkinStageResult* Rp) {
  SkinStageResult& R = *Rp;
  const JointError e = joint_error(R.placed->rig, *in.rig);
  // Far from the given rig, on which the skin was built: the placed skeleton is the one that
  // does not fit when the skin would refuse it (a hand spread 15 deg with its thumb at 70 deg,
  // before the placement took its wrist from the palm: the placement's thumb 4.0 mm off its
  // sections, its wrist 101 mm from the given one's, and the given rig, the pair's own, had
  // been refused as another hand's). A rig of another scan or with its digits out of order is
  // refused by the skin or by a placement that fits.
  if (e.mean_mm > kRigRefuseMm && !in.auto_rig)
    if (std::string why = digits_off_their_sections(in.points, R.placed->rig, so); !why.empty()) {
      R.placement_failed = "the skeleton placed in the cloud does not fit it: " + why;
      R.placed.reset();
      return;
    }
  R.against_given = e;
  progress("automatic skeleton: mean joint error " + mm(e.mean_mm) + " mm against the given rig");
  if (e.mean_mm > kRigRefuseMm && !in.auto_rig)
    throw InputError(in.rig_name, "its joints lie " + mm(e.mean_mm) + " mm (mean; worst " + e.worst_joint + ", " +
                                      mm(e.max_mm) + " mm) from the skeleton found in " + in.cloud_name +
                                      " (more than " + mm(kRigRefuseMm) +
                                      "): a rig of another hand or scan, or with its digits out of order; give "
                                      "this scan's rig, or none to place it automatically");
  if (e.mean_mm > kRigWarnMm)
    R.warnings.push_back("the given rig lies " + mm(e.mean_mm) + " mm (mean) from the skeleton placed in the cloud "
                         "(worst: " + e.worst_joint + "); is it this scan's rig?");
}

// The skin's figures: the cloud against it, the slices, the Poisson baseline and the truth
// when asked for.
void measure_skin(const SkinStageInputs& in, const SkinOptions& so, const std::function<void(const std::string&)>& progress,
                  SkinStageResult* Rp) {
  SkinStageResult& R = *Rp;
  const SkinResult& skin = R.skin;
  progress("measuring the cloud against the skin");
  const MeshDistance to_skin(skin.mesh);
  const auto cloud = thinned_points(in.points, kCloudToSkinPoints);
  R.cloud_to_skin = one_way_distance(cloud, to_skin);
  if (in.slices && !R.slices) R.slices = slice_cloud(in.points, R.rig, so.slicing);

  std::optional<MeshDistance> to_base;
  if (in.baseline) {
    progress("baseline: Poisson reconstruction of the same cloud (for comparison)");
    SkinBaseline b;
    b.result = poisson_baseline(in.points, in.normals);
    b.health = mesh_health(b.result.mesh);
    to_base.emplace(b.result.mesh);
    b.cloud_to_baseline = one_way_distance(cloud, *to_base);
    R.baseline = std::move(b);
  }
  if (in.truth) {
    const TruthSkin& t = *in.truth;
    progress("comparing with the true skin of " + t.path);
    const auto t_truth = std::chrono::steady_clock::now();
    const MeshDistance to_truth(t.skin);
    const auto ours = sample_surface(skin.mesh, 4.0), theirs = sample_surface(t.skin, 4.0);
    SkinTruthFigures f;
    f.skin_path = t.skin_path;
    f.exclude_mm = t.exclude_mm;
    f.skin_to_truth = one_way_distance(ours, to_truth, t.markers, t.exclude_mm);
    f.truth_to_skin = one_way_distance(theirs, to_skin, t.markers, t.exclude_mm);
    if (R.baseline) {
      f.baseline_to_truth =
          one_way_distance(sample_surface(R.baseline->result.mesh, 4.0), to_truth, t.markers, t.exclude_mm);
      f.truth_to_baseline = one_way_distance(theirs, *to_base, t.markers, t.exclude_mm);
    }
    f.seconds = since(t_truth);
    R.truth = std::move(f);
  }
}

}  // namespace

SkinStageResult run_skin_stage(const SkinStageInputs& in, const PipelineOptions& options,
                               const std::function<void(const std::string&)>& progress) {
  const auto t_stage = std::chrono::steady_clock::now();
  SkinOptions so = skin_options(options);  // checked by build_skin (and when the pipeline was read)
  SkinStageResult R;
  R.automatic = in.auto_rig || !in.rig;
  so.rig_given = !R.automatic;
  // Errors of the skin steps say "rig" or "merged cloud": name the file the user gave, or the
  // automatic skeleton when that is what the skin was built on (also with --rig --auto-rig).
  auto renamed = [&](const InputError& e) {
    // A tube folding on every placement (R12 of scripts/random_hands_study.py --draw 72) is the
    // placement's failure too: the way on is the same.
    if (const auto* fold = dynamic_cast<const TubeFoldsError*>(&e); fold && R.automatic)
      return InputError("automatic skeleton", std::string("the ") + skin_tube_name(fold->tube) +
                                                  " tube folds into itself on every placement tried; the automatic "
                                                  "placement missed this hand: give its rig (--rig)");
    if (e.where() == "rig" && R.automatic)
      return InputError("automatic skeleton", e.detail() + "; the automatic placement missed this hand: give its rig (--rig)");
    if (e.where() == "rig") {  // a hint where the step gave none
      const std::string& d = e.detail();
      // A rig placed by hand a few millimetres off the digits' axes is refused too (the
      // family's H01 with 3 mm of noise on every joint: "the ring's links lie 3.3 mm from the
      // middle of its sections"): the hint names that and the way on without a rig.
      return InputError(in.rig_name, !d.empty() && d.back() == '?'
                                         ? d
                                         : d + " (a rig of another scan, its digits swapped, or its joints placed off the "
                                               "digits' axes? without --rig, or with --auto-rig, the skeleton is placed in "
                                               "the scan)");
    }
    if (e.where() == "merged cloud") return InputError(in.cloud_name, e.detail());
    return e;
  };
  // --- the skeleton: given, or placed in the cloud (and the given one checked against it) ---
  // With a rig given, the placement (its check) and the skin build are independent: they run
  // at once, and their errors are reported in the order of a sequential run (the check first).
  auto place = [&] {
    const auto ta = std::chrono::steady_clock::now();
    try {
      if (R.automatic) progress("placing the skeleton in the cloud");
      R.placed = place_skeleton(in.points, in.sides);
      // Fault injection for tests (docs/architecture.md): HANDSKIN_FAULT=placement-off moves
      // the placed skeleton 25 mm aside, a placement that missed the hand.
      if (const char* f = std::getenv("HANDSKIN_FAULT"); f && std::string(f) == "placement-off")
        for (auto& j : R.placed->rig.joints) j.y() += 25.0;
    } catch (const InputError& e) {
      if (R.automatic) throw renamed(e);
      R.placement_failed = e.what();
    }
    R.placement_seconds = since(ta);
  };
  std::exception_ptr build_error;
  std::string rig_refused;  // the build's error, when it refused the rig
  std::vector<int> folded;  // the digits whose tubes folded on a placed skeleton (0 the thumb)
  // The cloud's mean distance to the skin just built, its points thinned once as measure_skin
  // thins them: what chooses between two placements' skins.
  std::vector<Eigen::Vector3d> thinned;
  auto cloud_mean = [&] {
    if (thinned.empty()) thinned = thinned_points(in.points, kCloudToSkinPoints);
    return one_way_distance(thinned, MeshDistance(R.skin.mesh)).mean;
  };
  // One skin built on `rig`: its result or its error, which the stage's state takes in the
  // order a run of one build after another takes them (`apply`). A build can run on a thread
  // of its own beside another (`build_beside`): its progress lines are kept and said when it is
  // applied, and it touches nothing of the stage's until then.
  struct BuildOutcome {
    std::optional<SkinResult> skin;  // built
    std::exception_ptr error;        // else why not
    std::string refused;             // the error, when it refused the rig
    int folded = -1;                 // the digit (0 the thumb) whose tube folded
    double seconds = 0;
    std::vector<std::string> lines;  // its progress, when built beside
  };
  auto try_build = [&](const Rig& rig, const std::function<void(const std::string&)>& say,
                       const std::function<void()>& beside, const std::function<void()>& accepted) {
    BuildOutcome b;
    const auto tb = std::chrono::steady_clock::now();
    try {
      SkinResult skin = build_skin(in.points, rig, so, say, beside, accepted);
      // A placed skeleton must also carry the patches' layout: its corners are cast from the
      // joints onto the skin, and a placement whose curled finger's tip it put short of the
      // true one (past the DIP, along the finger's line where the finger turned down) built a
      // skin whose distal row had two corners on one spot, and the run stopped in the patch
      // stage (R10 of `scripts/random_hands_study.py --draw 70`). Such a placement is refused
      // like one whose links miss their sections, and the next is tried.
      if (R.automatic) try {
          (void)hand_patch_layout(skin, rig, in.points, in.sides);
        } catch (const InputError& e) {
          throw InputError("rig", "the patch layout cannot be laid on its skin: " + e.detail());
        }
      b.skin = std::move(skin);
    } catch (const TubeFoldsError& e) {
      b.error = std::current_exception();
      if (R.automatic) b.refused = e.detail();  // says the same of a placed skeleton as a refusal
      if (R.automatic && e.tube >= 1) b.folded = e.tube - 1;
    } catch (const InputError& e) {
      b.error = std::current_exception();
      if (e.where() == "rig") b.refused = e.detail();
    } catch (...) {
      b.error = std::current_exception();
    }
    b.seconds = since(tb);
    return b;
  };
  auto apply = [&](BuildOutcome b) {
    for (const std::string& line : b.lines) progress(line);
    build_error = b.error;
    rig_refused = std::move(b.refused);
    if (b.skin) R.skin = std::move(*b.skin);
    if (b.folded >= 0 && std::find(folded.begin(), folded.end(), b.folded) == folded.end()) folded.push_back(b.folded);
    R.build_seconds = b.seconds;
  };
  auto build = [&](const Rig& rig, const std::function<void()>& beside = {}, const std::function<void()>& accepted = {}) {
    apply(try_build(rig, progress, beside, accepted));
  };
  // The automatic placement builds a second skin on another placement in two places (the
  // traced fingers' lines, the two centred placements), each independent of the first but for
  // the first's outcome, which decides whether it is needed. It is started on the second
  // thread as soon as the first has passed the check of its links (build_skin's `accepted`),
  // and runs beside the first's union and later steps, which keep one thread busy: on the
  // random hands of `scripts/random_hands_study.py --draw 73` the skin stage's automatic runs
  // took one build less of wall time (docs/performance.md). Not needed, it is dropped (with
  // one thread, a deferred build never runs). Its skin is the one a later build makes: the same
  // bytes either way.
  auto build_beside = [&](const Rig& rig) {
    return std::async(side_launch(), [&, rig] {
      std::vector<std::string> lines;
      BuildOutcome b = try_build(rig, [&lines](const std::string& m) { lines.push_back(m); }, {}, {});
      b.lines = std::move(lines);
      return b;
    });
  };
  progress("building the strips (" + std::to_string(so.slicing.planes) + " planes, " +
           std::to_string(so.slicing.points_per_segment) + " points per segment)");
  if (R.automatic) {
    place();
    R.rig = R.placed->rig;
    // The fingers' lines traced in their flexion planes (below; also one of the fallbacks
    // after a refusal): placed beside the first skin's build.
    std::future<std::optional<AutoRig>> tracing = std::async(side_launch(), [&]() -> std::optional<AutoRig> {
      try {
        return place_skeleton(in.points, in.sides, DigitParting::Silhouette, CentreLines::Traced);
      } catch (const InputError&) {
        return std::nullopt;
      }
    });
    std::optional<std::optional<AutoRig>> traced_placement;  // got once
    auto traced_rig_placement = [&]() -> const std::optional<AutoRig>& {
      if (!traced_placement) traced_placement = tracing.get();
      return *traced_placement;
    };
    std::future<BuildOutcome> traced_build;  // the traced placement's skin, built beside the first
    build(R.rig, {}, [&] {
      const std::optional<AutoRig>& traced = traced_rig_placement();
      if (traced && tip_gap(traced->rig, R.rig) > kTracedTipGapMm) traced_build = build_beside(traced->rig);
    });
    // The skin took the placement. But a finger curled past ~45 deg at its PIP can be followed
    // by the quadratic centre line and still be missed: the line runs on past the curl, and the
    // fingertip lands 15 mm beyond the true one, along the finger's first direction, in flesh
    // the skin then builds (R05 of `scripts/random_hands_study.py --draw 70`, its middle finger
    // at 45/41/5 deg: 0.72 mm mean from the true skin). Where the fingers' lines traced in their
    // flexion planes (step 7 below) put a fingertip more than kTracedTipGapMm from the placed
    // one, the skin is built on them too, and kept if it lies nearer the cloud (mean) by more
    // than kTracedNearerShare.
    if (!build_error && rig_refused.empty()) {
      const std::optional<AutoRig>& traced = traced_rig_placement();
      const double gap = traced ? tip_gap(traced->rig, R.rig) : 0.0;
      if (gap > kTracedTipGapMm) {
        char line[400];
        std::snprintf(line, sizeof line,
                      "the fingers' lines traced in their flexion planes put a fingertip %.1f mm from the placed one; "
                      "building the skin on them too",
                      gap);
        progress(line);
        const double first_mean = cloud_mean();
        SkinResult first_skin = std::move(R.skin);
        double build_seconds = R.build_seconds;  // every build's, for the report
        Rig traced_rig = traced->rig;
        if (traced_build.valid())
          apply(traced_build.get());
        else
          build(traced_rig);
        build_seconds += R.build_seconds;
        // Refused (a digit's links off its sections: the middle finger above, 2.8 mm, allowed
        // 2.7), those digits' joints moved onto their sections' middles, as the last fallback
        // below does.
        std::optional<Rig> centred;
        if (!rig_refused.empty()) try {
            centred = centre_digit_links(in.points, traced_rig, so, folded);
          } catch (const InputError&) {
          }
        if (centred) {
          traced_rig = *centred;
          build(traced_rig);
          build_seconds += R.build_seconds;
        }
        const double traced_mean = build_error ? 0.0 : cloud_mean();
        if (!build_error && traced_mean < (1.0 - kTracedNearerShare) * first_mean) {
          std::snprintf(line, sizeof line,
                        "the fingers' centre lines traced in their flexion planes%s: their skin lies nearer the cloud "
                        "(mean %.4f mm) than the quadratic lines' (%.4f mm), whose fingertip lay %.1f mm away",
                        centred ? ", the refused digits' joints moved onto their sections' middles" : "", traced_mean,
                        first_mean, gap);
          R.placed = *traced;
          R.placed->rig = traced_rig;
          R.placed->notes.push_back(line);
          R.rig = traced_rig;
        } else {
          R.skin = std::move(first_skin);
          if (build_error)
            std::snprintf(line, sizeof line,
                          "the fingers' lines traced in their flexion planes put a fingertip %.1f mm away; no skin "
                          "built on them (%s)",
                          gap, rig_refused.empty() ? error_line(build_error).c_str() : rig_refused.c_str());
          else
            std::snprintf(line, sizeof line,
                          "the fingers' lines traced in their flexion planes put a fingertip %.1f mm away; their skin "
                          "lay not %.0f %% nearer the cloud (mean %.4f mm against %.4f)",
                          gap, 100 * kTracedNearerShare, traced_mean, first_mean);
          R.placed->notes.push_back(line);
          build_error = nullptr;
          rig_refused.clear();
        }
        R.build_seconds = build_seconds;
      }
    }
    // The skin refused the placed skeleton (its links off the middle of a digit's sections):
    // once more with the thumb's base on the thumb's own centre line. The proportions put it
    // in the thenar, which suits a thumb near the palm's plane; a thumb raised and turned out
    // of it (the WebXR hand) then has its metacarpal's link cross the thenar off its sections.
    // Then the skeleton placed again with the digits parted by the sheets (a finger touching
    // its neighbour along most of its length leaves only its tip to the silhouette's parting:
    // H12 of the family as a cloud), with either thumb base. Then with curled fingers traced in
    // their flexion planes (auto_rig.hpp, CentreLines).
    if (!rig_refused.empty()) {
      const std::string first = rig_refused;
      const std::exception_ptr refused = build_error;
      // A placement with `rig` for its skeleton, its notes saying how and why (the first refusal).
      auto placed_as = [&](const AutoRig& placed, const Rig& rig, const std::string& note) {
        AutoRig kept = placed;
        kept.rig = rig;
        kept.notes.push_back(note + first);
        return kept;
      };
      auto attempt = [&](const AutoRig& placed, const Rig& rig, const std::string& note) {
        build(rig);
        if (build_error) return false;
        R.placed = placed_as(placed, rig, note);
        R.rig = rig;
        return true;
      };
      const std::string base_note = "the thumb's base placed on the thumb's centre line: with the proportions' base, ";
      progress("the skin refused the placed skeleton (" + first + "); trying the thumb's base on its centre line");
      bool ok = attempt(*R.placed, R.placed->thumb_base_on_line, base_note);
      if (!ok) {
        progress("trying the skeleton placed with the digits parted by the sheets");
        std::optional<AutoRig> by_sheets;
        try {
          by_sheets = place_skeleton(in.points, in.sheets.empty() ? in.sides : in.sheets, DigitParting::Sheets);
        } catch (const InputError&) {  // no five digits that way either: the first refusal stands
        }
        const std::string sheets_note = "the digits parted by the sheets: with the silhouette's, ";
        ok = by_sheets && (attempt(*by_sheets, by_sheets->rig, sheets_note) ||
                           attempt(*by_sheets, by_sheets->thumb_base_on_line, sheets_note + "and " + base_note));
      }
      std::optional<AutoRig> traced;
      if (!ok) {
        // Fingers curled past what the centre lines' quadratic height follows (PIPs at 55-60
        // deg: their tips were put on the DIPs' knuckles): their lines traced in their
        // flexion planes.
        progress("trying the skeleton placed with the fingers' lines traced in their flexion planes");
        traced = traced_rig_placement();
        const std::string traced_note = "the fingers' centre lines traced in their flexion planes: with their quadratic lines, ";
        ok = traced && (attempt(*traced, traced->rig, traced_note) ||
                        attempt(*traced, traced->thumb_base_on_line, traced_note + "and " + base_note));
      }
      if (!ok) {
        // A digit the placements put beside its sections every way (the WebXR hand's thumb
        // bent across the palm at its CMC, MCP and IP: 2.9-3.5 mm off, allowed 2.6-2.7; a
        // curled little finger's proximal link tilted against it): a placement with that
        // digit's joints fitted through its sections' middles. Both the traced placement
        // (when there is one) and the first, so centred, are built; the skin that lies nearer
        // the cloud's points (mean) is kept. Neither is the better everywhere: on a relaxed
        // curl (the test APlacedLinkTiltedAgainstItsCurledFingerIsFittedThroughItsSections)
        // the first's skin is (truth within 1 mm 97.3 % against 95.7 %; cloud 0.070 mm from
        // it against 0.122), on the probe hands' pointing hand (U2) and the WebXR hand's two
        // bent-thumb pairs that come this far the traced one's (93.5 against 92.7 %, 99.38
        // against 99.26, 99.33 against 99.05; cloud 0.0693 / 0.0698 / 0.0700 mm against
        // 0.0779 / 0.0701 / 0.0703). A tie keeps the traced one. A digit whose tube folded on
        // any placement is centred too (R08 of scripts/random_hands_study.py: its thumb folded
        // on every placement, with no digit off its sections, and the run stopped).
        struct Centring {
          const AutoRig* placed;
          const char* which;  // in the progress line
          const char* note;
        };
        std::vector<Centring> order;
        if (traced) order.push_back({&*traced, "traced", "the traced fingers' joints moved onto their sections' middles: placed, "});
        order.push_back({&*R.placed, "placed", "the digits' joints moved onto their sections' middles: placed, "});
        struct Built {
          SkinResult skin;
          Rig rig;
          AutoRig placed;
          double cloud_mean_mm = 0;
        };
        std::vector<Built> built;
        const auto centre = [&](const Centring& c) -> std::optional<Rig> {
          try {
            return centre_digit_links(in.points, c.placed->rig, so, folded);
          } catch (const InputError&) {
            return std::nullopt;
          }
        };
        // The second placement's skin is built beside the first's (build_beside) when its
        // centring does not wait on the first's outcome: it takes the digits that folded, and
        // is made again (and built after) when the first's build adds one.
        const std::vector<int> folded_before = folded;
        std::optional<Rig> next_centred;
        std::future<BuildOutcome> next_build;
        for (size_t k = 0; k < order.size(); ++k) {
          const Centring& c = order[k];
          std::optional<Rig> centred = k > 0 && folded == folded_before && next_centred ? next_centred : centre(c);
          if (!centred) continue;
          progress(std::string("trying the ") + c.which + " skeleton with its digits' joints moved onto their sections' middles");
          if (k > 0 && next_build.valid() && folded == folded_before) {
            apply(next_build.get());
          } else {
            build(*centred, {}, [&] {
              if (k + 1 < order.size() && (next_centred = centre(order[k + 1]))) next_build = build_beside(*next_centred);
            });
          }
          if (build_error) continue;
          const double mean = cloud_mean();
          built.push_back({std::move(R.skin), *centred, placed_as(*c.placed, *centred, c.note), mean});
        }
        if (!built.empty()) {
          auto best = std::min_element(built.begin(), built.end(),
                                       [](const Built& a, const Built& b) { return a.cloud_mean_mm < b.cloud_mean_mm; });
          if (built.size() > 1) {
            char line[160];
            std::snprintf(line, sizeof line,
                          "of the two centred placements, the one whose skin lies nearer the cloud (mean %.4f mm; the "
                          "other's %.4f mm)",
                          best->cloud_mean_mm, built[best == built.begin() ? 1 : 0].cloud_mean_mm);
            best->placed.notes.push_back(line);
          }
          R.skin = std::move(best->skin);
          R.rig = best->rig;
          R.placed = std::move(best->placed);
          build_error = nullptr;
          ok = true;
        }
      }
      if (!ok) build_error = refused;  // the first refusal is the one to report
    }
  } else {
    R.rig = *in.rig;
    if (const auto note = orient_rig_to_cloud(&R.rig, in.points, in.sides); note && !note->empty()) {
      R.rig_orientation = *note;
      progress(in.rig_name + ": " + *note);
    }
    // The placement (the given rig's check), the thesis's sections (they need the cloud and
    // the rig only) and the caller's work beside the build's first steps (build_skin's
    // `beside`: ~125 ms of steps that two threads make hardly faster, against ~20 + ~30 ms for
    // the two and ~60 ms for the run's picture of the merged cloud); the build's later steps
    // then have both threads.
    build(R.rig, [&] {
      place();  // a given rig: the placement records its failure, never throws
      // A placed skeleton whose joints lie outside the cloud (the placement lost this hand:
      // a broad, thick hand with its fingers together, 240 mm long, in
      // scripts/unusual_hands_study.py) is the placement's failure, not a check of the given
      // rig: compared with it, it had the given rig refused as another hand's (101 mm).
      if (R.placed)
        if (std::string why = rig_outside_cloud(in.points, R.placed->rig); !why.empty()) {
          R.placement_failed = "the skeleton placed in the cloud does not fit it: " + why;
          R.placed.reset();
        }
      try {
        if (in.slices) R.slices = slice_cloud(in.points, R.rig, so.slicing);
      } catch (...) {  // made again after the build (measure_skin), which reports the error in turn
      }
      if (in.beside_build) in.beside_build();
    });
  }
  if (R.placed && in.rig) check_given_rig(in, so, progress, &R);
  if (in.rig && !R.automatic && !R.placement_failed.empty())
    R.warnings.push_back("the given rig is used unchecked: the automatic placement missed this hand (" +
                         R.placement_failed + ")");
  if (build_error) {
    try {
      std::rethrow_exception(build_error);
    } catch (const InputError& e) {
      throw renamed(e);
    }
  }
  R.warnings.insert(R.warnings.end(), R.skin.warnings.begin(), R.skin.warnings.end());
  for (const auto& w : R.warnings) progress("warning: " + w);
  const SkinResult& skin = R.skin;
  if (!skin.watertight())
    throw InputError(in.cloud_name, std::string("the skin is not a closed, manifold, outward, self-intersection-free "
                                                "surface (") +
                                        std::to_string(skin.health.boundary_edges) + " boundary edges, " +
                                        std::to_string(skin.health.nonmanifold_vertices) + " non-manifold vertices, " +
                                        std::to_string(skin.health.components) + " components" +
                                        (skin.self_intersects ? ", self-intersecting" : "") + ")");
  measure_skin(in, so, progress, &R);
  R.seconds = since(t_stage);
  return R;
}

Json to_json(const SkinStageResult& r) {
  const SkinResult& skin = r.skin;
  Json skeleton;
  if (r.placed) {
    skeleton["automatic"] = {{"seconds", r.placement_seconds}, {"scale", r.placed->scale},
                             {"palm_radius_mm", r.placed->palm_radius_mm}, {"notes", r.placed->notes}};
    if (r.against_given)
      skeleton["automatic"]["against_given_rig"] = {{"mean_joint_error_mm", r.against_given->mean_mm},
                                                    {"max_joint_error_mm", r.against_given->max_mm},
                                                    {"worst_joint", r.against_given->worst_joint}};
  } else if (!r.placement_failed.empty()) {
    skeleton["automatic"] = {{"failed", r.placement_failed}};
  }
  skeleton["used"] = r.automatic ? "automatic" : "given";
  if (!r.rig_orientation.empty()) skeleton["given_rig_orientation"] = r.rig_orientation;
  Json j;
  j["name"] = "skin";
  j["seconds"] = r.seconds;
  j["build_seconds"] = r.build_seconds;
  j["skeleton"] = skeleton;
  j["mesh"] = health_json(skin.health);
  j["mesh"]["self_intersections"] = skin.self_intersects;
  j["mesh"]["watertight"] = skin.watertight();
  j["triangles_before_decimation"] = skin.triangles_before_decimation;
  j["pockets_removed"] = skin.pockets_removed;
  j["crossings_mended"] = skin.crossings_mended;
  j["thumb_turns_slowly"] = skin.thumb_turns_slowly;
  j["fit_to_data"] = {{"points", skin.data_fit.points},
                      {"moved", skin.data_fit.moved},
                      {"reverted", skin.data_fit.reverted},
                      {"mean_move_mm", skin.data_fit.mean_move_mm},
                      {"max_move_mm", skin.data_fit.max_move_mm}};
  j["fair_unseen"] = {{"vertices", skin.fair_unseen.vertices},
                      {"unseen", skin.fair_unseen.unseen},
                      {"crease_vertices", skin.fair_unseen.crease_vertices},
                      {"faired", skin.fair_unseen.faired},
                      {"held", skin.fair_unseen.held},
                      {"taken_back", skin.fair_unseen.taken_back},
                      {"mean_move_mm", skin.fair_unseen.mean_move_mm},
                      {"max_move_mm", skin.fair_unseen.max_move_mm}};
  j["timings_ms"] = {{"rings", 1000 * skin.seconds_rings}, {"stitch", 1000 * skin.seconds_union},
                     {"decimate", 1000 * skin.seconds_decimation}, {"fit", 1000 * skin.seconds_fit},
                     {"checks", 1000 * skin.seconds_checks}};
  Json tubes = Json::array();
  for (const auto& t : skin.tubes)
    tubes.push_back({{"name", t.name}, {"present", t.present}, {"points", t.points}, {"rings", t.rings},
                     {"measured", t.measured}, {"filled", t.filled}, {"partial", t.partial}, {"axis_offset_mm", t.axis_offset_mm}, {"axis_offset_seen_mm", t.axis_offset_seen_mm},
                     {"section_radius_mm", t.section_radius_mm}});
  j["tubes"] = tubes;
  const WristCut& cut = skin.wrist_cut;
  j["wrist_cut"] = {{"fitted", cut.fitted}, {"tilt_deg", cut.tilt_deg}, {"rim_points", cut.rim_points},
                    {"rms_mm", cut.rms_mm}, {"normal_hand_frame", to_json(cut.n)}};
  Json webs = Json::array();
  for (const auto& w : skin.webs) webs.push_back(to_json(w));
  j["webs_hand_frame"] = webs;
  Json bones = Json::array();
  for (const auto& b : skin.bones) bones.push_back(b.name());
  j["bones"] = bones;
  j["warnings"] = r.warnings;
  j["cloud_to_skin_mm"] = to_json(r.cloud_to_skin);
  if (r.baseline) {
    const auto& b = *r.baseline;
    j["baseline"] = {{"method", "PCL Poisson (Kazhdan), depth 7, one thread"},
                     {"seconds", b.result.seconds},
                     {"points_used", b.result.points_used},
                     {"faces_dropped", b.result.faces_dropped},
                     {"mesh", health_json(b.health)},
                     {"cloud_to_baseline_mm", to_json(b.cloud_to_baseline)}};
  }
  if (r.truth) {
    const auto& t = *r.truth;
    j["truth"] = {{"file", t.skin_path},
                  {"excluded_within_mm_of_markers", t.exclude_mm},
                  {"seconds", t.seconds},
                  {"skin_to_truth_mm", to_json(t.skin_to_truth)},
                  {"truth_to_skin_mm", to_json(t.truth_to_skin)}};
    if (t.baseline_to_truth) {
      j["truth"]["baseline_to_truth_mm"] = to_json(*t.baseline_to_truth);
      j["truth"]["truth_to_baseline_mm"] = to_json(*t.truth_to_baseline);
    }
  }
  return j;
}

const std::vector<std::string>& skin_output_names() {
  static const std::vector<std::string> names = {"skin.ply", "skin.obj", "skin.mtl", "skin.png", "skin_grid.json", "rig_auto.json",
                                                 "slices.json", "baseline.ply"};
  return names;
}

std::vector<std::string> skin_output_plan(bool automatic, bool slices, bool baseline) {
  std::vector<std::string> n = {"skin.ply", "skin.obj", "skin.png", "skin_grid.json"};
  if (automatic) n.push_back("rig_auto.json");
  if (slices) n.push_back("slices.json");
  if (baseline) n.push_back("baseline.ply");
  return n;
}

std::string skin_preview_png(const SkinStageResult& r, const TextureMap* texture, float texture_weight) {
  RenderOptions ro;
  ro.width = 900;
  ro.height = 500;
  ro.view = hand_frame_from_rig(r.rig).linear();  // looking at the back, fingers to the right
  ro.texture = texture;
  ro.texture_weight = texture_weight;
  return render_mesh_png({&r.skin.mesh}, ro);
}

Json write_skin_outputs(OutputSet& out, const SkinStageResult& r, const std::string& skin_png,
                        const TextureMap* texture, const std::function<void()>& ply_staged) {
  Json outputs;
  save_skin_ply(out.stage("skin.ply"), r.skin);
  outputs["skin_ply"] = out.final_path("skin.ply");
  if (ply_staged) ply_staged();
  const bool textured = texture && !texture->empty();
  write_file_atomic(out.stage("skin.obj"),
                    obj_text(r.skin.mesh, textured ? &texture->corner_uv : nullptr, textured ? "skin.mtl" : ""));
  outputs["skin_obj"] = out.final_path("skin.obj");
  if (textured) {
    write_file_atomic(out.stage("skin.mtl"),
                      "# handskin: the skin's material; its colour is the texture baked from the scans' photos\n"
                      "newmtl skin\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\nmap_Kd texture.png\n");
    outputs["skin_mtl"] = out.final_path("skin.mtl");
  }
  write_file_atomic(out.stage("skin.png"), skin_png);
  outputs["skin_png"] = out.final_path("skin.png");
  // Compact: ~5000 grid points; every number in its shortest round-trip form.
  write_file_atomic(out.stage("skin_grid.json"), skin_grid_to_json(r.skin, r.rig).dump() + "\n");
  outputs["skin_grid"] = out.final_path("skin_grid.json");
  if (r.automatic) {
    save_rig(out.stage("rig_auto.json"), r.rig);
    outputs["rig_auto"] = out.final_path("rig_auto.json");
  }
  if (r.slices) {
    save_json(out.stage("slices.json"), slicing_to_json(*r.slices));
    outputs["slices_json"] = out.final_path("slices.json");
  }
  if (r.baseline) {
    save_mesh(out.stage("baseline.ply"), r.baseline->result.mesh);
    outputs["baseline_ply"] = out.final_path("baseline.ply");
  }
  return outputs;
}

}  // namespace handskin
