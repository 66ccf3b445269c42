#pragma once
// Deterministic parallel loops. Work is cut into fixed blocks that depend only on the range,
// never on the thread count, and every block writes only its own outputs; reductions are
// combined in block order. So results are bit-identical for any number of threads.
#include <cstdint>
#include <type_traits>
#include <utility>

namespace arthrosim {

/// Sets the number of threads used by ParallelFor (1 = run inline): starts or stops the
/// persistent pool's threads - 1 workers, which wait for loops between calls. Not thread-safe;
/// call before a run, not while a loop runs.
void SetThreadCount(int threads);
/// Current thread count (>= 1).
int ThreadCount();

/// A non-owning reference to a callable body(begin, end): binding a lambda never allocates
/// (std::function would for captures beyond its small buffer). Valid while the callable lives,
/// which for a ParallelFor argument is the whole call.
class BlockBody {
 public:
  template <typename F, typename = std::enable_if_t<!std::is_same_v<std::decay_t<F>, BlockBody>>>
  BlockBody(F&& f)  // NOLINT(google-explicit-constructor): implicit from any callable
      : object_(const_cast<void*>(static_cast<const void*>(&f))),
        call_([](void* o, std::int64_t b, std::int64_t e) {
          (*static_cast<std::remove_reference_t<F>*>(o))(b, e);
        }) {}
  void operator()(std::int64_t begin, std::int64_t end) const { call_(object_, begin, end); }

 private:
  void* object_;
  void (*call_)(void*, std::int64_t, std::int64_t);
};

/// Calls body(begin, end) for fixed blocks of `block` items covering [0, n). Blocks may run
/// concurrently; body must not write anything another block reads or writes. Allocates nothing;
/// with one thread, or inside another loop's body, it runs inline. The first exception a block
/// throws is rethrown here after every started block has finished. Note: a `thread_local` named
/// inside body is the running thread's own.
void ParallelFor(std::int64_t n, std::int64_t block, BlockBody body);

}  // namespace arthrosim
