#pragma once
// Counts the heap allocations of a test binary by replacing the global operator new / delete.
// Include it in exactly one source file of an executable (the replacements are definitions).
// Under AddressSanitizer the replacement is off: a shared library (FCL) would allocate through
// the sanitizer's operator new while this binary's delete frees (an alloc-dealloc mismatch), so
// kCountingNew is false there and the tests skip; they run in the Release build.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <new>

namespace arthrosim::test_support {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kCountingNew = false;
#else
inline constexpr bool kCountingNew = true;
#endif

inline std::atomic<long> g_allocation_count{0};

/// Heap allocations made through operator new so far (stays 0 when kCountingNew is false).
inline long AllocationCount() { return g_allocation_count.load(std::memory_order_relaxed); }

/// Counted allocation of n bytes aligned to align; throws std::bad_alloc when out of memory.
inline void* CountedAllocate(std::size_t n, std::size_t align) {
  g_allocation_count.fetch_add(1, std::memory_order_relaxed);
  const std::size_t size = (std::max<std::size_t>(n, 1) + align - 1) / align * align;
  void* p = align > alignof(std::max_align_t) ? std::aligned_alloc(align, size) : std::malloc(size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

}  // namespace arthrosim::test_support

#if !defined(__SANITIZE_ADDRESS__)
void* operator new(std::size_t n) {
  return arthrosim::test_support::CountedAllocate(n, alignof(std::max_align_t));
}
void* operator new[](std::size_t n) {
  return arthrosim::test_support::CountedAllocate(n, alignof(std::max_align_t));
}
void* operator new(std::size_t n, std::align_val_t a) {
  return arthrosim::test_support::CountedAllocate(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return arthrosim::test_support::CountedAllocate(n, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
#endif
