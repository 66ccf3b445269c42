#pragma once
// Shared by the files of the soft-tissue solver (not installed): soft_system.cpp (build, layout,
// topology changes), soft_step.cpp (step stages, the built-in implicit Euler step and the stages
// an external integrator drives), soft_preconditioner.cpp, soft_queries.cpp (static solve,
// energies, queries).
#include <Eigen/Core>
#include <cstdint>
#include <ctime>
#include <initializer_list>
#include <string>

namespace arthrosim::physics::soft_internal {
// Stage timers read the CPU time of the process (all threads): on a shared machine it is far
// steadier than wall time, and for one thread it is the busy time of the step.
struct Clock {
  using time_point = double;  // ms
  static double now() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
  }
};
inline double MsSince(double t0) { return Clock::now() - t0; }

inline auto Seg(Eigen::VectorXd& v, std::int32_t slot) {
  return v.segment<3>(3 * static_cast<Eigen::Index>(slot));
}
inline auto Seg(const Eigen::VectorXd& v, std::int32_t slot) {
  return v.segment<3>(3 * static_cast<Eigen::Index>(slot));
}

// Joins pieces by append (operator+ chains trip a GCC 12 -Wrestrict false positive).
inline std::string Cat(std::initializer_list<std::string> parts) {
  std::string out;
  for (const std::string& p : parts) out.append(p);
  return out;
}

constexpr std::int64_t kTetBlock = 128;  // fixed ParallelFor block (independent of threads)

}  // namespace arthrosim::physics::soft_internal
