#include "areomap/map/pds_label.h"

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap {
namespace {

std::string ErrorOf(const nlohmann::json& label) {
  try {
    ParseProductGeometry(label, "label.IMG");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(PdsLabel, MissingOrMalformedKeywordsAreNamed) {
  nlohmann::json camera = {{"GEOMETRIC_CAMERA_MODEL", {{"MODEL_COMPONENT_ID", {"C"}}}}};
  EXPECT_NE(ErrorOf(camera).find("label.IMG: label group GEOMETRIC_CAMERA_MODEL has no keyword "
                                 "MODEL_TYPE"),
            std::string::npos)
      << ErrorOf(camera);
  nlohmann::json frame = {
      {"ROVER_COORDINATE_SYSTEM",
       {{"ORIGIN_OFFSET_VECTOR", {1, 2, 3}}, {"ORIGIN_ROTATION_QUATERNION", {1, 0, 0}}}}};
  EXPECT_NE(ErrorOf(frame).find("ROVER_COORDINATE_SYSTEM.ORIGIN_ROTATION_QUATERNION is invalid: "
                                "expected 4 numbers"),
            std::string::npos)
      << ErrorOf(frame);
}

TEST(PdsLabel, FrameIndexBeyondIntIsNamedNotWrapped) {
  const nlohmann::json label = {{"ROVER_COORDINATE_SYSTEM",
                                 {{"COORDINATE_SYSTEM_INDEX", {4294967297LL, 973}},
                                  {"ORIGIN_OFFSET_VECTOR", {1, 2, 3}},
                                  {"ORIGIN_ROTATION_QUATERNION", {1, 0, 0, 0}}}}};
  EXPECT_NE(ErrorOf(label).find("label.IMG: label keyword ROVER_COORDINATE_SYSTEM."
                                "COORDINATE_SYSTEM_INDEX holds 4294967297: expected indices in int "
                                "range"),
            std::string::npos)
      << ErrorOf(label);
}

TEST(PdsLabel, FrameQuaternionIsScalarFirstAndMapsFrameToReference) {
  // 90 degrees about z: the frame's x axis is the reference's y axis.
  const double s = std::sqrt(0.5);
  const nlohmann::json label = {{"ROVER_COORDINATE_SYSTEM",
                                 {{"COORDINATE_SYSTEM_NAME", "ROVER_FRAME"},
                                  {"REFERENCE_COORD_SYSTEM_NAME", "SITE_FRAME"},
                                  {"ORIGIN_OFFSET_VECTOR", {10, 20, 0}},
                                  {"ORIGIN_ROTATION_QUATERNION", {s, 0, 0, s}}}}};
  const ProductGeometry geometry = ParseProductGeometry(label, "x");
  ASSERT_EQ(geometry.frames.size(), 1u);
  const Eigen::Vector3d p_in_site =
      geometry.frames[0].reference_from_frame * Eigen::Vector3d(1, 0, 0);
  EXPECT_LT((p_in_site - Eigen::Vector3d(10, 21, 0)).norm(), 1e-12);
}

TEST(PdsLabel, ReadsCahvoreFromRealHazcamLabel) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto path = testing::SharedDataDir() / "mer" / "1F490747543EFFCNY9P1214L0M1.IMG";
  const ProductGeometry geometry = ParseProductGeometry(ReadProductLabel(path), path.string());
  ASSERT_TRUE(geometry.camera.has_value());
  EXPECT_EQ(geometry.camera->model_type, "CAHVORE");
  for (const char* id : {"C", "A", "H", "V", "O", "R", "E"}) {
    EXPECT_EQ(geometry.camera->components.at(id).size(), 3u) << id;
  }
  EXPECT_EQ(geometry.camera->components.at("T"), std::vector<double>{3});
  EXPECT_EQ(geometry.camera->components.at("P"), std::vector<double>{0.37});
}

TEST(PdsLabel, PlainImageHasNoLabel) {
  SKIP_WITHOUT_SHARED_DATA();
  EXPECT_THROW(ReadProductLabel(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png"),
               Error);
}

}  // namespace
}  // namespace areomap
