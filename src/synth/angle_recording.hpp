#pragma once
/// Synthetic joint-angle recordings with known structure, for testing posture calibration
/// (docs/posture.md, "Synthetic recordings"): frames drawn from a known Gaussian (three
/// postural synergies plus independent noise) or from a known curved relation (one grasp
/// closure t per frame, MCP linear in t, PIP and DIP quadratic, the thumb along an arc).
/// A person index adds that person's own offsets (as a glove calibrated differently); gaps
/// blank cells at random.
#include <Eigen/Core>
#include <string>

#include "core/json_util.hpp"
#include "posture/angle_table.hpp"

namespace handskin {

struct AngleRecordingOptions {
  std::string kind = "gaussian";  ///< "gaussian" or "curved"
  long rows = 5000;               ///< [10, 1e6]
  unsigned seed = 1;              ///< the hand (synergy loadings, means) and the frames
  int person = 0;                 ///< 0: no offsets; k ≥ 1: person k's offsets (sd `offset_sd`)
  double offset_sd = 4;           ///< degrees
  double gaps = 0;                ///< fraction of cells left empty, [0, 0.5]
  double noise = 1.5;             ///< curved: independent noise per joint, deg
  bool IsValid(std::string* error) const;
};

struct AngleRecording {
  AngleTable table;
  /// The truth: kind, DOFs, person offsets; for a Gaussian its mean and covariance (before
  /// the person's offsets), for the curved relation its formulas.
  Json truth;
  Eigen::VectorXd mean;       ///< gaussian: per column (offsets included)
  Eigen::MatrixXd covariance; ///< gaussian
};

AngleRecording synth_angle_recording(const AngleRecordingOptions& options);

}  // namespace handskin
