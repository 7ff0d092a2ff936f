#pragma once
/// Calibration of a posture model from measured joint angles (thesis §3.2.2–3.2.3): the
/// relaxed posture, joint pairs (given, or chosen by correlation), a least-squares line per
/// pair (a row of A and b), weights W by eq. 3.18, optional non-linear grids, and limits that
/// cover what the data shows.
#include <string>
#include <utility>
#include <vector>

#include "core/json_util.hpp"
#include "posture/angle_table.hpp"
#include "posture/model.hpp"

namespace handskin {

struct CalibrationOptions {
  std::vector<std::pair<int, int>> pairs;  ///< empty: choose by correlation
  double min_correlation = 0.5;            ///< |r| a pair needs to be chosen automatically
  int max_pairs = 8;
  /// "thesis": eq. 3.18, w_k = (Σ l_i² / n) / max (the spread about the line, normalised);
  /// "inverse": w_k ∝ 1 / spread (a tight correlation holds harder), normalised to max 1.
  std::string weights = "thesis";
  bool grids = false;                      ///< also build non-linear grid potentials per pair
  int grid_cells = 100;
  double grid_weight = 0.5;
  int max_grid_samples = 400;              ///< samples kept per grid (thinned on a 1° lattice)
  double limit_margin_deg = 2.0;           ///< widened limits reach this far past the data
  long min_rows = 10;                      ///< fewer usable rows: an error
  bool IsValid(std::string* error) const;
};

/// `file` names the table in errors and notes. `report` (if given) receives the figures:
/// rows, per-DOF coverage, pairs with r, slope, intercept, spread and weight, widened limits.
PostureModel calibrate(const AngleTable& table, const CalibrationOptions& options, const std::string& file,
                       Json* report);

}  // namespace handskin
