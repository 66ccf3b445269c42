#include "arthrosim/render/sequence.h"

#include <gtest/gtest.h>

#include "test_scene.h"

namespace arthrosim::render {
namespace {

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

Renderer& SharedRenderer() {
  testing::PinLlvmpipeThreads();
  static Renderer renderer;
  return renderer;
}

TEST(SequenceRendererTest, SampleAndHoldAtTheFrameRate) {
  Model model;
  const State base = testing::MakeTestScene(&model);
  const std::vector<State> states = States(model, base);
  RenderOptions opt;
  opt.width = 48;
  opt.height = 32;
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
  RenderOptions opt;
  opt.width = 32;
  opt.height = 32;
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
  RenderOptions opt;
  opt.width = 32;
  opt.height = 32;
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

}  // namespace
}  // namespace arthrosim::render
