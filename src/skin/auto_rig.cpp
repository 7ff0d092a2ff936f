#include "skin/auto_rig.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include <Eigen/Geometry>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/hand_proportions.hpp"
#include "skin/auto_rig_steps.hpp"
#include "skin/principal_axes.hpp"

namespace handskin {

namespace {

using namespace proportions;

// The palm widens into the thenar and hypothenar eminences this far (nominal mm) beyond the
// wrist joint (measured on the proportions' hand: the knee of its breadth along the hand).
constexpr double kKneeBeyondWrist = 12.0;

// In the palm, the joints' depth as a share of the palm's local thickness from its back: the
// metacarpals lie nearer the back than the palm (the palmar soft tissue is the thicker).
// Measured at the true joints of the synthetic family (12 hands, 160-215 mm, thin to thick):
// MCPs and metacarpal bases 0.39-0.42, the wrist 0.45-0.47, the thumb's base 0.56. Before,
// the MCPs took the height of their finger's centre line carried into the palm along its end
// tangent; on close or arched fingers that line is short and the heights strayed 9-12 mm (the
// metacarpal bases with them).
constexpr double kMetacarpalDepth = 0.41, kWristDepth = 0.46, kThumbBaseDepth = 0.56;

// The silhouette's breadth (across Yh) in 1 mm steps along Xh from the cut to the MCPs,
// fitted with a continuous two-piece line (a hinge); the hinge where the breadth starts to
// grow fast. Empty when the fit shows no such knee (the slope must at least double).
std::optional<double> breadth_knee(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector3d& Xh,
                                   const Eigen::Vector3d& Yh, double cut, double mcp_x, double s) {
  // Searched from the cut (or 170 nominal mm before the MCPs) to 60 before them: the knee
  // lies ~85 before them, and further into the palm the breadth grows slower again. The
  // forearm stub before the knee is the hinge's flat piece: a window that began 120 mm
  // before the MCPs lost most of it when the scale of the last round was too large (a 40 mm
  // stub, the knee not yet found), and the knee with it.
  const double x0 = std::max(cut + 1.5, mcp_x - 170 * s), x1 = mcp_x - 60 * s;
  const int n = static_cast<int>(x1 - x0);
  if (n < 8) return std::nullopt;
  std::vector<double> lo(n, 1e300), hi(n, -1e300);
  for (const auto& q : h) {
    const int b = static_cast<int>(std::floor(q.dot(Xh) - x0));
    if (b < 0 || b >= n) continue;
    lo[b] = std::min(lo[b], q.dot(Yh)), hi[b] = std::max(hi[b], q.dot(Yh));
  }
  std::vector<Eigen::Vector2d> xw;
  for (int b = 0; b < n; ++b)
    if (hi[b] > lo[b]) xw.emplace_back(x0 + b + 0.5, hi[b] - lo[b]);
  if (xw.size() < 8) return std::nullopt;
  double best = 1e300, best_k = 0, b1 = 0, b2 = 0;
  for (double k = x0 + 1; k <= x1 - 4; k += 0.5) {
    Eigen::MatrixXd A(xw.size(), 3);
    Eigen::VectorXd y(xw.size());
    for (size_t i = 0; i < xw.size(); ++i) {
      A.row(i) << 1, std::min(xw[i].x() - k, 0.0), std::max(xw[i].x() - k, 0.0);
      y(i) = xw[i].y();
    }
    const Eigen::Vector3d c = A.colPivHouseholderQr().solve(y);
    const double sse = (A * c - y).squaredNorm();
    if (sse < best) best = sse, best_k = k, b1 = c(1), b2 = c(2);
  }
  if (!(b2 > 0.3 && b2 > 2 * std::max(b1, 0.0))) return std::nullopt;
  return best_k;
}

// The middle of the cloud's section through `at` square to `a` (the points within 1.5 mm of
// that plane and within `window` of `at` along e1 and e2): the midpoint of their extents
// along e1 and e2, moved to and measured again, three times. Empty when the section does not
// close inside the window (it runs on into the palm or a neighbour) or holds < 30 points.
std::optional<Eigen::Vector3d> section_middle(const std::vector<Eigen::Vector3d>& h, Eigen::Vector3d at,
                                              const Eigen::Vector3d& a, const Eigen::Vector3d& e1,
                                              const Eigen::Vector3d& e2, double window) {
  for (int it = 0; it < 3; ++it) {
    double lo1 = 1e300, hi1 = -1e300, lo2 = 1e300, hi2 = -1e300;
    int n = 0;
    for (const auto& p : h) {
      const Eigen::Vector3d d = p - at;
      if (std::abs(d.dot(a)) > 1.5) continue;
      const double x1 = d.dot(e1), x2 = d.dot(e2);
      if (std::abs(x1) > window || std::abs(x2) > window) continue;
      lo1 = std::min(lo1, x1), hi1 = std::max(hi1, x1), lo2 = std::min(lo2, x2), hi2 = std::max(hi2, x2);
      ++n;
    }
    const double edge = 0.9 * window;
    if (n < 30 || lo1 < -edge || hi1 > edge || lo2 < -edge || hi2 > edge) return std::nullopt;
    at += 0.5 * (lo1 + hi1) * e1 + 0.5 * (lo2 + hi2) * e2;
  }
  return at;
}

// The centre line's direction at the curve point nearest q.
Eigen::Vector3d tangent_near(const auto_rig_steps::Digit& dg, const Eigen::Vector3d& q) {
  size_t best = 1;
  double bd = 1e300;
  for (size_t k = 1; k < dg.curve.size(); ++k)
    if (const double d = (dg.curve[k] - q).squaredNorm(); d < bd) bd = d, best = k;
  return Eigen::Vector3d((dg.curve[best] - dg.curve[best - 1]).normalized());
}

}  // namespace

namespace auto_rig_steps {

std::optional<double> depth_at(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector3d& at, double share,
                               double radius) {
  double lo = 1e300, hi = -1e300;
  int n = 0;
  for (const auto& q : h)
    if ((q.head<2>() - at.head<2>()).squaredNorm() < radius * radius) lo = std::min(lo, q.z()), hi = std::max(hi, q.z()), ++n;
  if (n < 5) return std::nullopt;
  return hi - share * (hi - lo);
}

// The hand's frame: long axis, thickness axis toward the back, X away from the wrist's end.
HandFrame principal_frame(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides) {
  HandFrame f;
  Eigen::Matrix3d axes;
  principal_axes<3>(pts, &axes, &f.c);
  const Eigen::Vector3d& c = f.c;
  Eigen::Vector3d X = axes.col(0), Z = axes.col(2);
  Eigen::Vector3d back = Eigen::Vector3d::Zero(), palm = Eigen::Vector3d::Zero();
  size_t nb = 0, np = 0;
  for (size_t i = 0; i < pts.size(); ++i)
    if (sides[i] <= 1) (sides[i] == 1 ? (++nb, back) : (++np, palm)) += pts[i];
  if (nb == 0 || np == 0) throw InputError("merged cloud", "needs points of both scans (back and palm) to place a skeleton");
  if ((back / nb - palm / np).dot(Z) < 0) Z = -Z;
  double umin = 1e300, umax = -1e300;
  for (const auto& p : pts) umin = std::min(umin, (p - c).dot(X)), umax = std::max(umax, (p - c).dot(X));
  auto end_thickness = [&](bool low) {
    double lo = 1e300, hi = -1e300;
    for (const auto& p : pts) {
      const double u = (p - c).dot(X);
      if (low ? u < umin + 15 : u > umax - 15) lo = std::min(lo, (p - c).dot(Z)), hi = std::max(hi, (p - c).dot(Z));
    }
    return hi - lo;
  };
  if (end_thickness(false) > end_thickness(true)) X = -X;  // the wrist's cut end is the thicker (checked below)
  f.X = X, f.Z = Z, f.Y = Z.cross(X);
  return f;
}

// Scale from the middle fingertip and the wrist cut; joints by the proportions. The rig's
// hand frame (X from the wrist to the middle MCP) is only approximated by the principal
// axes, and the wrist, the scale and the MCPs depend on one another: three rounds of
// wrist → scale → digit joints → frame.
Chains place_chains(const std::vector<Eigen::Vector3d>& h, const std::vector<Digit>& digits) {
  const Digit& middle = digits[2];
  Chains out;
  Eigen::Vector3d& Xh = out.Xh;
  Eigen::Vector3d& W = out.W;
  double& s = out.s;
  std::array<std::vector<Eigen::Vector3d>, 5>& chains = out.joints;  // hand coordinates, MCP ... tip
  double& thumb_mcp_arc = out.thumb_mcp_arc;                      // the thumb's MCP along its centre line
  // The wrist end is the palm's: a thumb spread 70 deg reaches back past it once the frame
  // turns (its tip became the "cut", and the wrist went 101 mm off on a hand spread 15 deg).
  std::vector<char> in_digit(h.size(), 0);
  for (const auto& dg : digits)
    for (const size_t i : dg.points) in_digit[i] = 1;
  for (int round = 0; round < 3; ++round) {
    const Eigen::Vector3d Yh = Eigen::Vector3d::UnitZ().cross(Xh);
    double cut = 1e300;
    for (size_t i = 0; i < h.size(); ++i)
      if (!in_digit[i]) cut = std::min(cut, h[i].dot(Xh));
    // The hand's length along the middle finger's centre line (a curled finger is longer
    // than its shadow): to the middle MCP (where the last round put it), then along the curve.
    const double a_mcp_guess =
        std::max(0.0, middle.length() - (kTipInset + kFingers[2].distal + kFingers[2].middle + kFingers[2].proximal) * s);
    const double mcp_x = middle.at(a_mcp_guess).dot(Xh), to_tip = middle.length() - a_mcp_guess;
    // The wrist: where the palm starts to widen into the thenar and hypothenar eminences, a
    // knee in the silhouette's breadth along the hand, kKneeBeyondWrist beyond the joint.
    // The cut is where the replica was sawn off (a forearm stub of any length): only a
    // fallback when no knee shows.
    const std::optional<double> knee = breadth_knee(h, Xh, Yh, cut, mcp_x, s);
    double wrist_x;
    if (knee) {
      s = (mcp_x - *knee + to_tip) / (kNominalHandLength - kKneeBeyondWrist);
      wrist_x = *knee - kKneeBeyondWrist * s;
    } else {
      s = (mcp_x - cut + to_tip) / (kNominalHandLength + kWristCut);
      wrist_x = cut + kWristCut * s;
    }
    double vl = 1e300, vh = -1e300, wl = 1e300, wh = -1e300;
    for (size_t i = 0; i < h.size(); ++i) {
      const Eigen::Vector3d& q = h[i];
      if (!in_digit[i] && q.dot(Xh) < cut + 10)
        vl = std::min(vl, q.dot(Yh)), vh = std::max(vh, q.dot(Yh)), wl = std::min(wl, q.z()), wh = std::max(wh, q.z());
    }
    W = wrist_x * Xh + 0.5 * (vl + vh) * Yh + 0.5 * (wl + wh) * Eigen::Vector3d::UnitZ();
    // Its height from the thickness a disc's radius inside the cut: a disc at the cut itself
    // (a cast sawn off at the wrist, no stub) holds the rim only, often one scan's side, and
    // put the wrist 10 mm toward the palm (H03).
    const Eigen::Vector3d W_in = W + std::max(0.0, cut + 3 * s - wrist_x) * Xh;
    if (const auto z = depth_at(h, W_in, kWristDepth, 3 * s)) W.z() = *z;
    // digits sorted little, ring, middle, index, thumb → fingers 4, 3, 2, 1, 0; joints back
    // from the tip along the centre line by the proportions' lengths.
    for (int k = 0; k < 5; ++k) {
      const int fi = 4 - k;
      const Digit& dg = digits[k];
      const FingerSpec& f = kFingers[fi];
      const std::vector<double> lengths = fi == 0 ? std::vector<double>{f.distal, f.proximal}
                                                  : std::vector<double>{f.distal, f.middle, f.proximal};
      double a = dg.length() - kTipInset * s;
      std::vector<Eigen::Vector3d> js = {dg.at(a)};
      for (size_t li = 0; li < lengths.size(); ++li) {
        const double L = lengths[li];
        // Chord, not arc: the joints are the corners of the bent chain.
        const Eigen::Vector3d from = js.back();
        a = dg.chord_back(from, L * s, a);
        Eigen::Vector3d j = dg.at(a);
        if (fi != 0 && fi != 2 && li + 1 == lengths.size()) {
          // A finger's MCP is its metacarpal's head: a spread finger turns there, so the
          // phalanx's line, carried on into the palm, passes beside it. The joint is put
          // the proximal phalanx's length from the PIP toward where the proportions put
          // the metacarpal's head across the hand (its height from the centre line). Not the
          // middle finger's: its MCP sets the frame's X (and its phalanges point along it).
          // (The proportions' frame turned so that the middle finger's head lies on X, as the
          // rig's hand frame has it.)
          auto head_of = [](const FingerSpec& g) {
            const double h = g.angle_deg * M_PI / 180.0;
            return Eigen::Vector2d(g.cmc.x() + g.metacarpal * std::cos(h), g.cmc.y() + g.metacarpal * std::sin(h));
          };
          const Eigen::Vector2d mid = head_of(kFingers[2]);
          const Eigen::Vector2d hd = Eigen::Rotation2Dd(-std::atan2(mid.y(), mid.x())) * head_of(f);
          const Eigen::Vector3d head = W + s * hd.x() * Xh + s * hd.y() * Yh;
          Eigen::Vector3d target = j;
          target.head<2>() = head.head<2>();
          const Eigen::Vector3d aim = target - from;
          j = from + L * s * aim.normalized();
        }
        js.push_back(j);
      }
      // A finger's MCP lies in the palm: its height from the palm's thickness there.
      std::optional<double> mcp_z;
      if (fi != 0) mcp_z = depth_at(h, js.back(), kMetacarpalDepth, 3 * s);
      // The bones lie dorsal of a digit's section middle (the palmar pad is the thicker
      // side): the joints are lifted by kDigitBoneDorsalMm, square to the centre line.
      for (Eigen::Vector3d& j : js) {
        Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
        const Eigen::Vector3d tl = tangent_near(dg, j);
        up = (up - up.dot(tl) * tl).normalized();
        j += kDigitBoneDorsalMm * s * up;
      }
      if (mcp_z) js.back().z() = *mcp_z;
      std::reverse(js.begin(), js.end());
      chains[fi] = js;
      if (fi == 0) thumb_mcp_arc = a;
    }
    Xh = chains[2].front() - W;
    Xh.z() = 0;
    Xh.normalize();
  }
  return out;
}

void centre_thumb_joints(const std::vector<Eigen::Vector3d>& h, const Digit& thumb, double s,
                         std::vector<Eigen::Vector3d>* jsp) {
  // The thumb's MCP and IP on the middle of the cloud's sections through them. The centre
  // line's height is a quadratic fitted to the part beyond the palm's opening and carried on
  // straight; a raised thumb bent at its MCP (the WebXR hand model posed about parallel axes,
  // ~25 deg out of the palm's plane and flexed 10 deg) had its MCP there 5.4 mm below the
  // thumb's middle. On the family the skins' mean went 0.0748 -> 0.0746 mm with it.
  if (const double dg_thumb_width = thumb.width; dg_thumb_width > 0) {
    std::vector<Eigen::Vector3d>& js = *jsp;  // MCP, IP, tip
    bool mcp_centred = false;
    // Each joint moves as the middle of the section at `along` of the way from it to the
    // next joint out: the IP's own section is free of the palm; at the MCP the thenar runs
    // on below the thumb, but a third of the way out along its proximal phalanx it is clear.
    // A thumb bent across the palm (the WebXR hand's, 10/20/25 deg at its CMC, MCP and IP)
    // lies on the thenar a third of the way out too: the MCP's section is then taken half
    // and two thirds of the way out, the first that closes (it had stayed 6-8 mm beside
    // the thumb, and the skin refused the skeleton).
    for (const auto& [k, along] : {std::pair{1, 0.0}, std::pair{0, 0.35}, std::pair{0, 0.5}, std::pair{0, 0.65}}) {
      if (k == 0 && mcp_centred) break;  // centred by a section nearer the MCP
      const Eigen::Vector3d a = (js[k + 1] - js[k]).normalized(), q = js[k] + along * (js[k + 1] - js[k]);
      Eigen::Vector3d e1 = Eigen::Vector3d::UnitZ() - a.z() * a;
      if (e1.norm() < 0.3) continue;  // a thumb pointing up or down out of the hand: no height to centre
      e1.normalize();
      const Eigen::Vector3d e2 = a.cross(e1), up = kDigitBoneDorsalMm * s * e1;
      if (const auto m = section_middle(h, q - up, a, e1, e2, dg_thumb_width)) {
        js[k] += *m + up - q;
        if (k == 0) mcp_centred = true;
      }
    }
  }
}

void assemble_rig(const HandFrame& frame, const std::vector<Eigen::Vector3d>& h, const Chains& ch, const Digit& thumb,
                  AutoRig* out) {
  const Eigen::Vector3d& Xh = ch.Xh;
  const Eigen::Vector3d& W = ch.W;
  const double s = ch.s;
  const std::array<std::vector<Eigen::Vector3d>, 5>& chains = ch.joints;
  const Eigen::Vector3d& Z = frame.Z;
  out->scale = s;
  Rig& rig = out->rig;
  rig.frame = "palm";
  rig.joints[0] = frame.to_cloud(W);
  // The metacarpal bases at their nominal places in that frame.
  const Eigen::Vector3d Yh = Eigen::Vector3d::UnitZ().cross(Xh);
  for (int fi = 0; fi < 5; ++fi) {
    const FingerSpec& f = kFingers[fi];
    const auto chain = finger_chain(static_cast<Finger>(fi));
    Eigen::Vector3d cmc = W + s * (f.cmc.x() * Xh + f.cmc.y() * Yh);
    cmc.z() = fi == 0 ? W.z() - 6.0 * s : chains[fi].front().z();
    if (const auto z = depth_at(h, cmc, fi == 0 ? kThumbBaseDepth : kMetacarpalDepth, 3 * s)) cmc.z() = *z;
    rig.joints[chain[0]] = frame.to_cloud(cmc);
    for (size_t k2 = 0; k2 < chains[fi].size(); ++k2) rig.joints[chain[k2 + 1]] = frame.to_cloud(chains[fi][k2]);
  }
  // The palm's normal from the placed joints, square to the wrist -> middle MCP line and to
  // the index -> little MCP line (toward the back, as Z): the frame the skin stage slices in.
  // Z itself, the cloud's thinnest axis (or the palm's mid-surface), can lie 20 deg off it
  // in roll on an arched hand (the WebXR hand flexed 8-14 deg at the MCPs: 21 deg), and in
  // that frame the little finger ran under the ring finger's edge: the ring-little web was
  // found beyond the little finger's PIP and the palm's last ring folded.
  {
    const auto at = [&](const char* n) { return rig.joints[joint_index(n).value()]; };
    const Eigen::Vector3d x = (at("middle-finger-phalanx-proximal") - at("wrist")).normalized();
    Eigen::Vector3d n = x.cross(at("index-finger-phalanx-proximal") - at("pinky-finger-phalanx-proximal"));
    n -= n.dot(x) * x;
    rig.palm_normal = n.norm() > 1e-9 ? Eigen::Vector3d((n.dot(Z) < 0 ? -n : n).normalized()) : Z;
  }
  {
    // The thumb's base on its own centre line: the metacarpal's length (chord) back from the
    // MCP along the curve, which runs on into the palm; straight on along its first chord
    // where it ends sooner.
    const Digit& dg = thumb;
    const Eigen::Vector3d& mcp = chains[0].front();
    const double L = kFingers[0].metacarpal * s;
    const Eigen::Vector3d base = (dg.curve.front() - mcp).norm() >= L
                                     ? dg.at(dg.chord_back(mcp, L, ch.thumb_mcp_arc))
                                     : Eigen::Vector3d(mcp - L * (mcp - dg.curve.front()).normalized());
    out->thumb_base_on_line = rig;
    out->thumb_base_on_line.joints[finger_chain(Finger::Thumb)[0]] = frame.to_cloud(base);
  }
  if (out->side == HandSide::Left) out->notes.push_back("a left hand (the thumb lies on the other side of the middle finger)");
  out->notes.push_back("joints along the measured digit centre lines with the proportions of Buryanov & Kotiuk (2010), scale " +
                      std::to_string(s).substr(0, 5) + " from the middle fingertip and the wrist cut");
}

}  // namespace auto_rig_steps

AutoRig place_skeleton(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::uint32_t>& sides,
                       DigitParting parting, CentreLines lines) {
  using namespace auto_rig_steps;
  if (pts.size() < 1000 || sides.size() != pts.size())
    throw InputError("merged cloud", "too few points (or no side labels) to place a skeleton in");
  AutoRig out;
  HandFrame frame = principal_frame(pts, sides);
  std::vector<Eigen::Vector3d> h(pts.size());  // hand coordinates
  DigitCells cells = find_digit_cells(pts, sides, parting, &frame, &h, &out);
  std::vector<Digit> digits = collect_digits(cells, h);
  orient_digits(&frame, &h, &cells.pc, &digits, &out);
  digit_directions(h, cells.pc, &digits);
  for (size_t k = 0; k < digits.size(); ++k) trace_centre_line(h, cells.pc, k < 4, lines == CentreLines::Traced && k < 4, &digits[k]);
  Chains chains = place_chains(h, digits);
  centre_thumb_joints(h, digits[4], chains.s, &chains.joints[0]);
  assemble_rig(frame, h, chains, digits[4], &out);
  return out;
}

JointError joint_error(const Rig& a, const Rig& b) {
  JointError e;
  for (int j = 0; j < kJointCount; ++j) {
    const double d = (a.joints[j] - b.joints[j]).norm();
    e.mean_mm += d / kJointCount;
    if (d > e.max_mm) e.max_mm = d, e.worst_joint = joints()[j].name;
  }
  return e;
}

}  // namespace handskin
