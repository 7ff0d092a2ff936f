#pragma once
/// The hand studio's JSON API (docs/studio.md), as plain functions from a request to a
/// response, so that the HTTP server (server.cpp) only routes and the API is tested without a
/// socket:
/// - `GET /api/dofs`: every DOF with its joint, limits, relaxed value and unit, the parameter
///   set skin.glb carries, and the parameter sets a request may name;
/// - `POST /api/solve` with `{"inputs": {"L2.flex": 60}, "torques": {...}, "targets":
///   {"I3.flex": 40 | {"deg": 40, "weight": 2}}, "parameter_set": "thesis"}`: every DOF's
///   angle (with the parameter set named — default the skin's own), the potential, and the
///   joint nodes' local transforms (what the page sets on skin.glb's joints);
/// - `POST /api/animate`: keyframe or constrained animation (below);
/// - `GET /api/system`: what a page needs to solve the linear model and pose the joints
///   itself (docs/studio.md, "Solving in the page"): per parameter set, whether it is linear,
///   the potential ½xᵀHx − gᵀx + c (H, g, c), the relaxed posture and the limits; per joint,
///   its flexion and abduction DOFs, the abduction's sign and its node's rest transform.
/// Bad requests get a 4xx status and `{"error": "<one line>"}`: a body over kMaxBodyBytes
/// (413), JSON that does not parse or nests deeper than kMaxDepth, a key of the wrong type, an
/// unknown DOF, a value that is not a finite number (400), a pinned value beyond the DOF's
/// limits (422).
#include <memory>
#include <mutex>
#include <utility>
#include <vector>
#include <string>

#include "core/json_util.hpp"
#include "posture/skeleton.hpp"
#include "posture/solver.hpp"
#include "rigging/animation.hpp"
#include "rigging/gltf.hpp"
#include "studio/http_module.hpp"

namespace handskin {

constexpr size_t kMaxBodyBytes = 64 * 1024;
constexpr int kMaxDepth = 8;

/// A reply: status, body (JSON, unless content_type says otherwise), content type — the HTTP
/// transport's own reply (studio/http_module.hpp), so the server passes it on as it is.
using ApiResponse = HttpReply;

constexpr int kMaxAnimationKeys = 500;
constexpr int kMaxAnimationFrames = 3600;

/// The studio's model: skin.glb as read, its solver and skeleton. The solver's caches are not
/// thread-safe, so solves take the lock.
class StudioModel {
 public:
  explicit StudioModel(RiggedSkin skin);
  const RiggedSkin& skin() const { return skin_; }
  ApiResponse dofs() const;
  ApiResponse solve(const std::string& body) const;
  ApiResponse system() const;
  /// `POST /api/animate` with `{"keys": [{"time": 0, "angles": {"L2.flex": 0, …}}, …],
  /// "fps": 30, "inputs_only": false, "format": "frames" | "glb" | "csv"}`: the animation of
  /// rigging/animation.hpp — as frames (times, every DOF, and the joint nodes' transforms per
  /// frame, for the page to play), as skin.glb with the animation, or as the frames' CSV. At
  /// most kMaxAnimationKeys keys and kMaxAnimationFrames frames.
  ApiResponse animate(const std::string& body) const;

 private:
  /// The parameter set a request names ("parameter_set"; default the skin's own), or a 400.
  const PostureSolver& solver_for(const Json& body) const;
  RiggedSkin skin_;
  /// The parameter sets: "model" (the one skin.glb carries), then the shipped "anatomical"
  /// and "thesis" (posture/model.hpp).
  std::vector<std::pair<std::string, std::unique_ptr<PostureSolver>>> solvers_;
  Skeleton skeleton_;
  mutable std::mutex mutex_;
};

}  // namespace handskin
