#include "device/cpu_memory.hpp"

#include <sys/mman.h>

#include <atomic>
#include <cstdlib>
#include <cstring>

#include <c10/core/Allocator.h>
#include <c10/core/CPUAllocator.h>

namespace cd {

namespace {

std::atomic<bool> advise{true};

void free_huge(void* p) { std::free(p); }

class HugePageCpuAllocator final : public c10::Allocator {
 public:
  explicit HugePageCpuAllocator(c10::Allocator* fallback) : fallback_(fallback) {}

  c10::DataPtr allocate(size_t n) const override {
    if (n < kHugePageBytes || !advise.load(std::memory_order_relaxed))
      return fallback_->allocate(n);
    void* p = nullptr;
    // glibc serves this from a mapping of its own (well above its mmap threshold), which free()
    // unmaps whole; the pointer is 2 MiB-aligned inside it, so the kernel can back each whole
    // 2 MiB of [p, p + n) with one huge page.
    if (posix_memalign(&p, kHugePageBytes, n) != 0 || p == nullptr)
      return fallback_->allocate(n);  // torch's allocator then says what went wrong
    madvise(p, n, MADV_HUGEPAGE);  // advice only: refused (no THP in this kernel) is harmless
    return {p, p, &free_huge, c10::Device(c10::DeviceType::CPU)};
  }

  // raw_allocate's memory, either way, is posix_memalign's (torch's allocator's too): free().
  c10::DeleterFnPtr raw_deleter() const override { return &free_huge; }

 private:
  c10::Allocator* fallback_;
};

}  // namespace

bool use_huge_pages_for_cpu_tensors() {
  static bool installed = [] {
    const char* env = std::getenv("CAUSALDRIVE_HUGE_PAGES");
    if (env != nullptr && std::strcmp(env, "0") == 0) return false;
    static HugePageCpuAllocator allocator(c10::GetDefaultCPUAllocator());
    c10::SetCPUAllocator(&allocator, /*priority=*/100);
    return c10::GetCPUAllocator() == &allocator;
  }();
  return installed;
}

void set_huge_pages(bool on) { advise.store(on, std::memory_order_relaxed); }

bool huge_pages_on() { return advise.load(std::memory_order_relaxed); }

}  // namespace cd
