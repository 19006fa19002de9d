#include "areomap/map/image_io.h"

#include <gtest/gtest.h>

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
}

TEST(ImageIo, ReadsTheRealHrscImage) {
  SKIP_WITHOUT_SHARED_DATA();
  const cv::Mat image = ReadImage(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png");
  EXPECT_EQ(image.cols, 1700);
  EXPECT_EQ(image.rows, 850);
  EXPECT_EQ(image.type(), CV_8UC1);
}

}  // namespace
}  // namespace areomap
