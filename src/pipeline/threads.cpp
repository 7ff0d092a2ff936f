#include "pipeline/threads.hpp"

#include <omp.h>

#include "core/errors.hpp"

namespace handskin {

void set_thread_count(int n) {
  HS_CHECK(n >= 1, "at least one thread");
  omp_set_num_threads(n);
}

int thread_count() { return omp_get_max_threads(); }

}  // namespace handskin
