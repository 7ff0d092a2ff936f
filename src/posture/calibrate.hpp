#pragma once
/// Calibration of a posture model from measured joint angles (docs/posture.md), by one of
/// three methods:
/// - "gaussian" (the default): the recordings' mean and shrunk covariance, written as springs
///   plus synergy constraint rows, so that a solve with pins is the conditional mean;
/// - "mixture": a mixture of such Gaussians (the non-linear mode), kept only where it beats the
///   single Gaussian on held-out frames;
/// - "thesis-pairs": thesis §3.2.2–3.2.3 — the relaxed posture, joint pairs (given, or chosen
///   by correlation), a least-squares line per pair (a row of A and b), weights W by eq. 3.18,
///   optional non-linear grids.
/// Every method widens the limits to cover what the data shows, and reports cross-validated
/// figures on the standard tasks against the training mean and a linear regression.
#include <string>
#include <utility>
#include <vector>

#include "core/json_util.hpp"
#include "posture/angle_table.hpp"
#include "posture/model.hpp"

namespace handskin {

struct CalibrationOptions {
  std::string method = "gaussian";        ///< "gaussian", "mixture" or "thesis-pairs"
  /// Gaussian and mixture: "remove" each recording's own mean before the covariance (glove
  /// offsets differ between people), "keep" them, or "auto": choose by leaving recordings out.
  std::string offsets = "auto";
  double shrinkage = -1;                  ///< toward the diagonal, [0, 1]; < 0: chosen by cross-validation
  int components = 0;                     ///< mixture: 0 = chosen by cross-validation (2–8), else 2–16
  int folds = 5;                          ///< held-out blocks per recording
  bool evaluate = true;                   ///< cross-validated figures in the report
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

/// One table per recording (a person or a session); `files` name them in errors and notes.
/// `report` (if given) receives the figures: frames and joints that carried the fit, widened
/// limits, the method's own figures (pairs; shrinkage and synergies; components) and the
/// cross-validation (`cross_validation.blocks`, and `.recordings` with two or more tables).
PostureModel calibrate(const std::vector<AngleTable>& tables, const std::vector<std::string>& files,
                       const CalibrationOptions& options, Json* report);
/// One recording.
PostureModel calibrate(const AngleTable& table, const CalibrationOptions& options, const std::string& file,
                       Json* report);

}  // namespace handskin
