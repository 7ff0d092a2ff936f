#pragma once
/// Every stage's parameters, as held by `pipelines/*.json` (format "handskin-pipeline/1").
/// Plain data with no stage's headers (the fuzzer builds it alone); the stages' own option
/// structs are made from it in pipeline/stage_options.hpp.
/// The defaults here are the thesis's and equal `pipelines/cubist.json` (a test keeps them so).
#include <optional>
#include <string>

#include "core/json_util.hpp"

namespace handskin {

struct PipelineOptions {
  struct Ingest {
    long min_returns = 1000;       ///< a scan with fewer measured samples is refused
  } ingest;
  struct Markers {                 ///< registration (thesis §4.1.1)
    long count = 9;                ///< spherical markers on the replica
    /// Their radius; unset: estimated from the scans (the thesis gives none; docs/registration.md).
    std::optional<double> radius_mm;
  } markers;
  struct Registration {            ///< back scan into the palm frame (docs/registration.md)
    double table_margin_mm = 1.0;  ///< samples this close above the table plane are table
    double match_tolerance_mm = 0.5;   ///< marker distances must agree this well between scans
    double marker_clearance_mm = 0.5;  ///< samples within radius + this of a marker are not skin
    bool refine = true;            ///< refine the marker fit (markers as anchors + gated ICP)
    double icp_gate_mm = 0.5;      ///< ICP pairs farther apart are not the same surface
    double icp_normal_deg = 20.0;  ///< ... nor pairs whose normals differ more
    double icp_trim = 0.9;         ///< fraction of gated pairs kept
    long icp_max_iterations = 15;  ///< correspondence rounds
    /// Warn when the fit's own error estimate (1σ) exceeds these (issue 11's bounds).
    double warn_rotation_deg = 0.02;
    double warn_displacement_mm = 0.05;
  } registration;
  struct Slicing {                 ///< skin strips (thesis §4.1.2–4.1.3)
    long planes = 50;              ///< cross-section planes along the hand
    long points_per_segment = 10;  ///< resampled points per plane and bone segment (eq. 4.1)
  } slicing;
  struct Skin {                    ///< skin mesh from the strips (docs/skin.md)
    double thumb_overlap_mm = 3.0; ///< thumb and palm share points this near their boundary
    long smoothing_rings = 2;      ///< wrinkle filter: quadratic over ± this many rings
    double wrinkle_mm = 0.15;      ///< ... replaces radii straying from it by more than this
    long cap_rings = 4;            ///< rings of each fingertip's dome
    long max_triangles = 8000;     ///< decimate to at most this many triangles (0: no decimation)
    double decimation_tolerance_mm = 0.15; ///< ... moving the surface by at most this
    bool fit_to_data = true;       ///< the decimated skin fitted to the cloud (docs/skin.md, step 11)
    double fit_max_move_mm = 2.0;  ///< ... no vertex moving farther, no point farther counted
    bool fair_unseen = true;       ///< unseen creases made fair (docs/skin.md, step 12)
    bool slices_json = true;       ///< write slices.json (the thesis's sections, for inspection)
    bool baseline = false;         ///< also run CGAL Poisson on the cloud and report it beside (--baseline)
  } skin;
  struct Patches {                 ///< Bézier skin (thesis §4.1.4, Table 4.1)
    bool enabled = true;           ///< run fits the patches (false: skin only, as before issue 13)
    long count = 96;               ///< bicubic patches wanted (the thesis: palm 48 + back 48); the closed layout has 98 k²
    long error_grid = 100;         ///< error measured against a grid of n x n surface cells
    double c1_weight = 10;         ///< C1 across the borders, relative to the data's weight (0: G0 only)
    double fairness = 1e-3;        ///< second differences inside each patch, relative to the data's weight
    double skin_weight = 0.5;      ///< the polygon skin's samples as data where the scans saw nothing, relative to a measured point
    double tolerance_mm = 0;       ///< split the patches whose measured points lie farther than this (0: none; --patch-tolerance)
    long max_patches = 300;        ///< ... up to this many patches in all
  } patches;
  struct Rigging {                 ///< the skin bound to the skeleton, skin.glb (docs/rigging.md)
    bool smooth = true;            ///< bone-heat weights (false: rigid, each vertex with its nearest link, as the thesis)
  } rigging;
  struct Texture {                 ///< the skin's colour from the scans' photos (docs/rigging.md "Texture")
    bool enabled = true;           ///< bake it when both scans have a photo (<stem>.photo.png)
    long size = 1024;              ///< the atlas is size x size texels
    double blend_deg = 15;         ///< the photos blend across the flanks over ± this angle
    double weight = 0.7;           ///< pictures: colour = (1 - weight) shading + weight texture (thesis 0.3 : 0.7)
  } texture;

  struct Gates {                   ///< quality gates on the written outputs (docs/architecture.md "Quality gates")
    double cloud_to_skin_p95_mm = 0.35;     ///< the merged cloud's points to skin.ply
    double cloud_to_skin_max_mm = 3.0;
    double patches_to_skin_p95_mm = 0.75;   ///< the patch surface to skin.ply
    double patches_to_skin_max_mm = 3.0;
    double g0_gap_mm = 1e-6;                ///< largest gap between neighbouring patches
    double g1_kink_deg = 30;                ///< largest angle between neighbouring patches' normals, away from irregular corners
  } gates;

  /// False with a message naming the key when a value is out of range.
  bool IsValid(std::string* error) const;
};

/// Parse a pipeline file. Unknown sections or keys are errors (a typo must not pass silently);
/// missing keys keep their defaults. Every key, its type and its range are in one table
/// (options.cpp), which parsing, writing and IsValid share.
/// The closed layout's 98 faces are split k × k: the k whose 98 k² is nearest `count` (in
/// [1, 8]). IsValid refuses a count whose 98 k² is more than 5 % off.
int patch_subdivision(long count);

PipelineOptions parse_pipeline(const Json& j, const std::string& file);
PipelineOptions load_pipeline(const std::string& file);
Json pipeline_to_json(const PipelineOptions& o);

}  // namespace handskin
