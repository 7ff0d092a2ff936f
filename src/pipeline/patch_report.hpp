#pragma once
/// The fitting-error report of the Bézier patches (thesis Table 4.1), for people: a
/// self-contained `report.html` (pictures embedded, nothing fetched when viewed) and
/// the figures it shows.
#include <optional>
#include <string>

#include "core/json_util.hpp"
#include "core/rig.hpp"
#include "pipeline/patch_stage.hpp"

namespace handskin {


/// The HTML page: Table 4.1's columns per side (foot-point and cell-grid error, the noise
/// floor beside them), counts, the parameter correction, G0/G1, the run's stage times and
/// registration when given (`run_report`), the truth distances when measured, and pictures:
/// the data coloured by its distance to the surface from the palm and from the back (with a
/// colour bar in mm), the patch layout, and an error histogram.
/// `posed` (if any) adds a section of the rigged skin in a few postures.
/// The pictures are the stage's (r.pictures): the page only encodes them.
std::string patch_report_html(const PatchStageResult& r, const Json& run_report = Json(),
                              const std::vector<ReportPicture>& posed = {});

}  // namespace handskin
