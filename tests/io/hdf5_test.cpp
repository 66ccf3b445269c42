// The RAII HDF5 wrapper: attributes, growth in two dimensions, errors naming file and object,
// and no HDF5 error-stack printing.
#include "arthrosim/io/hdf5.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "run_fixture.h"

namespace arthrosim::io::h5 {
namespace {

TEST(Hdf5, AttributesRoundTrip) {
  const std::string path = testing::TestDir("h5_attrs") + "/a.h5";
  {
    File f = File::Create(path);
    Group g = f.root().CreateGroup("g");
    g.SetAttr("s", std::string("caf\xc3\xa9"));
    g.SetAttr("d", 0.1);
    g.SetAttr("i", std::int64_t{-7});
    g.SetAttr("i", std::int64_t{42});  // overwrite
    f.Close();
  }
  File f = File::OpenReadOnly(path, false);
  const Group g = f.root().OpenGroup("g");
  EXPECT_EQ(g.AttrString("s"), "caf\xc3\xa9");
  EXPECT_EQ(g.AttrDouble("d"), 0.1);
  EXPECT_EQ(g.AttrInt("i"), 42);
  EXPECT_TRUE(g.HasAttr("d"));
  EXPECT_FALSE(g.HasAttr("nope"));
  EXPECT_THROW(g.AttrString("d"), Error);  // not a string
}

TEST(Hdf5, DatasetGrowsInTimeAndNodeDimensions) {
  const std::string path = testing::TestDir("h5_grow") + "/a.h5";
  const double nan = std::numeric_limits<double>::quiet_NaN();
  {
    File f = File::Create(path);
    DatasetSpec spec = GrowingSpec({0, 2, 3}, 8, {1});
    spec.fill = &nan;
    Dataset d = f.root().CreateDataset<double>("x", spec);
    const double row0[6] = {1, 2, 3, 4, 5, 6};
    d.AppendRows(row0, 1);
    d.SetExtent({2, 3, 3});  // a node appears in frame 1
    const double row1[9] = {7, 8, 9, 10, 11, 12, 13, 14, 15};
    d.Write({1, 0, 0}, {1, 3, 3}, NativeType<double>(), row1);
    Dataset rows = f.root().CreateDataset<std::int32_t>("r", GrowingSpec({0, 2}, 4));
    const std::int32_t r[6] = {1, 2, 3, 4, 5, 6};
    rows.AppendRows(r, 2);
    rows.AppendRows(r + 4, 1);
    f.Close();
  }
  File f = File::OpenReadOnly(path, true);
  const Dataset d = f.root().OpenDataset("x");
  EXPECT_EQ(d.dims(), (std::vector<hsize_t>{2, 3, 3}));
  const std::vector<double> all = d.ReadAll<double>();
  ASSERT_EQ(all.size(), 18u);
  EXPECT_EQ(all[5], 6);
  EXPECT_TRUE(std::isnan(all[6]) && std::isnan(all[8]));  // frame 0 had no node 2
  EXPECT_EQ(all[17], 15);
  EXPECT_EQ(f.root().OpenDataset("r").ReadAll<std::int32_t>(),
            (std::vector<std::int32_t>{1, 2, 3, 4, 5, 6}));
}

TEST(Hdf5, ErrorsNameFileAndObjectAndPrintNothing) {
  const std::string path = testing::TestDir("h5_errors") + "/a.h5";
  {
    File f = File::Create(path);
    f.root().CreateGroup("bodies");
    f.Close();
  }
  ::testing::internal::CaptureStderr();
  File f = File::OpenReadOnly(path, false);
  try {
    f.root().OpenGroup("bodies").OpenDataset("positions");
    ADD_FAILURE() << "expected h5::Error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find("/bodies/positions"), std::string::npos) << what;
  }
  EXPECT_THROW(File::OpenReadOnly(path + ".missing", false), Error);
  EXPECT_TRUE(f.root().Exists("bodies"));
  EXPECT_FALSE(f.root().Exists("bodies/x/y"));
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

}  // namespace
}  // namespace arthrosim::io::h5
