#pragma once
// Where CPU tensors live. A training step on the CPU allocates its large tensors (a batch of
// camera frames, a layer's activations: tens of MB) afresh each step, and glibc hands each one
// out as a new anonymous mapping. With the kernel's transparent huge pages on `madvise` (as on
// the project's machines), every 4 KiB page of it then costs a page fault on first touch:
// ~116,000 faults a second in a camera training, ~40 % of its time in the kernel. The allocator
// here gives torch's CPU tensors of 2 MiB or more memory aligned to 2 MiB and advised for huge
// pages (MADV_HUGEPAGE), which the kernel fills 2 MiB at a time; smaller ones go to torch's own
// allocator. What a tensor holds, and so every result, is the same either way.
namespace cd {

// Installs the allocator as torch's CPU allocator, once per process (later calls do nothing).
// The environment variable CAUSALDRIVE_HUGE_PAGES=0 leaves torch's allocator in place. The CLI
// calls it at start. Returns whether the allocator is installed.
bool use_huge_pages_for_cpu_tensors();

// While the allocator is installed: whether new large tensors are advised for huge pages
// (true after installing). `bench train --huge-pages both` switches it to compare the two in one
// run; a tensor's memory is freed the way it was allocated whatever the switch says then.
void set_huge_pages(bool on);
bool huge_pages_on();

// The size from which a tensor's memory is advised for huge pages: 2 MiB.
constexpr unsigned long kHugePageBytes = 2ul << 20;

}  // namespace cd
