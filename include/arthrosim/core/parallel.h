#pragma once
// Deterministic parallel loops. Work is cut into fixed blocks that depend only on the range,
// never on the thread count, and every block writes only its own outputs; reductions are
// combined in block order. So results are bit-identical for any number of threads.
#include <cstdint>
#include <functional>

namespace arthrosim {

/// Sets the number of worker threads used by ParallelFor (1 = run inline). Not thread-safe;
/// call before a run.
void SetThreadCount(int threads);
/// Current thread count (>= 1).
int ThreadCount();

/// Calls body(begin, end) for fixed blocks of `block` items covering [0, n). Blocks may run
/// concurrently; body must not write anything another block reads or writes.
void ParallelFor(std::int64_t n, std::int64_t block,
                 const std::function<void(std::int64_t, std::int64_t)>& body);

}  // namespace arthrosim
