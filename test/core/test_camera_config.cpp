#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/config_table.h"
#include "test_util.h"

using namespace kinect_pipeline;

using kp_test::expectInvalid;

TEST(Camera, FromFovRoundTrips)
{
  const double hfov = 70.6 * M_PI / 180.0, vfov = 60.0 * M_PI / 180.0;
  const Camera c = Camera::fromFov(512, 424, hfov, vfov);
  EXPECT_NEAR(c.hfov(), hfov, 1e-12);
  EXPECT_NEAR(c.vfov(), vfov, 1e-12);
  EXPECT_DOUBLE_EQ(c.cx, 255.5);
  EXPECT_DOUBLE_EQ(c.cy, 211.5);
  // The outer pixel edge sits at half the field of view.
  EXPECT_NEAR(std::atan((511.5 - c.cx) / c.fx), hfov / 2, 1e-12);
}

TEST(Camera, RejectsBadModels)
{
  expectInvalid([] { Camera(512, 424, 0.0, 365, 256, 212); }, {"fx", "0"});
  expectInvalid([] { Camera(512, 424, 365, NAN, 256, 212); }, {"fy", "nan"});
  expectInvalid([] { Camera(0, 424, 365, 365, 256, 212); }, {"width", "0"});
  expectInvalid([] { Camera(512, 424, 365, 365, INFINITY, 212); }, {"cx"});
  expectInvalid([] { Camera::fromFov(512, 424, 3.2, 1.0); }, {"hfov", "3.2"});
}

TEST(Config, DefaultsAreValid) { EXPECT_NO_THROW(Config().validate()); }

TEST(Config, RefusesBadFieldsNamingThem)
{
  auto with = [](auto f) {
    return [f] {
      Config c;
      f(c);
      c.validate();
    };
  };
  expectInvalid(with([](Config& c) { c.sensor_height = -1.0; }), {"sensor_height", "-1"});
  expectInvalid(with([](Config& c) { c.ceiling_height = 0.9; }), {"ceiling_height", "sensor_height", "0.9"});
  expectInvalid(with([](Config& c) { c.open_kernel_size = 4; }), {"open_kernel_size", "4", "odd"});
  expectInvalid(with([](Config& c) { c.range_max = 0.05; }), {"range_max", "range_min"});
  expectInvalid(with([](Config& c) { c.sensor_pitch = 2.0; }), {"sensor_pitch", "2"});
  expectInvalid(with([](Config& c) { c.sensor_roll = 3.2; }), {"sensor_roll", "3.2"});
  EXPECT_NO_THROW(with([](Config& c) { c.sensor_roll = -M_PI; })());  // upside down
  expectInvalid(with([](Config& c) {
                  c.geometry = Geometry::kThesis;
                  c.sensor_roll = 2.0;
                }),
                {"sensor_roll = 2", "thesis", "upright"});
  expectInvalid(with([](Config& c) { c.confidence_window = 0; }), {"confidence_window", "0"});
  expectInvalid(with([](Config& c) { c.min_intensity = 1.5; }), {"min_intensity", "1.5"});
  expectInvalid(with([](Config& c) { c.threshold_curve = {{1.0, 0.1}}; }), {"threshold_curve", "1 point"});
  expectInvalid(with([](Config& c) { c.threshold_curve = {{2.0, 0.1}, {1.0, 0.2}}; }), {"point 1", "increasing"});
  expectInvalid(with([](Config& c) { c.threshold_curve = {{1.0, 0.3}, {2.0, 0.2}}; }), {"point 1", "non-decreasing"});
  expectInvalid(with([](Config& c) { c.threshold_curve = {{1.0, 0.0}, {2.0, 0.2}}; }), {"point 0", "> 0"});
}

TEST(Config, ProblemsNameEveryBadFieldAtOnce)
{
  EXPECT_TRUE(Config().problems().empty());
  Config c;
  c.ceiling_height = 0.5;  // below the sensor: a combination
  c.open_kernel_size = 4;
  c.range_min = -1.0;      // invalid on its own: its combination with range_max is not judged
  c.num_threads = 5000;
  c.range_max = 4.0;       // valid, so not named
  const std::vector<std::string> all = c.problems();
  // The order: each field's range in the table's order, then the rules of one field, then the combinations.
  ASSERT_EQ(all.size(), 4u);
  EXPECT_NE(all[0].find("range_min = -1"), std::string::npos) << all[0];
  EXPECT_NE(all[1].find("num_threads = 5000"), std::string::npos) << all[1];
  EXPECT_NE(all[2].find("open_kernel_size = 4"), std::string::npos) << all[2];
  EXPECT_NE(all[3].find("ceiling_height = 0.5"), std::string::npos) << all[3];
  expectInvalid([&] { c.validate(); }, {"ceiling_height = 0.5", "; Config.open_kernel_size = 4", "range_min = -1",
                                        "num_threads = 5000"});
  for (const std::string& m : all)
    EXPECT_EQ(m.find("range_max"), std::string::npos) << m;
}

TEST(Config, CurveTextRoundTrips)
{
  const auto curve = defaultThresholdCurve();
  const auto back = parseThresholdCurve(formatThresholdCurve(curve));
  ASSERT_EQ(back.size(), curve.size());
  for (std::size_t i = 0; i < curve.size(); ++i)
  {
    EXPECT_DOUBLE_EQ(back[i].depth, curve[i].depth);
    EXPECT_DOUBLE_EQ(back[i].threshold, curve[i].threshold);
  }
  expectInvalid([] { parseThresholdCurve("1.0:0.1, 2.0"); }, {"'2.0'", "depth:threshold"});
  expectInvalid([] { parseThresholdCurve("1.0:0.1, 2.0:x"); }, {"2.0:x"});
}

TEST(Config, EnumNames)
{
  EXPECT_EQ(geometryFromString("thesis"), Geometry::kThesis);
  EXPECT_EQ(projectionFromString("column"), Projection::kColumn);
  EXPECT_EQ(kernelShapeFromString("ellipse"), KernelShape::kEllipse);
  expectInvalid([] { geometryFromString("Exact"); }, {"geometry", "'Exact'", "'exact'"});
  expectInvalid([] { projectionFromString("radial"); }, {"projection", "radial"});
}

TEST(ConfigFields, EveryNumberOutsideItsRangeIsNamedAndEveryTextRoundTrips)
{
  for (const ConfigField& f : configFields())
  {
    Config c;
    EXPECT_EQ(configField(f.name).name, f.name);
    if (f.kind == FieldKind::kReal || f.kind == FieldKind::kInteger)
    {
      for (const double bad : {f.lo - 1.0, f.hi + 1.0})
      {
        f.setNumber(c, bad);
        const auto all = c.problems();
        ASSERT_FALSE(all.empty()) << f.name << " = " << bad;
        EXPECT_EQ(all.front().find(std::string("Config.") + f.name + " = "), 0u) << all.front();
      }
      f.setNumber(c, f.lo);
      EXPECT_EQ(f.rangeProblem(c), "") << f.name;
    }
    Config back;
    f.setText(back, f.text(Config{}));
    EXPECT_EQ(f.text(back), f.text(Config{})) << f.name;
    for (const std::string& name : f.choices)  // the table's names are the ones the parsers take
    {
      f.setText(back, name);
      EXPECT_EQ(f.text(back), name) << f.name;
    }
    EXPECT_EQ(f.kind == FieldKind::kChoice, !f.choices.empty()) << f.name;
  }
  expectInvalid([] { configField("sensor_hieght"); }, {"sensor_hieght", "sensor_height"});
  Config c;
  expectInvalid([&] { configField("open_kernel_size").setNumber(c, 2.5); }, {"open_kernel_size", "2.5", "whole"});
  // An integer its type cannot hold is named with the field's range (it said "a whole number" of a whole number).
  expectInvalid([&] { configField("open_kernel_size").setNumber(c, 0x1p40); },
                {"open_kernel_size = 1.09951e+12", "an integer in [0, 31]"});
  expectInvalid([&] { configField("geometry").setText(c, "exakt"); }, {"exakt", "'exact'"});
}
