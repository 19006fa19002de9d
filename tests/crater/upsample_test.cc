#include "areomap/crater/upsample.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/image_io.h"

namespace areomap {
namespace {

// Pixels where `a` and `b` differ: bit for bit, a NaN equal to a NaN.
int DifferingPixels(const cv::Mat& a, const cv::Mat& b) {
  int differing = 0;
  for (int r = 0; r < a.rows; ++r) {
    for (int c = 0; c < a.cols; ++c) {
      const float x = a.at<float>(r, c), y = b.at<float>(r, c);
      if (!(x == y || (std::isnan(x) && std::isnan(y)))) ++differing;
    }
  }
  return differing;
}

cv::Mat OpenCvUpsampled(const cv::Mat& image) {
  cv::Mat out;
  cv::resize(image, out, cv::Size(2 * image.cols, 2 * image.rows), 0, 0, cv::INTER_LINEAR);
  return out;
}

TEST(UpsampleTwice, GivesCvResizesValuesBitForBit) {
  cv::RNG rng(7);
  // Odd and even sizes, rows shorter than a vector register, and more rows than one TBB block.
  for (const cv::Size size :
       {cv::Size(2, 2), cv::Size(3, 5), cv::Size(37, 64), cv::Size(130, 129), cv::Size(7, 300)}) {
    cv::Mat image(size, CV_32F);
    rng.fill(image, cv::RNG::UNIFORM, -1000.0, 5000.0);
    cv::Mat ours;
    UpsampleTwice(image, &ours);
    ASSERT_EQ(ours.size(), cv::Size(2 * size.width, 2 * size.height));
    ASSERT_EQ(ours.type(), CV_32F);
    EXPECT_EQ(DifferingPixels(ours, OpenCvUpsampled(image)), 0) << size;
  }
}

TEST(UpsampleTwice, ReadsAViewAndSpreadsNodataAsCvResize) {
  cv::Mat parent(90, 120, CV_32F);
  cv::RNG(11).fill(parent, cv::RNG::UNIFORM, 0.0, 4095.0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  parent.at<float>(20, 31) = nan;  // inside the view
  parent.at<float>(10, 6) = nan;   // the view's column 1: weight 0 at its left column
  parent.at<float>(5, 40) = nan;   // the view's first row
  const cv::Mat view = parent(cv::Rect(5, 5, 70, 60));  // not continuous
  cv::Mat ours;
  UpsampleTwice(view, &ours);
  const cv::Mat expected = OpenCvUpsampled(view);
  EXPECT_EQ(DifferingPixels(ours, expected), 0);
  // The hole covers the output pixels whose taps include it, and no others.
  EXPECT_EQ(cv::countNonZero(NanMask(ours)), cv::countNonZero(NanMask(expected)));
  EXPECT_TRUE(std::isnan(ours.at<float>(2 * 15, 2 * 26)));
  EXPECT_TRUE(std::isnan(ours.at<float>(2 * 5, 0)));  // weight 0, as cv::resize
}

TEST(UpsampleTwice, ReusesAnOutputOfTheRightSizeAndRejectsOtherTypes) {
  cv::Mat image(16, 24, CV_32F, cv::Scalar(3.0f));
  cv::Mat out(32, 48, CV_32F, cv::Scalar(-1.0f));
  const uchar* memory = out.data;
  UpsampleTwice(image, &out);
  EXPECT_EQ(out.data, memory);
  EXPECT_EQ(cv::countNonZero(out != 3.0f), 0);
  // A single row or column: cv::resize's own path.
  cv::Mat row(1, 9, CV_32F, cv::Scalar(2.0f));
  UpsampleTwice(row, &out);
  EXPECT_EQ(out.size(), cv::Size(18, 2));
  EXPECT_EQ(DifferingPixels(out, OpenCvUpsampled(row)), 0);
  EXPECT_THROW(UpsampleTwice(cv::Mat(8, 8, CV_16U, cv::Scalar(1)), &out), Error);
}

}  // namespace
}  // namespace areomap
