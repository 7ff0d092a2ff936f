#pragma once
/// The solver's results at the edges: a whole table of partial postures solved row by row
/// (`solve --inputs`), and one solution as `handskin-posture-solution/1` JSON (`solve --json`).
#include <Eigen/Core>
#include <array>
#include <optional>

#include "core/json_util.hpp"
#include "posture/angle_table.hpp"
#include "posture/solver.hpp"

namespace handskin {

struct BatchSolution {
  AngleTable angles;        ///< every DOF per row, rows in input order
  long clamped_rows = 0;    ///< rows with an input outside the limits (clamped onto them)
  long clamped_cells = 0;
};
/// Solve every row of `inputs` with its given cells pinned (empty cells are free).
BatchSolution solve_batch(const PostureSolver& solver, const AngleTable& inputs, bool linear);

/// handskin-posture-solution/1: the angles of every DOF, which were pinned, which sit at a
/// limit, the solver's figures, and (with `joints`) the joint positions.
Json posture_solution_to_json(const PostureModel& model, const PostureInputs& inputs, const PostureSolution& s,
                              const std::array<Eigen::Vector3d, kJointCount>* joints = nullptr);

}  // namespace handskin
