#pragma once
/// The patch layout (issue 13, docs/patches.md): a closed quad cage over the whole hand, one
/// bicubic Bézier patch per face. Neighbouring faces share an edge, so their patches share
/// that border's control points (G0 by construction); faces meet edge to edge everywhere (no
/// T-junctions). The hand's layout is built from the skin and its rig:
///
///   palm    10 columns around (4 back, the ulnar flank, 4 palm, the radial flank) × 3 rows
///           from the wrist cut to the finger webs, less the face the thumb grows from: 29
///   wrist   the cut's 10-sided rim closed by a strip of 4 faces
///   fingers 4 columns (back, ulnar, palm, radial) × 3 rows (web–PIP, PIP–DIP, DIP–tip ring)
///           and a cap over the fingertip: 13 each; neighbouring fingers share the edge that
///           runs through their web
///   thumb   the same 13 on the palm's radial flank (its middle row)
///
/// 98 faces in all: the nearest a closed hand of four-sided faces comes to the thesis's 96
/// (docs/patches.md says why). Where three (wrist corners, fingertip caps), five (the thumb's
/// base) or six (the webs) faces meet, the corner is extraordinary: G1 is not enforced there.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/rig.hpp"
#include "skin/skin_mesh.hpp"

namespace handskin {

struct PatchLayout {
  std::vector<Eigen::Vector3d> vertices;    ///< the faces' corners (palm frame, mm), on the skin
  std::vector<std::array<int, 4>> faces;    ///< corners in order, counter-clockwise seen from outside
  std::vector<std::string> names;           ///< per face, e.g. "index.2.back", "palm.1.radial", "wrist.0"
  /// Edges (corner pairs) where the surface may fold sharply, e.g. the wrist cut's rim: no G1
  /// is asked across them.
  std::vector<std::array<int, 2>> creases;
  /// Per face: how many times it was halved along u and along v (the refinement to a
  /// tolerance); empty when no face was. A halving halves the parameter's speed, so the fit's C1
  /// conditions across a border weigh each side's cross derivative by 2^level (net_fit.cpp).
  std::vector<std::array<int, 2>> levels;
  bool is_crease(int a, int b) const;
  /// Face f's halvings along u (dir 0) or v (dir 1).
  int level(int f, int dir) const { return levels.empty() ? 0 : levels[f][dir]; }
};

/// Edge-to-edge structure of a layout. Side s of a face runs from its corner s to corner s + 1.
///
/// A layout refined locally (patches/refine.cpp, issue 38) has T-junctions, at most two faces
/// against one: a *long* side runs beside two faces, each of whose *short* side is one half of
/// it, and the vertex between the halves *hangs* on the long side (it is no corner of the long
/// side's face). The surface holds it there exactly: a short side's border curve is the long
/// side's curve split at its midpoint (de Casteljau), so the two short sides' control points are
/// fixed combinations of the long side's (build_net).
struct LayoutTopology {
  /// Per face side: the face across it and which of its sides that is; on a long side -1 (its
  /// two faces are in `halves`); on a short side the long side's face and side.
  std::vector<std::array<int, 4>> neighbour;
  std::vector<std::array<int, 4>> neighbour_side;
  /// Per face side: -1 shared whole (or long); on a short side which half of the long side it
  /// is (0: the half from the long side's start).
  std::vector<std::array<int, 4>> half;
  /// Per long side (face, side): the faces and sides across its first and second halves.
  std::map<std::pair<int, int>, std::array<std::pair<int, int>, 2>> halves;
  /// Per vertex: the long side (face, side) it hangs on, or (-1, -1). A hanging vertex counts as
  /// regular (valence 4): the faces either side of it split one smooth curve.
  std::vector<std::pair<int, int>> hangs_on;
  std::map<std::pair<int, int>, int> hanging;  ///< per long side (face, side): the vertex hanging on it
  std::vector<int> valence;                        ///< per vertex: the faces meeting there
  std::vector<std::vector<int>> around;            ///< per vertex: its edges' other ends, in turn round it (none for a hanging one)
  size_t edges = 0;
  bool regular(int vertex) const { return valence[vertex] == 4; }
  bool conforming() const { return halves.empty(); }
  /// The point `q` along side s of face f (0 at its corner s) seen from across: the face, its
  /// side and how far along that side (each face runs a shared side its own way).
  void across(int f, int s, double q, int* g, int* gs, double* gq) const;
  /// The faces (and their sides) across side s of face f: one, or a long side's two.
  std::vector<std::pair<int, int>> sides_across(int f, int s) const;
  /// Every face across one of f's sides (a long side's two).
  std::vector<int> faces_across(int f) const;
};

/// The topology of a closed, consistently oriented quad layout. Throws InputError (naming
/// `what`) when an edge has other than two faces (but a long side's two halves), two faces run
/// an edge the same way, a face repeats a corner, or a vertex is in no face.
LayoutTopology layout_topology(const PatchLayout& layout, const std::string& what);

/// The hand's layout on `skin` (built on `rig`; `points`/`sides` tell the back from the palm).
/// `thumb_ring_shift` moves the palm ring the thumb's base ends at (two thirds of the way from
/// the wrist to the webs) by that many of the skin's rings toward the webs (negative: toward
/// the wrist), within the palm's middle rings. `thumb_turn_deg` turns the thumb's base (the
/// palm's radial column between those rings) round the palm's section toward the palm (negative:
/// toward the back), for a thumb that grows from the palm's side. Throws InputError when a digit
/// is missing from the skin or a corner cannot be placed.
PatchLayout hand_patch_layout(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                              const std::vector<std::uint32_t>& sides, int thumb_ring_shift = 0,
                              double thumb_turn_deg = 0);

/// Every face split into k × k (bilinear in its corners): k² times the patches, same corners.
PatchLayout subdivide_layout(const PatchLayout& layout, int k);

/// Six times the volume the layout's faces enclose (each quad as two triangles): positive when
/// they run counter-clockwise seen from outside.
double layout_volume(const PatchLayout& layout);
/// Faces turned so that every edge is run both ways and the enclosed volume is positive.
/// Throws InputError (naming `what`) when the faces cannot be oriented (not a closed surface).
void orient_layout(PatchLayout* layout, const std::string& what);

}  // namespace handskin
