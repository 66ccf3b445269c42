#include "arthrosim/render/sequence.h"

#include <gtest/gtest.h>

#include <limits>

#include "test_scene.h"

namespace arthrosim::render {
namespace {

using testing::SharedRenderer;
// Keeps every frame in memory.
class MemorySink : public FrameSink {
 public:
  void Write(const Image& frame) override { frames_.push_back(frame); }
  void Close() override { closed_ = true; }
  std::int64_t frames() const override { return static_cast<std::int64_t>(frames_.size()); }
  std::vector<Image> frames_;
  bool closed_ = false;
};

// States 0, 0.1, ..., 1.0 s whose lens roll encodes the index (so every frame shows which).
std::vector<State> States(const Model& model, const State& base) {
  (void)model;
  std::vector<State> out;
  for (int i = 0; i <= 10; ++i) {
    State s = base;
    s.time_s = 0.1 * i;
    s.camera.lens_roll_rad = 0.3 * i;
    out.push_back(s);
  }
  return out;
}

// Render options for w x h frames, the rest default.
RenderOptions Sized(int w, int h) {
  RenderOptions opt;
  opt.width = w;
  opt.height = h;
  return opt;
}

TEST(SequenceRendererTest, SampleAndHoldAtTheFrameRate) {
  Model model;
  const State base = testing::MakeTestScene(&model);
  const std::vector<State> states = States(model, base);
  RenderOptions opt = Sized(48, 32);
  opt.fps = 25;
  opt.frames_dir = "unused";  // allows any size; the sink is ours
  MemorySink sink;
  SequenceRenderer seq(model, opt, &SharedRenderer(), &sink);
  for (const State& s : states) seq.Push(s);
  seq.Finish();
  EXPECT_TRUE(sink.closed_);
  ASSERT_EQ(sink.frames(), 26);  // t = 0, 0.04, ..., 1.0
  // frame k at t = k / 25 shows the last state at or before t
  ViewSpec spec;
  spec.width = 48;
  spec.height = 32;
  for (int k = 0; k < 26; ++k) {
    const double t = k / 25.0;
    int expect = 0;
    for (int i = 0; i <= 10; ++i) {
      if (states[i].time_s <= t + 1e-9) expect = i;  // SequenceRenderer's time tolerance
    }
    Image ref;
    SharedRenderer().Render(BuildScene(model, states[expect]), spec, &ref);
    EXPECT_EQ(ref.rgb, sink.frames_[k].rgb) << "frame " << k << " expected state " << expect;
  }
}

TEST(SequenceRendererTest, TimeWindowAndOverlayHook) {
  Model model;
  const State base = testing::MakeTestScene(&model);
  RenderOptions opt = Sized(32, 32);
  opt.fps = 10;
  opt.from_s = 0.5;
  opt.to_s = 0.8;
  opt.frames_dir = "unused";
  MemorySink sink;
  int calls = 0;
  SequenceRenderer seq(model, opt, &SharedRenderer(), &sink, [&](const State&, Overlay* o) {
    ++calls;
    o->verdict = "ok";
  });
  for (const State& s : States(model, base)) seq.Push(s);
  seq.Finish();
  EXPECT_EQ(sink.frames(), 4);  // 0.5, 0.6, 0.7, 0.8
  EXPECT_EQ(calls, 4);          // one scene per shown state
}

TEST(SequenceRendererTest, RejectsNonIncreasingTimesAndBadOptions) {
  Model model;
  const State base = testing::MakeTestScene(&model);
  RenderOptions opt = Sized(32, 32);
  MemorySink sink;
  SequenceRenderer seq(model, opt, &SharedRenderer(), &sink);
  seq.Push(base);
  EXPECT_THROW(seq.Push(base), std::invalid_argument);
  opt.fps = 0;
  EXPECT_THROW(ValidateRenderOptions(opt), std::invalid_argument);
  opt.fps = 25;
  opt.width = 33;  // odd: not encodable as yuv420p
  EXPECT_THROW(ValidateRenderOptions(opt), std::invalid_argument);
  opt.frames_dir = "frames";
  EXPECT_NO_THROW(ValidateRenderOptions(opt));
  opt.to_s = -1;
  EXPECT_THROW(ValidateRenderOptions(opt), std::invalid_argument);
}

// The video names the step that started last, "in progress" until it ends, "done" after; nothing
// before the first step, and a step that never started is never named.
TEST(SequenceRendererTest, StepOverlayTextNamesTheCurrentStep) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<StepSpan> steps = {
      {"Look", 1.0, 3.0}, {"Cut", 4.0, 6.0}, {"Never", nan, nan}, {"Burr", 5.0, nan}};
  const auto at = [&](double t) {
    Overlay o;
    StepOverlayText(steps, t, &o);
    return o.plan_step + " | " + o.verdict;
  };
  EXPECT_EQ(at(0.5), " | ");
  EXPECT_EQ(at(1.0), "step 1/4: Look | in progress");
  EXPECT_EQ(at(3.0), "step 1/4: Look | done");
  EXPECT_EQ(at(4.5), "step 2/4: Cut | in progress");
  // Burr starts while Cut is still running: the later start is the current step.
  EXPECT_EQ(at(5.5), "step 4/4: Burr | in progress");
  EXPECT_EQ(at(100), "step 4/4: Burr | in progress");
}

}  // namespace
}  // namespace arthrosim::render
