#pragma once
// Knot tying with the knot pusher (Choi et al. 2020 section III.6) and the knot security pull
// test: the queries a test or a scorer needs to find a knot in State and to judge it.
//
// A knot is a set of spring constraints tagged "knot" between two threads (end a on thread A,
// end b on thread B); the lowest id is the seat spring, which joins the knot nodes (the nodes
// where the loop from the tissue enters the knot). The knot pusher holds the threads with
// springs tagged "knot_pusher" (end a on the tool). Threads run from the tissue side (node 0:
// anchor or fixed end) to their free end; the tissue side of a limb is its outermost node held by
// a "stitch" constraint, or node 0 without a stitch.
#include <cstdint>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/state.h"

namespace arthrosim::instruments {

/// Spring tag of the knot springs and of the knot pusher's tool-thread springs.
inline constexpr const char* kKnotTag = "knot";
inline constexpr const char* kKnotPusherTag = "knot_pusher";

/// A knot found in State: its threads, knot (seat) nodes and spring ids (ascending).
struct KnotRef {
  std::int64_t id = -1;  ///< the seat spring's id (identifies the knot), -1 = none
  std::int32_t thread_a = -1, thread_b = -1;
  std::int32_t node_a = -1, node_b = -1;  ///< knot nodes on each thread
  std::vector<std::int64_t> springs;      ///< every "knot" spring between these two threads
};

/// Every knot in the state, ordered by seat spring id.
std::vector<KnotRef> FindKnots(const State& state);

/// The tissue-side node of thread `thread`: the largest node index held by a "stitch"
/// constraint, or 0 if none.
int TissueSideNode(const State& state, int thread);

/// What one pull test simulated (tests, diagnostics).
struct KnotPullWork {
  int threads = 0;            ///< thread pieces copied (1 if the knot ties a thread to itself)
  int nodes = 0;              ///< thread nodes copied and stepped
  int steps = 0;              ///< thread steps (StepThreads calls)
  int newton_iterations = 0;  ///< summed over the steps (ThreadStepStats::newton_iterations)
};

/// Default reach of the pull test's copy along each knot thread beyond the knot's nodes, mm of
/// rest arc length (see KnotSlipMm).
inline constexpr double kKnotPullWindowMm = 5.0;

/// Knot security pull test (docs/operations.md "Knot tying"). What is simulated: a copy of the
/// knot's thread(s) only (thread_a and thread_b, one piece if they are the same thread), each cut
/// to the nodes the knot touches (its knot springs' ends, the knot nodes and the nodes just below
/// them) widened by `window_mm` of rest arc length on each side (clamped to the thread; a huge
/// window copies the whole threads), holding only the knot's springs (tissue, anchors,
/// stitches, tools and other threads left out; the model's fixed nodes inside the piece stay
/// fixed). The loop node just below the knot on each limb is pulled with
/// operations.knot_pusher.pull_force_n (N), the two in opposite directions along the line
/// between them, for pull_time_s (s) of thread steps of the model's dt. Returns the slip (mm):
/// how much the distance between the two knot nodes has grown, averaged over the last two
/// steps (the staggered spring coupling alternates). `state` is not changed; `work`, if given,
/// receives what was simulated. Throws std::invalid_argument if `knot` does not name threads and
/// nodes of the state, a knot spring does not join the knot's threads, or window_mm < 0.
double KnotSlipMm(const Model& model, const State& state, const KnotRef& knot,
                  KnotPullWork* work = nullptr, double window_mm = kKnotPullWindowMm);

}  // namespace arthrosim::instruments
