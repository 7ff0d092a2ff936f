#pragma once
/// How well a posture model predicts held-out frames (docs/posture.md, "Evaluation"): the
/// standard tasks (one joint → the rest, PIPs → DIPs, MCPs → the rest), held-out blocks of
/// each recording or whole recordings left out, against the training mean posture and a
/// linear regression fitted on the same training frames.
#include <functional>
#include <string>
#include <vector>

#include "posture/gaussian.hpp"

namespace handskin {

/// Columns of a PostureSamples: the given joints are pinned, the predicted ones are scored.
struct PostureTask {
  std::string name;
  std::vector<int> given, predicted;
};
/// The standard tasks the measured DOFs allow; a task whose joints were not measured is left
/// out and named in `skipped` with the reason.
std::vector<PostureTask> standard_tasks(const std::vector<int>& dofs, std::vector<std::string>* skipped);

struct Split {
  std::vector<long> train, test;
};
/// `folds` contiguous blocks of every recording; fold k holds out block k of each.
std::vector<Split> block_splits(const PostureSamples& s, int folds);
/// One split per recording: that recording held out (needs two or more).
std::vector<Split> recording_splits(const PostureSamples& s);

/// Squared errors summed over held-out frames and predicted joints, per task.
struct TaskErrors {
  std::vector<double> sse;
  std::vector<long> cells;
  double rms(size_t task) const;
};
/// A model fitted on a split's training rows; `split` is the split's index (a fit may cache
/// what does not change between calls on the same split).
using ModelFit = std::function<PostureModel(const PostureSamples& train, size_t split)>;
/// The model fitted on each split's training rows, solving each held-out frame with the
/// task's joints pinned (PostureSolver::solve: the mixture where the model has one).
TaskErrors model_errors(const PostureSamples& s, const std::vector<PostureTask>& tasks, const std::vector<Split>& splits,
                        const ModelFit& fit);
/// The two baselines on the same splits: the training mean of each predicted joint, and an
/// ordinary least-squares regression (with intercept) of it on the given joints.
void baseline_errors(const PostureSamples& s, const std::vector<PostureTask>& tasks, const std::vector<Split>& splits,
                     TaskErrors* mean, TaskErrors* linreg);

}  // namespace handskin
