#include "cli/huge_pages.hpp"

#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
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

// A 4 kB page's first touch below this (µs) and the pages stay as they are (rerun_with_huge_pages).
constexpr double kCheapFaultUs = 6.0;

// What the probe found when it kept the 4 kB pages, for --verbose's last line.
std::string kept_small;

// The median time (µs) of a 4 kB page's first touch, over 64 fresh pages (~0.2–2 ms in all);
// -1 when it cannot map them. The median, so that a page the scheduler interrupted does not count.
double small_fault_us() {
  constexpr int kPages = 64;
  const size_t len = size_t{kPages} * 4096;
  void* map = mmap(nullptr, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (map == MAP_FAILED) return -1;
  madvise(map, len, MADV_NOHUGEPAGE);
  volatile char* page = static_cast<char*>(map);
  double us[kPages];
  for (int k = 0; k < kPages; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    page[size_t{4096} * k] = 1;
    us[k] = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  }
  munmap(map, len);
  std::nth_element(us, us + kPages / 2, us + kPages);
  return us[kPages / 2];
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
  // Whether they pay depends on the machine. Huge pages spare the kernel a fault per 4 kB page
  // first touched (a run touches ~140 MB: ~35 000 faults), so they pay where a fault is dear:
  // on 2026-11-28's virtual machine a 4 kB page's first touch cost 20-25 µs and the fixture's
  // run went 2.04 -> 1.88 s on huge pages. Where it is cheap they cost more than they spare: on
  // 2026-12-02's a 4 kB page's cost ~2 µs while its 65 huge pages of fresh memory cost ~4 ms
  // each (0.25 s more in the kernel: the run 1.46 -> 1.62 s). A huge page's own cost cannot be
  // told from one probe (the first of a process cost 7 ms there, the next ones 0.1-0.3 ms), a
  // small page's can: 64 of them are timed (~0.2-2 ms), and below kCheapFaultUs the pages stay.
  // HANDSKIN_HUGE_PAGES=1 skips the probe.
  const char* force = std::getenv("HANDSKIN_HUGE_PAGES");
  if (!(force && std::strcmp(force, "1") == 0)) {
    const double us = small_fault_us();
    if (us >= 0 && us < kCheapFaultUs) {
      char buf[120];
      std::snprintf(buf, sizeof buf, " (allocator on 4 kB pages: a page's first touch takes %.1f µs here)", us);
      kept_small = buf;
      return;
    }
  }
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

std::string pages_note() {
  const char* t = std::getenv("GLIBC_TUNABLES");
  if (t && std::string(t).find("glibc.malloc.hugetlb=1") != std::string::npos) return " (allocator on transparent huge pages)";
  return kept_small;
}

}  // namespace handskin::cli
