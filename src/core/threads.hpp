#pragma once
// How many threads the parallel steps use (`--threads N`). Every parallel step writes each
// result into its own slot and sums in a fixed order, so the outputs are the same bytes with
// any number of threads (test threads_same_bytes). Header-only over OpenMP's runtime: only the
// libraries that link OpenMP (patches, pipeline and what links them) include it.
#include <omp.h>

#include <future>

#include "core/errors.hpp"

namespace handskin {

/// The OpenMP loops (and Eigen's products, which follow OpenMP) use at most n threads; n >= 1.
inline void set_thread_count(int n) {
  HS_CHECK(n >= 1, "at least one thread");
  omp_set_num_threads(n);
}
/// The threads the parallel steps may use (1 with `--threads 1`).
inline int thread_count() { return omp_get_max_threads(); }
/// How side work (a picture or a distance tree made beside a stage) is started: on a thread of
/// its own, or, with one thread, when its result is asked for.
inline std::launch side_launch() { return thread_count() > 1 ? std::launch::async : std::launch::deferred; }

}  // namespace handskin
