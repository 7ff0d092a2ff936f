#pragma once
// Independent jobs on the OpenMP threads (`--threads N`, core/threads.hpp). Its own header: it
// holds an OpenMP loop, and only the libraries compiled with OpenMP include it (the program's
// main, which includes threads.hpp, is not).
#include <exception>
#include <vector>

namespace handskin {

/// job(k) for every k in [0, n) on the OpenMP threads, each job writing into slots of its own.
/// An exception must not leave an OpenMP loop: each job's is kept, and the first by index is
/// rethrown once every job has ended.
template <typename Job>
void parallel_jobs(long n, const Job& job) {
  std::vector<std::exception_ptr> failed(static_cast<size_t>(n > 0 ? n : 0));
#pragma omp parallel for schedule(dynamic)
  for (long k = 0; k < n; ++k) {
    try {
      job(k);
    } catch (...) {
      failed[static_cast<size_t>(k)] = std::current_exception();
    }
  }
  for (const auto& e : failed)
    if (e) std::rethrow_exception(e);
}

}  // namespace handskin
