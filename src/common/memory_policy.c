/* The C allocator's policy for a long run (memory_policy.f90). glibc serves every block
 * above its mmap threshold (at most 32 MB) with a fresh mmap() and gives it back on free;
 * each new block then costs a page fault per 4 KiB page, zeroed by the kernel. A run that
 * saves and rebuilds arrays of that size at every cross-rank window (the flight records of
 * 50,000 bodies are 40 MB) spent a third of its time so on two ranks. Here every block
 * comes from the heap, and freed memory stays with the process for the next one. C because
 * mallopt is glibc's; elsewhere this does nothing. Returns 1 if the policy was set. */
#if defined(__GLIBC__) || defined(__linux__)
#include <malloc.h>
#endif
#include <limits.h>

int ricochet_keep_freed_memory(void) {
#if defined(__GLIBC__) && defined(M_MMAP_MAX) && defined(M_TRIM_THRESHOLD)
  if (mallopt(M_MMAP_MAX, 0) != 1) return 0;
  if (mallopt(M_TRIM_THRESHOLD, INT_MAX) != 1) return 0;
  return 1;
#else
  return 0;
#endif
}
