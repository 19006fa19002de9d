// The decision's high-passed images (registration/src/high_pass.h): the window high-passed whole
// gives the same pixels as crop by crop, and the high pass removes the local mean.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "high_pass.h"

namespace areomap::internal {
namespace {

// Blurred noise with a few NaN holes and a masked-out block, as an orbital window can have.
MaskedImage Window() {
  cv::Mat image(180, 220, CV_32F);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (auto it = image.begin<float>(); it != image.end<float>(); ++it) *it = u(rng);
  cv::GaussianBlur(image, image, cv::Size(), 1.5);
  image(cv::Rect(40, 30, 6, 9)).setTo(std::numeric_limits<float>::quiet_NaN());
  cv::Mat mask(image.size(), CV_8U, cv::Scalar(255));
  mask(cv::Rect(150, 100, 20, 12)).setTo(0);
  return {image, mask};
}

// Equal where both are defined, NaN at the same pixels.
void ExpectSamePixels(const cv::Mat& a, const cv::Mat& b) {
  ASSERT_EQ(a.size(), b.size());
  int compared = 0;
  for (int r = 0; r < a.rows; ++r) {
    for (int c = 0; c < a.cols; ++c) {
      const float x = a.at<float>(r, c), y = b.at<float>(r, c);
      ASSERT_EQ(std::isnan(x), std::isnan(y)) << "at (" << c << ", " << r << ")";
      if (std::isnan(x)) continue;
      EXPECT_NEAR(x, y, 1e-6f) << "at (" << c << ", " << r << ")";
      ++compared;
    }
  }
  EXPECT_GT(compared, 0);
}

TEST(HighPassedImage, WholeAndCropByCropGiveTheSamePixels) {
  const MaskedImage window = Window();
  const HighPassedImage whole(window, true), by_crop(window, false);
  const cv::Size templ(60, 40);
  // Inside, over a NaN hole and the masked block, clipped by each edge.
  for (const ShiftWindow& shifts :
       {ShiftWindow::Around(80, 70, 5), ShiftWindow::Around(20, 10, 8),
        ShiftWindow::Around(140, 90, 3), ShiftWindow::Around(-10, -5, 4),
        ShiftWindow::Around(175, 150, 6)}) {
    ShiftWindow local_whole, local_crop;
    const MaskedImage a = whole.Reach(shifts, templ, &local_whole);
    const MaskedImage b = by_crop.Reach(shifts, templ, &local_crop);
    EXPECT_EQ(local_whole.min_shift_x, local_crop.min_shift_x);
    EXPECT_EQ(local_whole.min_shift_y, local_crop.min_shift_y);
    // The pixels the template reaches (the margin around them serves the high pass only).
    const cv::Rect reached =
        cv::Rect(local_crop.min_shift_x, local_crop.min_shift_y,
                 local_crop.max_shift_x - local_crop.min_shift_x + templ.width,
                 local_crop.max_shift_y - local_crop.min_shift_y + templ.height) &
        cv::Rect(0, 0, b.image.cols, b.image.rows);
    ExpectSamePixels(a.image(reached), b.image(reached));
  }
  ShiftWindow local;
  EXPECT_TRUE(whole.Reach(ShiftWindow::Around(1000, 1000, 2), templ, &local).image.empty());
  EXPECT_TRUE(by_crop.Reach(ShiftWindow::Around(1000, 1000, 2), templ, &local).image.empty());
}

TEST(HighPass, RemovesTheLocalMeanAndKeepsInvalidPixelsOut) {
  cv::Mat ramp(64, 64, CV_32F);
  for (int r = 0; r < ramp.rows; ++r) {
    for (int c = 0; c < ramp.cols; ++c)
      ramp.at<float>(r, c) = 100.0f + 0.5f * static_cast<float>(c);
  }
  ramp.at<float>(30, 30) = std::numeric_limits<float>::quiet_NaN();
  const MaskedImage hp = HighPass({ramp, {}});
  EXPECT_TRUE(std::isnan(hp.image.at<float>(30, 30)));
  EXPECT_EQ(hp.mask.at<uchar>(30, 30), 0);
  // A linear ramp is its own local mean away from the border and the hole.
  EXPECT_NEAR(hp.image.at<float>(15, 45), 0.0f, 1e-3f);
  EXPECT_NEAR(hp.image.at<float>(48, 20), 0.0f, 1e-3f);
}

}  // namespace
}  // namespace areomap::internal
