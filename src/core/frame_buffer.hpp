#pragma once
// Storage for recorded frames. Recording writes tens of kilobytes per step; this allocator
// skips the zero-fill of resize(), since the renderer writes every byte, and maps large
// buffers with their pages populated up front: one kernel call instead of a page fault every
// few kilobytes in the middle of the loop. (Transparent huge pages were tried: with this
// kernel's synchronous compaction they made steps slower.)
#include <sys/mman.h>

#include <cstdint>
#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace cd {

template <class T>
struct FrameAllocator {
  using value_type = T;
  FrameAllocator() = default;
  template <class U>
  FrameAllocator(const FrameAllocator<U>&) noexcept {}

  static constexpr size_t kMapped = size_t(1) << 20;

  T* allocate(size_t n) {
    if (n * sizeof(T) < kMapped) return std::allocator<T>().allocate(n);
    void* p = mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (n * sizeof(T) < kMapped) std::allocator<T>().deallocate(p, n);
    else munmap(p, n * sizeof(T));
  }
  // Default-initialise: resize() leaves new bytes as they are instead of zeroing them.
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U>
  bool operator==(const FrameAllocator<U>&) const noexcept { return true; }
};

using FrameBytes = std::vector<uint8_t, FrameAllocator<uint8_t>>;

}  // namespace cd
