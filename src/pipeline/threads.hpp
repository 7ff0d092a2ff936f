#pragma once
// How many threads the parallel steps use (`--threads N`). Every parallel step writes each
// result into its own slot and sums in a fixed order, so the outputs are the same bytes with
// any number of threads (tests: threads_same_bytes).
#include <future>

namespace handskin {

/// The OpenMP loops (and Eigen's products, which follow OpenMP) use at most n threads; n >= 1.
void set_thread_count(int n);
/// The threads the parallel steps may use (1 with `--threads 1`).
int thread_count();
/// How side work (the pictures drawn beside the stages) is started: on a thread of its own, or,
/// with one thread, when its result is asked for.
inline std::launch side_launch() { return thread_count() > 1 ? std::launch::async : std::launch::deferred; }

}  // namespace handskin
