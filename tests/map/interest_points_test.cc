#include "areomap/map/interest_points.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap {
namespace {

// A 7 x 7 checkerboard of 40 px squares filling the image, softened like a camera would: its
// 6 x 6 corners (X junctions) sit at (40 i - 0.5, 40 j - 0.5), between pixel centres.
cv::Mat Checkerboard() {
  cv::Mat image(280, 280, CV_8U);
  for (int j = 0; j < 7; ++j) {
    for (int i = 0; i < 7; ++i) {
      const int value = (i + j) % 2 == 0 ? 40 : 220;
      image(cv::Rect(40 * i, 40 * j, 40, 40)).setTo(value);
    }
  }
  cv::GaussianBlur(image, image, cv::Size(5, 5), 1.0);
  return image;
}

TEST(ForstnerPoints, FindEveryCheckerboardCornerAndNothingOnEdgesOrFlatAreas) {
  const cv::Mat image = Checkerboard();
  ForstnerOptions options;
  options.grid_cells = 1;
  options.max_points_per_cell = 1000;
  const std::vector<InterestPoint> points = DetectForstnerPoints(image, options);

  std::vector<int> found(36, 0);
  for (const InterestPoint& p : points) {
    const int i = static_cast<int>(std::lround((p.pixel.x() + 0.5) / 40.0));
    const int j = static_cast<int>(std::lround((p.pixel.y() + 0.5) / 40.0));
    const double dx = p.pixel.x() + 0.5 - 40.0 * i, dy = p.pixel.y() + 0.5 - 40.0 * j;
    // Förstner's least-squares location is biased only by the discrete (Sobel) gradients near
    // the junction, where they are not normal to either edge: within half a pixel.
    ASSERT_LE(std::hypot(dx, dy), 0.5) << "point at " << p.pixel.transpose() << " is no corner";
    ASSERT_TRUE(i >= 1 && i <= 6 && j >= 1 && j <= 6)
        << "point off the corner grid " << p.pixel.transpose();
    EXPECT_GE(p.roundness, options.min_roundness);
    ++found[static_cast<size_t>((j - 1) * 6 + (i - 1))];
  }
  for (size_t k = 0; k < found.size(); ++k) {
    EXPECT_GE(found[k], 1) << "inner corner " << k << " missed";
    EXPECT_EQ(found[k], 1) << "inner corner " << k << " found " << found[k] << " times";
  }
}

TEST(ForstnerPoints, GridKeepsAtMostTheStrongestPointsPerCell) {
  ForstnerOptions options;
  options.grid_cells = 2;
  options.max_points_per_cell = 3;
  const std::vector<InterestPoint> points = DetectForstnerPoints(Checkerboard(), options);
  EXPECT_EQ(points.size(), 12u);  // Each 140 px quadrant holds 9 corners.
  for (size_t k = 1; k < points.size(); ++k) EXPECT_GE(points[k - 1].weight, points[k].weight);
}

TEST(ForstnerPoints, FlatNanAndBadImages) {
  EXPECT_TRUE(DetectForstnerPoints(cv::Mat(64, 64, CV_32F, cv::Scalar(3.0f))).empty());
  cv::Mat holes = cv::Mat(64, 64, CV_32F, cv::Scalar(std::nanf("")));
  EXPECT_TRUE(DetectForstnerPoints(holes).empty());
  EXPECT_THROW(DetectForstnerPoints(cv::Mat(8, 8, CV_8UC3)), Error);
  EXPECT_THROW(DetectForstnerPoints(cv::Mat()), Error);
  ForstnerOptions bad;
  bad.min_roundness = 1.5;
  try {
    DetectForstnerPoints(Checkerboard(), bad);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("min_roundness"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace areomap
