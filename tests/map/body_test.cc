#include "areomap/map/body.h"

#include <gtest/gtest.h>

#include "areomap/map/error.h"

namespace areomap {
namespace {

TEST(Body, NamedBodiesHaveTheIauRadii) {
  EXPECT_EQ(Body::Mars2000().a, 3396190.0);
  EXPECT_EQ(Body::Mars2000().b, 3376200.0);
  EXPECT_TRUE(Body::MarsSphere().IsSphere());
  EXPECT_EQ(Body::MarsSphere().a, 3396190.0);
  EXPECT_EQ(Body::MolaSphere().a, 3396000.0);
  EXPECT_NEAR(Body::Mars2000().InverseFlattening(), 169.894447223612, 1e-9);
  EXPECT_EQ(Body::MarsSphere().InverseFlattening(), 0.0);
}

TEST(Body, FromNameAcceptsKnownNamesAndNamesThemOnError) {
  EXPECT_EQ(Body::FromName("MOLA-sphere"), Body::MolaSphere());
  try {
    Body::FromName("earth");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("mars2000, mars-sphere, mola-sphere"), std::string::npos);
  }
}

TEST(Body, LocalRadiusRunsFromEquatorialToPolar) {
  const Body mars = Body::Mars2000();
  EXPECT_DOUBLE_EQ(mars.RadiusAtPlanetocentricLatitude(0.0), mars.a);
  EXPECT_NEAR(mars.RadiusAtPlanetocentricLatitude(std::numbers::pi / 2), mars.b, 1e-6);
}

TEST(Body, CheckRejectsInvalidRadii) {
  EXPECT_THROW((Body{"bad", 1.0, 2.0}.Check()), Error);
  EXPECT_THROW((Body{"bad", -1.0, -1.0}.Check()), Error);
  EXPECT_NO_THROW(Body::Mars2000().Check());
}

}  // namespace
}  // namespace areomap
