#include "cli/huge_pages.hpp"

#include <malloc.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

namespace handskin::cli {

namespace {

// Not `synth`: CGAL's mesher there (synth hand) follows the order of its objects' addresses,
// and on huge pages glibc places them differently from run to run: hand.ply changed from run
// to run (with 4 kB pages the layout, and the mesh, repeat).
bool heavy(const char* command) {
  if (!command) return false;
  static const char* kHeavy[] = {"run", "register", "skin", "patches"};
  for (const char* c : kHeavy)
    if (std::strcmp(command, c) == 0) return true;
  return false;
}

}  // namespace

void rerun_with_huge_pages(const char* command, char** argv) {
  if (!heavy(command)) return;
  if (const char* off = std::getenv("HANDSKIN_HUGE_PAGES"); off && std::strcmp(off, "0") == 0) return;
  // A preloaded library (valgrind's, heaptrack's, another allocator) is a tool watching this
  // process or replacing its allocator: not started again under it.
  if (const char* pre = std::getenv("LD_PRELOAD"); pre && *pre) return;
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  const std::string had = tunables ? tunables : "";
  if (had.find("glibc.malloc.hugetlb") != std::string::npos) return;  // set already (by us or the user)
  // Only where the kernel gives huge pages to memory marked for them: with "always" every
  // process has them already, with "never" the mark does nothing.
  std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
  const std::string mode((std::istreambuf_iterator<char>(thp)), std::istreambuf_iterator<char>());
  if (mode.find("[madvise]") == std::string::npos) return;
  const std::string set = had.empty() ? "glibc.malloc.hugetlb=1" : had + ":glibc.malloc.hugetlb=1";
  if (setenv("GLIBC_TUNABLES", set.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);
  // Not run again (no /proc, say): the run goes on with the pages it has, and the
  // environment as it was.
  if (tunables) setenv("GLIBC_TUNABLES", had.c_str(), 1);
  else unsetenv("GLIBC_TUNABLES");
}

void reuse_freed_memory(const char* command) {
  if (!heavy(command)) return;
  // Blocks of any size from the heap (glibc's default maps each block over 128 kB–32 MB on its
  // own, and unmaps it when freed), and the heap grown and trimmed 16 MB at a time.
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TOP_PAD, 16 << 20);
}

bool huge_pages_asked() {
  const char* t = std::getenv("GLIBC_TUNABLES");
  return t && std::string(t).find("glibc.malloc.hugetlb=1") != std::string::npos;
}

}  // namespace handskin::cli
