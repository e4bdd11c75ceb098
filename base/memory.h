// How the programs' memory allocator hands memory back to the kernel.
#pragma once

namespace revolve::base {

// Keeps the memory the process frees for its next use instead of handing it back to the kernel
// at once: glibc's trim threshold is raised to 512 MiB and its mmap threshold set to its maximum
// (32 MiB), so blocks up to 32 MiB come from the heap and freed space stays mapped. A scan's
// finish allocates and frees the same tens of MiB every time (surface, colours, file buffers),
// and memory handed back is paid for again as page faults when next written (about 1 us per
// 4 KiB page on a virtual machine). The cost: the resident size stays near its peak. Returns
// whether the allocator took the settings (false without glibc, where it does nothing). Call
// it once, first thing in main(); the station's programs do (GuardedMain).
bool RetainFreedMemory();

}  // namespace revolve::base
