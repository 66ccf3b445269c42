// Recorded sessions: resampling exactness, slerp, button latching, bad data, HDF5, record/replay.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>

#include "arthrosim/core/error.h"
#include "arthrosim/core/units.h"
#include "arthrosim/input/open_source.h"
#include "arthrosim/input/pose_math.h"
#include "arthrosim/input/recorded_source.h"
#include "arthrosim/input/recorder.h"
#include "arthrosim/input/session.h"
#include "test_model.h"

namespace arthrosim::input {
namespace {

using testing::MakeTestModel;
using testing::TempPath;

const std::string kHeader = "t,device,instrument,x,y,z,qw,qx,qy,qz,jaw,buttons\n";

// Message of the InputError thrown by parsing `text`, or "" if none.
std::string ErrorOf(const std::string& text, const SessionOptions& opt = {}) {
  try {
    ParseSessionCsv(text, "s.csv", opt);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Resampling, PositionAndJawAreLinearBetweenSamples) {
  const Model m = MakeTestModel();
  const SessionTable t = ParseSessionCsv(kHeader +
                                             "0.0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                                             "0.1,slot0,grasper,10,-20,5,1,0,0,0,1,0\n",
                                         "s.csv");
  RecordedSource src(t, m, 0.02);
  for (int k = 0; k <= 5; ++k) {
    const double ts = k * 0.02;
    InputFrame f;
    src.Frame(k, ts, &f);
    const double u = ts / 0.1;
    EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("grasper"));
    EXPECT_NEAR(f.tools[0].pose.position_mm.x(), 10 * u, 1e-12);
    EXPECT_NEAR(f.tools[0].pose.position_mm.y(), -20 * u, 1e-12);
    EXPECT_NEAR(f.tools[0].pose.position_mm.z(), 5 * u, 1e-12);
    EXPECT_NEAR(f.tools[0].jaw, u, 1e-12);
    EXPECT_EQ(f.tools[1].instrument, -1);  // never reported: withdrawn
  }
  EXPECT_FALSE(src.Finished(0.1));
  EXPECT_TRUE(src.Finished(0.12));
}

TEST(Resampling, SlerpFollowsTheShortArcAtConstantRate) {
  const Model m = MakeTestModel();
  // 0 to 90 degrees about z; the second sample is written as -q (same rotation).
  const double h = std::sqrt(0.5);
  const SessionTable t =
      ParseSessionCsv(kHeader + "0,slot1,shaver,0,0,0,1,0,0,0,0,0\n" + "0.1,slot1,shaver,0,0,0," +
                          std::to_string(-h) + ",0,0," + std::to_string(-h) + ",0,0\n",
                      "s.csv");
  RecordedSource src(t, m, 0.025);
  for (int k = 0; k <= 4; ++k) {
    InputFrame f;
    src.Frame(k, k * 0.025, &f);
    const Quat q = f.tools[1].pose.orientation;
    const Vec3 x = q * Vec3::UnitX();
    const double angle = std::atan2(x.y(), x.x());
    EXPECT_NEAR(angle, k * 0.25 * units::kPi / 2, 1e-6)
        << k;  // 22.5 deg per step, not 270 the long way
    EXPECT_NEAR(q.norm(), 1.0, 1e-14);
  }
}

TEST(Resampling, OneMillisecondPressIsLatchedIntoItsStep) {
  const Model m = MakeTestModel();
  std::string text = kHeader;
  for (int i = 0; i <= 100; ++i) {  // 1 kHz log, button down only at t = 0.031 s
    text += std::to_string(i * 0.001) + ",slot0,electrocautery,0,0,0,1,0,0,0,0," +
            (i == 31 ? "1" : "0") + "\n";
  }
  RecordedSource src(ParseSessionCsv(text, "s.csv"), m, 0.02);
  std::vector<int> pressed;
  for (int k = 0; k <= 5; ++k) {
    InputFrame f;
    src.Frame(k, k * 0.02, &f);
    pressed.push_back(f.tools[0].buttons);
  }
  // 0.031 lies in (0.02, 0.04]: step 2 only.
  EXPECT_EQ(pressed, (std::vector<int>{0, 0, 1, 0, 0, 0}));
}

TEST(Resampling, JitteredHapticLogInterpolatesBetweenNeighbours) {
  const Model m = MakeTestModel();
  std::string text = kHeader;
  double t = 0;
  for (int i = 0; i < 300; ++i) {  // ~1 kHz with +-0.3 ms jitter, x = 100 t
    text += fmt::format("{:.17g},slot0,burr,{:.17g},0,0,1,0,0,0,0,0\n", t, 100 * t);
    t += 0.001 + 0.0003 * std::sin(i * 1.7);
  }
  RecordedSource src(ParseSessionCsv(text, "s.csv"), m, 0.01);
  for (int k = 0; k < 25; ++k) {
    InputFrame f;
    src.Frame(k, k * 0.01, &f);
    EXPECT_NEAR(f.tools[0].pose.position_mm.x(), 100 * k * 0.01, 1e-9) << k;
  }
}

TEST(Resampling, InstrumentExchangeHappensAtTheSampleTime) {
  const Model m = MakeTestModel();
  const SessionTable t = ParseSessionCsv(kHeader +
                                             "0.0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                                             "0.1,slot0,grasper,10,0,0,1,0,0,0,0,0\n"
                                             "0.2,slot0,none,20,0,0,1,0,0,0,0,0\n"
                                             "0.3,slot0,shaver,30,0,0,1,0,0,0,0,0\n",
                                         "s.csv");
  RecordedSource src(t, m, 0.05);
  InputFrame f;
  src.Frame(3, 0.15, &f);
  EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("grasper"));
  EXPECT_EQ(f.tools[0].pose.position_mm.x(), 10.0);  // held, not blended toward the withdrawal
  src.Frame(4, 0.2, &f);
  EXPECT_EQ(f.tools[0].instrument, -1);
  src.Frame(6, 0.3, &f);
  EXPECT_EQ(f.tools[0].instrument, m.FindInstrument("shaver"));
  EXPECT_EQ(f.tools[0].pose.position_mm.x(), 30.0);
}

TEST(Resampling, ScopeCarriesLensAndHeadRoll) {
  const Model m = MakeTestModel();
  const SessionTable t = ParseSessionCsv(
      "t,device,instrument,x,y,z,qw,qx,qy,qz,jaw,buttons,lens_roll,head_roll\n"
      "0.0,scope,,1,2,3,1,0,0,0,,,0,0\n"
      "0.2,scope,,1,2,3,1,0,0,0,,,1.0,-0.5\n",
      "s.csv");
  RecordedSource src(t, m, 0.05);
  InputFrame f;
  src.Frame(1, 0.05, &f);
  EXPECT_NEAR(f.camera.lens_roll_rad, 0.25, 1e-15);
  EXPECT_NEAR(f.camera.head_roll_rad, -0.125, 1e-15);
  EXPECT_EQ(f.camera.pose.position_mm, Vec3(1, 2, 3));
  // Before the first sample the scope stays at the scenario's initial pose.
  src.Frame(-1, -0.05, &f);
  EXPECT_TRUE(f.camera.pose == m.camera.initial_pose);
}

TEST(BadData, NonFiniteValuesNameLineAndColumn) {
  const std::string e = ErrorOf(kHeader + "0,slot0,grasper,0,0,0,1,0,0,0,0,0\n" +
                                "0.01,slot0,grasper,nan,0,0,1,0,0,0,0,0\n");
  EXPECT_NE(e.find("s.csv:3: field 'x': column 4: non-finite value 'nan'"), std::string::npos) << e;
  const std::string e2 = ErrorOf(kHeader + "0,slot0,grasper,0,0,inf,1,0,0,0,0,0\n");
  EXPECT_NE(e2.find("s.csv:2: field 'z': column 6: non-finite"), std::string::npos) << e2;
  const std::string e3 = ErrorOf(kHeader + "0,slot0,grasper,0,0,1e,1,0,0,0,0,0\n");
  EXPECT_NE(e3.find("'1e' is not a number"), std::string::npos) << e3;
}

TEST(BadData, OneInstrumentInBothSlotsNamesTheLineThatTookItTwice) {
  const std::string e = ErrorOf(kHeader +
                                "0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                                "0,slot1,shaver,0,0,0,1,0,0,0,0,0\n"
                                "0.1,slot1,grasper,0,0,0,1,0,0,0,0,0\n");
  EXPECT_NE(e.find("s.csv:4: field 'instrument': 'grasper' is in slot0 and slot1 at the same "
                   "time (0.1 s; the other slot took it at line 2)"),
            std::string::npos)
      << e;
  // Handing the instruments over between the slots within one instant is not a conflict, in
  // either row order.
  EXPECT_EQ(ErrorOf(kHeader + "0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                              "0,slot1,shaver,0,0,0,1,0,0,0,0,0\n"
                              "0.1,slot1,grasper,0,0,0,1,0,0,0,0,0\n"
                              "0.1,slot0,shaver,0,0,0,1,0,0,0,0,0\n"),
            "");
  // Nor is an instrument returned to the rack (empty) in one slot and picked in the other.
  EXPECT_EQ(ErrorOf(kHeader + "0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                              "0.1,slot0,,0,0,0,1,0,0,0,0,0\n"
                              "0.2,slot1,grasper,0,0,0,1,0,0,0,0,0\n"),
            "");
}

TEST(BadData, TimestampGoingBackIsAnError) {
  const std::string e = ErrorOf(kHeader +
                                "0.2,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                                "0.1,slot1,grasper,0,0,0,1,0,0,0,0,0\n"  // other device: fine
                                "0.1,slot0,grasper,0,0,0,1,0,0,0,0,0\n");
  EXPECT_NE(e.find("s.csv:4: field 't'"), std::string::npos) << e;
  EXPECT_NE(e.find("goes back in time (line 2 had 0.2)"), std::string::npos) << e;
}

TEST(BadData, UnknownDeviceAndInstrument) {
  const std::string e = ErrorOf(kHeader + "0,hand3,grasper,0,0,0,1,0,0,0,0,0\n");
  EXPECT_NE(e.find("s.csv:2: field 'device': column 2: unknown device 'hand3'"), std::string::npos)
      << e;
  const Model m = MakeTestModel();
  const SessionTable t = ParseSessionCsv(kHeader + "0,slot0,graspr,0,0,0,1,0,0,0,0,0\n", "s.csv");
  try {
    RecordedSource src(t, m, 0.02);
    FAIL() << "no error";
  } catch (const InputError& err) {
    EXPECT_NE(
        std::string(err.what()).find("s.csv:2: field 'instrument': unknown instrument 'graspr'"),
        std::string::npos)
        << err.what();
  }
}

TEST(BadData, NearUnitQuaternionIsNormalisedWithWarningFarOneIsAnError) {
  const SessionTable t =
      ParseSessionCsv(kHeader + "0,slot0,grasper,0,0,0,1.0005,0,0,0,0,0\n", "s.csv");
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("s.csv:2: 1 orientation(s) of device slot0 normalised"),
            std::string::npos);
  EXPECT_DOUBLE_EQ(t.rows[0].orientation.w(), 1.0);
  const std::string e = ErrorOf(kHeader + "0,slot0,grasper,0,0,0,1.1,0,0,0,0,0\n");
  EXPECT_NE(e.find("s.csv:2: field 'qw': orientation quaternion has norm 1.1"), std::string::npos)
      << e;
}

TEST(BadData, GapLongerThanTheLimit) {
  const std::string text = kHeader +
                           "0.0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                           "0.5,slot0,grasper,10,0,0,1,0,0,0,0,0\n";
  const std::string e = ErrorOf(text);
  EXPECT_NE(e.find("s.csv:3: field 't': gap of 0.5 s in device slot0 since line 2 exceeds the "
                   "limit of 0.25 s"),
            std::string::npos)
      << e;
  SessionOptions hold;
  hold.gap_policy = GapPolicy::kHold;
  const SessionTable t = ParseSessionCsv(text, "s.csv", hold);
  ASSERT_EQ(t.warnings.size(), 1u);
  RecordedSource src(t, MakeTestModel(), 0.1, hold);
  InputFrame f;
  src.Frame(4, 0.4, &f);
  EXPECT_EQ(f.tools[0].pose.position_mm.x(), 0.0);  // held across the gap
  src.Frame(5, 0.5, &f);
  EXPECT_EQ(f.tools[0].pose.position_mm.x(), 10.0);
}

TEST(BadData, TruncatedLastLineIsDroppedTruncatedMiddleLineIsAnError) {
  const SessionTable t = ParseSessionCsv(kHeader +
                                             "0.0,slot0,grasper,0,0,0,1,0,0,0,0,0\n"
                                             "0.01,slot0,grasper,1,0,0,1,0,0",  // no newline
                                         "s.csv");
  EXPECT_EQ(t.rows.size(), 1u);
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("s.csv:3: truncated last line (9 of 12 columns) dropped"),
            std::string::npos);
  const std::string e = ErrorOf(kHeader +
                                "0.0,slot0,grasper,0,0,0,1,0,0\n"
                                "0.01,slot0,grasper,1,0,0,1,0,0,0,0,0\n");
  EXPECT_NE(e.find("s.csv:2: column 10: expected 12 columns as in the header, found 9"),
            std::string::npos)
      << e;
}

TEST(BadData, HeaderEmptyFileAndRanges) {
  EXPECT_NE(ErrorOf("").find("empty file"), std::string::npos);
  EXPECT_NE(ErrorOf(kHeader).find("no samples"), std::string::npos);
  EXPECT_NE(ErrorOf("t,device,instrument,x,y,z,qw,qx,qy,qz,jaw,buttons,speed\n")
                .find("column 13: unknown column 'speed'"),
            std::string::npos);
  EXPECT_NE(ErrorOf("t,device,x,y,z,qw,qx,qy,qz,jaw,buttons\n")
                .find("lacks required column 'instrument'"),
            std::string::npos);
  EXPECT_NE(ErrorOf(kHeader + "0,slot0,grasper,0,0,0,1,0,0,0,1.5,0\n")
                .find("field 'jaw': column 11: jaw 1.5 outside [0, 1]"),
            std::string::npos);
  EXPECT_NE(ErrorOf(kHeader + "0,slot0,grasper,0,0,0,1,0,0,0,0,4\n").find("field 'buttons'"),
            std::string::npos);
  EXPECT_NE(ErrorOf(kHeader + "0,scope,grasper,0,0,0,1,0,0,0,0,0\n")
                .find("scope row carries no instrument"),
            std::string::npos);
}

TEST(Hdf5, RoundTripAndBadValue) {
  SessionTable t = ParseSessionCsv(
      "t,device,instrument,x,y,z,qw,qx,qy,qz,jaw,buttons,lens_roll,head_roll\n"
      "0.0,slot0,grasper,0.1,0.2,0.3,1,0,0,0,0.25,1,,\n"
      "0.0,scope,,1,2,3,0,1,0,0,,,0.5,0.25\n"
      "0.001,slot0,none,0.4,0.5,0.6,0,0,1,0,0,2,,\n"
      "0.002,slot1,scorpion_needle,7,8,9,0,0,0,1,1,3,,\n",
      "s.csv");
  const std::string path = TempPath("session_roundtrip.h5");
  WriteSessionHdf5(path, t);
  const SessionTable r = ReadSessionHdf5(path);
  ASSERT_EQ(r.rows.size(), t.rows.size());
  for (std::size_t i = 0; i < r.rows.size(); ++i) {
    EXPECT_EQ(FormatSessionCsvRow(r.rows[i]), FormatSessionCsvRow(t.rows[i])) << i;
  }
  t.rows[2].position_mm.y() = std::nan("");
  WriteSessionHdf5(path, t);
  try {
    ReadSessionHdf5(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  ":2: field '/slot0/position': row 2: non-finite value in column 1"),
              std::string::npos)
        << e.what();
  }
}

TEST(Hdf5, FileImageInMemoryReadsAsTheFile) {
  const SessionTable t = ParseSessionCsv(
      "t,device,instrument,x,y,z,qw,qx,qy,qz,jaw,buttons,lens_roll,head_roll\n"
      "0.0,slot0,grasper,0.1,0.2,0.3,1,0,0,0,0.25,1,,\n"
      "0.0,scope,,1,2,3,0,1,0,0,,,0.5,0.25\n",
      "s.csv");
  const std::string path = TempPath("session_image.h5");
  WriteSessionHdf5(path, t);
  std::ifstream in(path, std::ios::binary);
  const std::string image((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const SessionTable r = ParseSessionHdf5(image.data(), image.size(), "memory.h5");
  EXPECT_EQ(r.file, "memory.h5");
  ASSERT_EQ(r.rows.size(), t.rows.size());
  for (std::size_t i = 0; i < r.rows.size(); ++i) {
    EXPECT_EQ(FormatSessionCsvRow(r.rows[i]), FormatSessionCsvRow(t.rows[i])) << i;
  }
  const std::string text = "not an HDF5 file";
  EXPECT_THROW(ParseSessionHdf5(text.data(), text.size(), "text.h5"), InputError);
}

TEST(RecordReplay, RecordedFramesReplayBitForBit) {
  const Model m = MakeTestModel();
  std::string text = kHeader;
  double t = 0;
  // slot0 exchanges the grasper for the hook half-way, slot1 the scissors for the shaver.
  const char* kInstruments[2][2] = {{"grasper", "hook"}, {"scissors", "shaver"}};
  for (int i = 0; i < 400; ++i) {  // jittery 1 kHz, rotating, jaw moving, short presses
    const Quat q = AimAlong(Vec3(std::cos(t), std::sin(3 * t), 1.0), 0.1 * i);
    text += fmt::format(
        "{:.17g},slot{},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{}\n", t,
        i % 2, kInstruments[i % 2][i < 200 ? 0 : 1], 10 * std::sin(t * 7), t, -t, q.w(), q.x(),
        q.y(), q.z(), 0.5 + 0.5 * std::sin(t * 11), i % 37 == 0 ? 1 : 0);
    t += 0.001 + 0.0004 * std::sin(i * 2.3);
  }
  const double dt = 0.01;
  const std::string path = TempPath("record_replay.csv");
  std::vector<InputFrame> live;
  {
    RecordingSource rec(std::make_unique<RecordedSource>(ParseSessionCsv(text, "s.csv"), m, dt),
                        path, m);
    for (int k = 0; k < 45; ++k) {
      InputFrame f;
      rec.Frame(k, k * dt, &f);
      live.push_back(f);
    }
  }
  RecordedSource replay(ReadSessionCsv(path), m, dt);
  EXPECT_TRUE(replay.warnings().empty());
  int pressed = 0;
  for (int k = 0; k < 45; ++k) {
    InputFrame f;
    replay.Frame(k, k * dt, &f);
    EXPECT_TRUE(BitwiseEqual(f, live[k])) << "step " << k;
    pressed += live[k].tools[0].buttons + live[k].tools[1].buttons;
  }
  EXPECT_GT(pressed, 0);
}

}  // namespace
}  // namespace arthrosim::input

namespace arthrosim::input {
namespace {

TEST(OpenInputSource, PicksTheSourceBySpecAndRecords) {
  const Model m = testing::MakeTestModel();
  SourceOptions o;
  o.dt_s = 0.01;
  o.record_path = testing::TempPath("open_source_record.csv");
  auto src = OpenInputSource(
      std::string(ARTHROSIM_SOURCE_DIR) + "/trajectories/rotator_cuff_tour.yaml", m, o);
  InputFrame f;
  for (int k = 0; k < 3; ++k) src->Frame(k, k * 0.01, &f);
  src.reset();
  EXPECT_EQ(ReadSessionCsv(o.record_path).rows.size(), 9u);
  EXPECT_NE(dynamic_cast<IdleSource*>(OpenInputSource("none", m, SourceOptions{}).get()), nullptr);
  EXPECT_THROW(OpenInputSource("walk.txt", m, SourceOptions{}), InputError);
}

}  // namespace
}  // namespace arthrosim::input
