#include "areomap/map/image_io.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#endif

#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap {
namespace {

TEST(ImageIo, PngRoundTripsEightAndSixteenBit) {
  testing::TempDir dir;
  cv::Mat gray16(40, 60, CV_16UC1);
  cv::randu(gray16, cv::Scalar(0), cv::Scalar(4095));  // 12-bit like MER frames.
  cv::Mat rgb8(30, 20, CV_8UC3);
  cv::randu(rgb8, cv::Scalar::all(0), cv::Scalar::all(255));
  WriteImage(dir.path() / "a.png", gray16);
  WriteImage(dir.path() / "b.tif", rgb8);
  const cv::Mat a = ReadImage(dir.path() / "a.png");
  const cv::Mat b = ReadImage(dir.path() / "b.tif");
  EXPECT_EQ(a.type(), CV_16UC1);
  EXPECT_EQ(b.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(a, gray16, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(b, rgb8, cv::NORM_INF), 0.0);
  // Only the two images are left: no temporary files.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            2);
}

TEST(ImageIo, ErrorsNameTheFile) {
  testing::TempDir dir;
  try {
    ReadImage(dir.path() / "nope.png");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nope.png: no such file"), std::string::npos);
  }
  EXPECT_THROW(WriteImage(dir.path() / "x.png", cv::Mat(3, 3, CV_32F)), Error);

  // A truncated PNG: one line naming the file and the cause.
  cv::Mat ramp(200, 300, CV_16UC1);
  cv::randu(ramp, 0, 65535);
  WriteImage(dir.path() / "whole.png", ramp);
  std::string bytes;
  {
    std::ifstream in(dir.path() / "whole.png", std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::ofstream(dir.path() / "cut.png", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  const std::string message = testing::ErrorMessageOf([&] {
#if defined(__SANITIZE_ADDRESS__)
    // OpenImageIO 2.4 leaks its error text when libpng gives up on the file (tests/lsan.supp
    // names the frame, but ASan's fast unwinder often stops in libstdc++ before reaching it, so
    // the suppression misses): that library's allocations here are not ours to report.
    const __lsan::ScopedDisabler third_party_leak;
#endif
    ReadImage(dir.path() / "cut.png");
  });
  EXPECT_NE(message.find("cut.png: read failed (truncated file?): "), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

TEST(ImageIo, ReadsTheRealHrscImage) {
  SKIP_WITHOUT_SHARED_DATA();
  const cv::Mat image = ReadImage(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png");
  EXPECT_EQ(image.cols, 1700);
  EXPECT_EQ(image.rows, 850);
  EXPECT_EQ(image.type(), CV_8UC1);
}

TEST(FiniteQuantileRange, MatchesTheSortedFiniteValuesAndSkipsNan) {
  // 0..9999 shuffled into a 100 x 100 image, with NaN and infinities on top of some of them.
  std::vector<float> values(10000);
  for (size_t i = 0; i < values.size(); ++i) values[i] = static_cast<float>(i);
  std::vector<float> shuffled = values;
  cv::RNG rng(7);
  for (size_t i = shuffled.size() - 1; i > 0; --i) {
    std::swap(shuffled[i], shuffled[static_cast<size_t>(rng.uniform(0, static_cast<int>(i) + 1))]);
  }
  cv::Mat image(100, 100, CV_32F, shuffled.data());
  std::vector<float> finite;
  for (int i = 0; i < 10000; ++i) {
    float& v = image.at<float>(i / 100, i % 100);
    if (i % 7 == 0) v = std::numeric_limits<float>::quiet_NaN();
    if (i % 11 == 0) v = std::numeric_limits<float>::infinity();
    if (std::isfinite(v)) finite.push_back(v);
  }
  std::sort(finite.begin(), finite.end());
  const auto expected = [&](double q) {
    return finite[static_cast<size_t>(q * static_cast<double>(finite.size() - 1))];
  };
  for (const auto& [low, high] : {std::pair{0.01, 0.99}, {0.0, 1.0}, {0.5, 0.5}, {0.2, 0.3}}) {
    const auto range = FiniteQuantileRange(image, low, high);
    ASSERT_TRUE(range.has_value());
    EXPECT_EQ(range->low, expected(low)) << low;
    EXPECT_EQ(range->high, expected(high)) << high;
  }
  // Every other row and column: the quantiles of that sample; 16-bit input converted.
  std::vector<float> every_other;
  for (int r = 0; r < 100; r += 2) {
    for (int c = 0; c < 100; c += 2) {
      if (std::isfinite(image.at<float>(r, c))) every_other.push_back(image.at<float>(r, c));
    }
  }
  std::sort(every_other.begin(), every_other.end());
  const auto strided = FiniteQuantileRange(image, 0.0, 1.0, 2);
  ASSERT_TRUE(strided.has_value());
  EXPECT_EQ(strided->low, every_other.front());
  EXPECT_EQ(strided->high, every_other.back());
  cv::Mat words(2, 2, CV_16U, cv::Scalar(300));
  words.at<uint16_t>(1, 1) = 900;
  EXPECT_EQ(FiniteQuantileRange(words, 0.0, 1.0)->high, 900.0);
}

TEST(FiniteQuantileRange, NoFinitePixelGivesNothingAndBadArgumentsThrow) {
  const cv::Mat holes(4, 4, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_FALSE(FiniteQuantileRange(holes, 0.01, 0.99).has_value());
  EXPECT_FALSE(FiniteQuantileRange(cv::Mat(), 0.01, 0.99).has_value());
  const cv::Mat ones(4, 4, CV_32F, cv::Scalar(1.0));
  EXPECT_THROW(FiniteQuantileRange(ones, 0.9, 0.1), Error);
  EXPECT_THROW(FiniteQuantileRange(ones, 0.0, 1.5), Error);
  EXPECT_THROW(FiniteQuantileRange(ones, 0.0, 1.0, 0), Error);
  EXPECT_THROW(FiniteQuantileRange(cv::Mat(2, 2, CV_32FC3), 0.0, 1.0), Error);
}

// Rows wider than any SIMD register, NaN at the first, middle and last lanes: `image != image`
// finds none of these in OpenCV 4.6, NanMask every one and nothing else.
template <typename T>
void ExpectNanMaskMarksExactlyTheNans(int type) {
  cv::Mat image(3, 67, type);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      image.at<T>(r, c) = (c * 7 + r) % 5 == 0 || c == image.cols - 1
                              ? std::numeric_limits<T>::quiet_NaN()
                              : static_cast<T>(c - 30);
    }
  }
  const cv::Mat mask = NanMask(image);
  ASSERT_EQ(mask.type(), CV_8U);
  ASSERT_EQ(mask.size(), image.size());
  int nans = 0;
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const bool nan = std::isnan(image.at<T>(r, c));
      nans += nan ? 1 : 0;
      EXPECT_EQ(mask.at<uchar>(r, c), nan ? 255 : 0) << "row " << r << ", column " << c;
    }
  }
  EXPECT_GT(nans, 40);
}

TEST(NanMask, MarksExactlyTheNanPixelsOfFloatImages) {
  ExpectNanMaskMarksExactlyTheNans<float>(CV_32F);
  ExpectNanMaskMarksExactlyTheNans<double>(CV_64F);
}

TEST(NanMask, IsEmptyForIntegerImages) {
  EXPECT_EQ(cv::countNonZero(NanMask(cv::Mat(5, 70, CV_16U, cv::Scalar(65535)))), 0);
  EXPECT_EQ(cv::countNonZero(NanMask(cv::Mat(5, 70, CV_8U, cv::Scalar(0)))), 0);
}

}  // namespace
}  // namespace areomap
