#include "areomap/map/raster.h"

#include <fstream>
#include <regex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/map/projection.h"
#include "areomap/map/raster_description.h"
#include "proj_oracle.h"

namespace areomap {
namespace {

using testing::RunCommand;
using testing::SharedDataDir;
using testing::TempDir;

GeoRaster MakeRaster() {
  cv::Mat band(300, 200, CV_32F);
  cv::randu(band, cv::Scalar(-100), cv::Scalar(100));
  band.at<float>(5, 7) = -9999.0f;
  const MapProjection projection =
      MapProjection::Equirectangular(Body::MarsSphere(), RadFromDeg(-14.57), RadFromDeg(175.47));
  GeoRaster raster;
  raster.bands = {band};
  raster.geotransform = GeoTransform::NorthUp(1000.0, -864000.0, 0.25, 0.25);
  raster.crs_wkt = projection.Wkt();
  raster.nodata = -9999.0;
  return raster;
}

TEST(GeoTransform, MapsPixelCornersAndInverts) {
  const GeoTransform t = GeoTransform::NorthUp(100.0, 200.0, 2.0, 3.0);
  EXPECT_EQ(t.PixelToMap(0, 0), Eigen::Vector2d(100.0, 200.0));
  EXPECT_EQ(t.PixelToMap(0.5, 0.5), Eigen::Vector2d(101.0, 198.5));  // First pixel's centre.
  EXPECT_LT((t.MapToPixel(107.0, 170.0) - Eigen::Vector2d(3.5, 10.0)).norm(), 1e-12);
}

TEST(Raster, GeoTiffRoundTripKeepsPixelsGeoreferenceAndMarsCrs) {
  TempDir dir;
  const GeoRaster raster = MakeRaster();
  const auto path = dir.path() / "dtm.tif";
  WriteGeoTiff(path, raster);
  const RasterDataset dataset = RasterDataset::Open(path);
  EXPECT_EQ(dataset.info().width, 200);
  EXPECT_EQ(dataset.info().height, 300);
  EXPECT_EQ(dataset.info().data_type, "Float32");
  ASSERT_TRUE(dataset.info().nodata.has_value());
  EXPECT_EQ(*dataset.info().nodata, -9999.0);
  ASSERT_TRUE(dataset.info().geotransform.has_value());
  EXPECT_EQ(dataset.info().geotransform->c, raster.geotransform.c);
  const cv::Mat read = dataset.ReadWindow(1, dataset.FullWindow());
  EXPECT_EQ(cv::norm(read, raster.bands[0], cv::NORM_INF), 0.0);
  EXPECT_TRUE(Crs::FromWkt(dataset.info().crs_wkt, path.string()).Describe().is_mars);
  // gdalinfo (what GIS users run) shows the Mars CRS and tiling.
  const std::string gdalinfo = RunCommand("gdalinfo " + path.string());
  EXPECT_NE(gdalinfo.find("Mars (2015) - Sphere"), std::string::npos) << gdalinfo;
  EXPECT_NE(gdalinfo.find("Block=256x256"), std::string::npos) << gdalinfo;
  EXPECT_NE(gdalinfo.find("COMPRESSION=DEFLATE"), std::string::npos) << gdalinfo;
}

TEST(Raster, WindowedReadMatchesTheFullRead) {
  TempDir dir;
  const GeoRaster raster = MakeRaster();
  WriteGeoTiff(dir.path() / "a.tif", raster);
  const RasterDataset dataset = RasterDataset::Open(dir.path() / "a.tif");
  const PixelWindow window{17, 250, 31, 40};
  const cv::Mat part = dataset.ReadWindow(1, window);
  const cv::Mat expected = raster.bands[0](cv::Rect(17, 250, 31, 40));
  EXPECT_EQ(cv::norm(part, expected, cv::NORM_INF), 0.0);
  const cv::Mat as_float = dataset.ReadWindowFloat(1, {0, 0, 10, 10});
  EXPECT_TRUE(std::isnan(as_float.at<float>(5, 7)));  // nodata -> NaN
  EXPECT_EQ(as_float.at<float>(0, 0), raster.bands[0].at<float>(0, 0));
  const std::string message = testing::ErrorMessageOf([&] {
    dataset.ReadWindow(1, {190, 0, 20, 5});
  });
  EXPECT_NE(message.find("outside the raster (200x300)"), std::string::npos) << message;
  EXPECT_THROW(dataset.ReadWindow(2, window), Error);
}

// Reopen gives a second handle with the same description and pixels; two threads reading at
// once, each through its own handle, get exactly what one handle reads alone; a file gone since
// the first Open is an error naming it.
TEST(Raster, ReopenedHandlesReadTheSamePixelsFromTwoThreads) {
  TempDir dir;
  GeoRaster raster = MakeRaster();
  cv::Mat big(1200, 900, CV_32F);
  cv::randu(big, cv::Scalar(-100), cv::Scalar(100));
  raster.bands = {big};
  WriteGeoTiff(dir.path() / "a.tif", raster);
  const RasterDataset dataset = RasterDataset::Open(dir.path() / "a.tif");
  const RasterDataset other = dataset.Reopen();
  EXPECT_EQ(other.info().width, 900);
  EXPECT_EQ(other.info().crs_wkt, dataset.info().crs_wkt);
  const std::vector<PixelWindow> windows = {
      {0, 0, 300, 400}, {250, 380, 400, 500}, {600, 700, 300, 500}};
  std::vector<cv::Mat> first(windows.size()), second(windows.size());
  std::thread reader([&] {
    for (int pass = 0; pass < 20; ++pass) {
      for (size_t i = 0; i < windows.size(); ++i) first[i] = dataset.ReadWindowFloat(1, windows[i]);
    }
  });
  for (int pass = 0; pass < 20; ++pass) {
    for (size_t i = 0; i < windows.size(); ++i) second[i] = other.ReadWindowFloat(1, windows[i]);
  }
  reader.join();
  for (size_t i = 0; i < windows.size(); ++i) {
    const PixelWindow& w = windows[i];
    const cv::Mat expected = big(cv::Rect(w.col0, w.row0, w.width, w.height));
    EXPECT_EQ(cv::norm(first[i], expected, cv::NORM_INF), 0.0) << i;
    EXPECT_EQ(cv::norm(second[i], expected, cv::NORM_INF), 0.0) << i;
  }
  std::filesystem::remove(dir.path() / "a.tif");
  const std::string message = testing::ErrorMessageOf([&] { dataset.Reopen(); });
  EXPECT_NE(message.find("a.tif: no such file"), std::string::npos) << message;
}

// Integer bands come back as the floats of their values, nodata as NaN, whether GDAL converts
// them while copying (up to 16 bits) or they go through doubles (32 bits).
TEST(Raster, IntegerBandsReadAsFloatExactlyWithNodataAsNan) {
  TempDir dir;
  struct Case {
    int depth;
    double nodata;
    std::vector<double> values;  // the first equals nodata
  };
  const std::vector<Case> cases = {
      {CV_8U, 255, {255, 0, 1, 254}},
      {CV_16U, 65535, {65535, 0, 1, 4095, 65534}},
      {CV_16S, -32768, {-32768, -32767, -1, 0, 32767}},
      {CV_32S, -2147483647, {-2147483647, 16777217, -16777219, 0, 2147483647}},
  };
  for (const Case& c : cases) {
    cv::Mat band(1, static_cast<int>(c.values.size()), CV_64F);
    for (size_t i = 0; i < c.values.size(); ++i)
      band.at<double>(0, static_cast<int>(i)) = c.values[i];
    GeoRaster raster;
    band.convertTo(raster.bands.emplace_back(), c.depth);
    raster.nodata = c.nodata;
    const auto path = dir.path() / ("band" + std::to_string(c.depth) + ".tif");
    WriteGeoTiff(path, raster);
    const RasterDataset dataset = RasterDataset::Open(path);
    const cv::Mat read = dataset.ReadWindowFloat(1, {0, 0, band.cols, 1});
    ASSERT_EQ(read.type(), CV_32F);
    EXPECT_TRUE(std::isnan(read.at<float>(0, 0))) << "depth " << c.depth;
    for (size_t i = 1; i < c.values.size(); ++i) {
      EXPECT_EQ(read.at<float>(0, static_cast<int>(i)), static_cast<float>(c.values[i]))
          << "depth " << c.depth << " value " << c.values[i];
    }
    // Into a caller's window-sized float memory: the same values; integers of up to 16 bits
    // land in that memory, the others are converted into a new matrix.
    std::vector<float> memory(c.values.size(), -1.0f);
    cv::Mat into(1, band.cols, CV_32F, memory.data());
    dataset.ReadWindowFloatInto(1, {0, 0, band.cols, 1}, &into);
    EXPECT_EQ(into.ptr<float>() == memory.data(), c.depth != CV_32S) << "depth " << c.depth;
    EXPECT_TRUE(std::isnan(into.at<float>(0, 0))) << "depth " << c.depth;
    EXPECT_EQ(cv::norm(into.colRange(1, band.cols), read.colRange(1, band.cols), cv::NORM_INF), 0.0)
        << "depth " << c.depth;
  }
  // A nodata value no stored integer can equal marks nothing.
  GeoRaster raster;
  raster.bands = {cv::Mat(1, 3, CV_16U, cv::Scalar(7))};
  raster.nodata = 7.5;
  WriteGeoTiff(dir.path() / "half.tif", raster);
  const cv::Mat read =
      RasterDataset::Open(dir.path() / "half.tif").ReadWindowFloat(1, {0, 0, 3, 1});
  EXPECT_EQ(cv::countNonZero(read == 7.0f), 3);
}

TEST(Raster, ScaledBandsReadAsScaledFloatsIntoTheCallersMemoryOrNot) {
  TempDir dir;
  // A VRT gives the stored values a scale and offset (as PDS and ISIS products do): value =
  // 0.5 x stored + 10, stored 0 is nodata.
  for (const int depth : {CV_16U, CV_32F}) {
    GeoRaster raster;
    cv::Mat(1, 4, CV_64F, cv::Scalar(0)).convertTo(raster.bands.emplace_back(), depth);
    for (int i = 0; i < 4; ++i) raster.bands[0].col(i).setTo(2 * i);
    const std::string name = depth == CV_16U ? "uint16" : "float32";
    WriteGeoTiff(dir.path() / (name + ".tif"), raster);
    std::ofstream(dir.path() / (name + ".vrt"))
        << "<VRTDataset rasterXSize=\"4\" rasterYSize=\"1\">\n"
        << "  <VRTRasterBand dataType=\"" << (depth == CV_16U ? "UInt16" : "Float32")
        << "\" band=\"1\">\n"
        << "    <NoDataValue>0</NoDataValue><Offset>10</Offset><Scale>0.5</Scale>\n"
        << "    <SimpleSource><SourceFilename relativeToVRT=\"1\">" << name
        << ".tif</SourceFilename><SourceBand>1</SourceBand></SimpleSource>\n"
        << "  </VRTRasterBand>\n</VRTDataset>\n";
    const RasterDataset dataset = RasterDataset::Open(dir.path() / (name + ".vrt"));
    std::vector<float> memory(4, -1.0f);
    cv::Mat into(1, 4, CV_32F, memory.data());
    dataset.ReadWindowFloatInto(1, {0, 0, 4, 1}, &into);
    // Float32 is read into the caller's memory and scaled there; UInt16 through a new matrix.
    EXPECT_EQ(into.ptr<float>() == memory.data(), depth == CV_32F) << name;
    EXPECT_TRUE(std::isnan(into.at<float>(0, 0))) << name;
    for (int i = 1; i < 4; ++i)
      EXPECT_EQ(into.at<float>(0, i), 10.0f + static_cast<float>(i)) << name;
    const cv::Mat read = dataset.ReadWindowFloat(1, {1, 0, 3, 1});
    EXPECT_EQ(cv::norm(read, into.colRange(1, 4), cv::NORM_INF), 0.0) << name;
  }
}

TEST(Raster, BadFilesGiveErrorsThatNameThem) {
  TempDir dir;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              RasterDataset::Open(dir.path() / "missing.tif");
            }).find("missing.tif: no such file"),
            std::string::npos);
  const auto text = dir.path() / "notes.txt";
  std::ofstream(text) << "this is not a raster\n";
  EXPECT_NE(
      testing::ErrorMessageOf([&] { RasterDataset::Open(text); }).find("not a readable raster"),
      std::string::npos);
  // A truncated GeoTIFF: either opening or reading fails with an error naming the file.
  WriteGeoTiff(dir.path() / "full.tif", MakeRaster(), {16, "NONE"});
  const auto truncated = dir.path() / "truncated.tif";
  std::filesystem::copy_file(dir.path() / "full.tif", truncated);
  std::filesystem::resize_file(truncated, std::filesystem::file_size(truncated) / 3);
  const std::string message = testing::ErrorMessageOf([&] {
    const RasterDataset dataset = RasterDataset::Open(truncated);
    dataset.ReadWindow(1, dataset.FullWindow());
  });
  EXPECT_NE(message.find("truncated.tif"), std::string::npos) << message;
}

TEST(Raster, FailedWriteLeavesNothingBehind) {
  TempDir dir;
  GeoRaster raster = MakeRaster();
  raster.crs_wkt = "not a crs";
  EXPECT_THROW(WriteGeoTiff(dir.path() / "bad.tif", raster), Error);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
  const std::string message = testing::ErrorMessageOf(
      [&] { WriteGeoTiff(dir.path() / "no" / "such" / "x.tif", MakeRaster()); });
  EXPECT_NE(message.find("does not exist"), std::string::npos) << message;
}

// Corner coordinates against GDAL/PROJ: gdalinfo's geotransform corners, converted to geographic by
// cs2cs with the file's own PROJ definition (as gdalinfo does, at full precision).
TEST(RasterDescription, CornersOfRealCubesAgreeWithGdalAndProj) {
  SKIP_WITHOUT_SHARED_DATA();
  int checked = 0;
  for (const auto& folder : {"moc", "isis"}) {
    for (const auto& entry : std::filesystem::directory_iterator(SharedDataDir() / folder)) {
      if (entry.path().extension() != ".cub") continue;  // Not GDAL's .aux.xml sidecars.
      const RasterDescription d = DescribeRaster(entry.path());
      ASSERT_TRUE(d.crs.has_value()) << entry.path();
      EXPECT_TRUE(d.crs->is_mars);
      std::string proj = RunCommand("gdalsrsinfo -o proj4 " + entry.path().string());
      proj.erase(std::remove(proj.begin(), proj.end(), '\n'), proj.end());
      proj.erase(std::remove(proj.begin(), proj.end(), '\''), proj.end());
      std::vector<Eigen::Vector3d> corners;
      for (const auto& c : d.corners) corners.push_back({c.map.x(), c.map.y(), 0.0});
      const auto expected = testing::RunProjTool("cs2cs -f %.12f " + proj, corners);
      for (size_t i = 0; i < d.corners.size(); ++i) {
        ASSERT_TRUE(d.corners[i].own_lon_lat_deg.has_value());
        EXPECT_NEAR(d.corners[i].own_lon_lat_deg->x(), expected[i].x(), 1e-6) << entry.path();
        EXPECT_NEAR(d.corners[i].own_lon_lat_deg->y(), expected[i].y(), 1e-6) << entry.path();
        // These cubes are on spheres, so planetocentric latitude equals the CRS's own.
        EXPECT_NEAR(DegFromRad(d.corners[i].planetocentric->lat), expected[i].y(), 1e-6);
      }
      ++checked;
    }
  }
  EXPECT_EQ(checked, 5);
}

TEST(RasterDescription, MerProductHasCameraModelAndFrames) {
  SKIP_WITHOUT_SHARED_DATA();
  const RasterDescription d =
      DescribeRaster(SharedDataDir() / "mer" / "1N491020376ILFCNY9P0706L0M1.IMG");
  EXPECT_FALSE(d.crs.has_value());
  ASSERT_TRUE(d.product.has_value());
  EXPECT_EQ(d.product->instrument_id, "NAVCAM_LEFT");
  ASSERT_TRUE(d.product->camera.has_value());
  EXPECT_EQ(d.product->camera->model_type, "CAHVOR");
  EXPECT_EQ(d.product->camera->reference_frame, "ROVER_FRAME");
  EXPECT_EQ(d.product->camera->components.at("C"),
            (std::vector<double>{0.442604, -0.0611635, -1.25106}));
  EXPECT_EQ(d.product->camera->components.at("R"),
            (std::vector<double>{0.00096, -0.002183, 0.018547}));
  const auto rover = std::find_if(d.product->frames.begin(), d.product->frames.end(),
                                  [](const auto& f) { return f.name == "ROVER_FRAME"; });
  ASSERT_NE(rover, d.product->frames.end());
  EXPECT_EQ(rover->reference_frame, "SITE_FRAME");
  EXPECT_EQ(rover->label_quaternion_wxyz,
            (std::array<double, 4>{0.580525, 0.0333603, -0.128929, 0.803278}));
  EXPECT_EQ(rover->index.front(), 195);  // Site 195.
  EXPECT_NEAR(rover->reference_from_frame.translation.x(), 73.9193, 1e-12);
}

TEST(DecimationFactor, PowerOfTwoToTheLongestSideButNeverBelowOnePixel) {
  EXPECT_EQ(DecimationFactor(1000, 800, 2048), 1);
  EXPECT_EQ(DecimationFactor(10000, 10000, 2048), 8);  // 1250 px; 4 would leave 2500
  EXPECT_EQ(DecimationFactor(4096, 100, 4096), 1);
  EXPECT_EQ(DecimationFactor(1, 3000, 1024), 1);  // a 1 px wide raster is read whole
  EXPECT_EQ(DecimationFactor(3000, 2, 1024), 2);
}

}  // namespace
}  // namespace areomap
