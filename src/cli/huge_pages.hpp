#pragma once
#include <string>

/// The allocator's pages (docs/performance.md, "page faults on huge pages"): the pipeline commands ask glibc
/// to back the memory they allocate with transparent huge pages.
namespace handskin::cli {

/// When the kernel gives transparent huge pages to the memory that asks for them
/// (/sys/kernel/mm/transparent_hugepage/enabled is "[madvise]") and glibc's tunable
/// glibc.malloc.hugetlb is not set yet, runs this program again from its start with it set
/// (GLIBC_TUNABLES, read by glibc only when a process starts): glibc then marks its heaps
/// MADV_HUGEPAGE, and the memory a run first touches faults in 2 MB at a time instead of
/// 4 kB. Only for `command` in run, register, skin and patches (the others allocate too little
/// to gain the second start, ~0.04 s, or, `synth`, would not repeat their bytes), and not when
/// HANDSKIN_HUGE_PAGES is "0" or a library is preloaded (LD_PRELOAD: valgrind, heaptrack…).
/// Nor where a 4 kB page's first touch is cheap (its median over 64 fresh pages under 6 µs:
/// there the huge pages' own cost outweighs the faults they spare; docs/performance.md,
/// 2026-12-02); HANDSKIN_HUGE_PAGES=1 skips that probe. Returns when it did not run the program
/// again (or could not: the run goes on as it is).
void rerun_with_huge_pages(const char* command, char** argv);

/// For `command` in run, register, skin and patches: glibc's allocator keeps the memory a
/// block freed for the blocks allocated after it. Every block comes from the heap, however
/// large (M_MMAP_THRESHOLD 256 MB: by default a block over 128 kB, and later over the largest
/// freed so far up to 32 MB, is mapped on its own and unmapped when freed, so that each new
/// one faults its pages in again), and the heap grows and shrinks 16 MB at a time (M_TOP_PAD).
/// A run's page faults fall from ~26 000 to ~6 000 (docs/performance.md, 2026-12-01, fourth
/// session); its peak memory stays as it was.
void reuse_freed_memory(const char* command);

/// For `--verbose`'s last line: " (allocator on transparent huge pages)" when this process's
/// allocator was asked for them (GLIBC_TUNABLES holds glibc.malloc.hugetlb=1), the probe's
/// figure when it kept the 4 kB pages, else nothing.
std::string pages_note();

}  // namespace handskin::cli
