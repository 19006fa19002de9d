// Orthophotos from rendered rover images (the generator's SiteMesh) draped on a DTM gridded from
// simulated stereo points, checked against the scene's albedo (geolocation) and the rendered
// ranges (occlusion).
#include "areomap/map/orthophoto.h"

#include <cmath>
#include <cstdio>
#include <optional>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/samples/orbital.h"
#include "areomap/samples/rover.h"
#include "areomap/samples/simulated_points.h"
#include "test_support.h"

namespace areomap {
namespace {

struct OrthoFixture {
  Scene scene;
  SceneGeoreference georef;
  MapFrame map;
  SiteGeoreference site;
  std::vector<OrthoSourceImage> images;
  std::vector<cv::Mat> ranges;  // Rendered range per image [m].
  Dtm dtm;                      // From simulated stereo points (eq. 4.3 noise).
  Dtm truth_dtm;                // The scene's true heights on the same grid (sigma 0).

  static SceneOptions Options() {
    SceneOptions o;
    o.half_extent_m = 60.0;
    o.crater_count = 0;
    o.roughness_m = 0.4;
    o.rock_path = {{-10.0, 0.0}, {10.0, 20.0}};
    o.rock_corridor_m = 15.0;
    o.rock_abundance_k = 0.08;
    o.seed = 5;
    return o;
  }

  OrthoFixture()
      : scene(Options()),
        georef{Body::Mars2000(),
               {RadFromDeg(-14.5692), RadFromDeg(175.4729), scene.GroundHeightAt(0.0, 0.0)}},
        map(MapFrame::LocalEquirectangular(georef.body, georef.origin)),
        site(SiteGeoreference::AtOrigin(georef.body, georef.origin)) {
    // The rover stands at the origin facing north, so its frame is the site frame.
    const Eigen::Vector3d site_in_enu(0.0, 0.0, georef.origin.h);
    const Rigid3d enu_from_site(SiteFromEnu().rotation.conjugate(), site_in_enu);
    RenderOptions render;
    render.near_posting_m = 0.04;
    render.near_radius_m = 6.0;
    render.mid_posting_m = 0.08;
    render.mid_radius_m = 20.0;
    render.far_radius_m = 40.0;
    const SiteMesh mesh(scene, site_in_enu, render);
    StereoCameraOptions navcam;
    navcam.width = navcam.height = 512;
    navcam.field_of_view_deg = 45.0;
    int id = 0;
    for (const double azimuth_deg : {10.0, 50.0}) {
      const CahvorModel camera =
          StereoCameras(navcam, {RadFromDeg(azimuth_deg), RadFromDeg(-25.0)})[0];
      const SiteMesh::Image image =
          mesh.Render(camera.Transformed(enu_from_site), navcam.width, navcam.height, 3u + id);
      images.push_back({id++, image.dn, camera});
      ranges.push_back(image.range);
    }
    SimulatedPointsOptions points;
    points.azimuth_min_deg = -15.0;
    points.azimuth_max_deg = 75.0;
    points.angular_step_rad = 2e-3;
    points.max_range_m = 16.0;
    const PointCloud cloud = SimulateSitePointCloud(scene, {0.0, 0.0}, 0, points);
    DtmOptions dtm_options;
    dtm_options.posting_m = 0.1;
    dtm = MakeDtm({{&cloud, site}}, map, dtm_options);
    truth_dtm = dtm;
    GriddedLayers& t = truth_dtm.layers;
    t.elevation = t.elevation.clone();
    t.sigma = cv::Mat(t.grid.height, t.grid.width, CV_32F, cv::Scalar(0.0));
    for (int row = 0; row < t.grid.height; ++row) {
      for (int col = 0; col < t.grid.width; ++col) {
        const Eigen::Vector2d e = Enu(t.grid.CellCenter(col, row), georef.origin.h);
        t.elevation.at<float>(row, col) = static_cast<float>(scene.HeightAt(e.x(), e.y()));
      }
    }
  }

  // ENU (east, north) under a map cell centre at height z.
  Eigen::Vector2d Enu(const Eigen::Vector2d& xy, double z) const {
    return (georef.EnuFromMbf() * map.MbfFromMap({xy.x(), xy.y(), z})).head<2>();
  }
};

const OrthoFixture& Fixture() {
  static const OrthoFixture fixture;
  return fixture;
}

// The check: the orthophoto's texture sits where the scene's albedo is, within 2 ground
// pixels, on patches out to 15 m (shift of the NCC peak against an albedo ortho of the truth).
TEST(Orthophoto, GeolocationWithinTwoGroundPixelsOutTo15m) {
  const OrthoFixture& f = Fixture();
  const Orthophoto ortho = MakeOrthophoto(f.dtm, f.site, f.map, f.images, OrthoOptions{});
  ASSERT_GT(ortho.valid_cells, 10000);
  constexpr int kPatch = 24, kSearch = 5;
  const int half = kPatch / 2 + kSearch;
  int patches = 0;
  double worst = 0.0, squared = 0.0;
  int within = 0;
  Eigen::Vector2d mean_shift = Eigen::Vector2d::Zero();
  for (int row = half; row + half < ortho.grid.height; row += kPatch / 2) {
    for (int col = half; col + half < ortho.grid.width; col += kPatch / 2) {
      const cv::Rect rect(col - kPatch / 2, row - kPatch / 2, kPatch, kPatch);
      if (cv::countNonZero(ortho.valid(rect)) < 0.9 * kPatch * kPatch) continue;
      const Eigen::Vector2d xy = ortho.grid.CellCenter(col, row);
      const Eigen::Vector2d enu = f.Enu(xy, f.georef.origin.h);
      if (enu.norm() < 3.0 || enu.norm() > 15.0) continue;
      // Truth: the scene's albedo on the same cells, with a margin to search in.
      cv::Mat truth(2 * half, 2 * half, CV_32F);
      const Eigen::Vector2i offset = ortho.grid.OffsetIn(f.dtm.layers.grid);
      for (int r = 0; r < 2 * half; ++r) {
        for (int c = 0; c < 2 * half; ++c) {
          const int tr = row - half + r, tc = col - half + c;
          float z = f.dtm.layers.elevation.at<float>(tr + offset.y(), tc + offset.x());
          if (!std::isfinite(z)) z = static_cast<float>(f.georef.origin.h);
          const Eigen::Vector2d e = f.Enu(ortho.grid.CellCenter(tc, tr), z);
          // Averaged over the cell (3 x 3 samples; ENU and map axes agree to ~1 %).
          double albedo = 0.0;
          for (int i = -1; i <= 1; ++i) {
            for (int j = -1; j <= 1; ++j) {
              const double step = ortho.grid.posting / 3.0;
              albedo += f.scene.AlbedoAt(e.x() + i * step, e.y() + j * step) / 9.0;
            }
          }
          truth.at<float>(r, c) = static_cast<float>(albedo);
        }
      }
      cv::Mat score;
      cv::Mat patch = ortho.image(rect).clone();
      patch.setTo(cv::mean(patch, ortho.valid(rect))[0], ortho.valid(rect) == 0);
      cv::matchTemplate(truth, patch, score, cv::TM_CCOEFF_NORMED);
      double peak = 0.0;
      cv::Point at;
      cv::minMaxLoc(score, nullptr, &peak, nullptr, &at);
      if (peak < 0.3) continue;  // Texture too weak or shadowed to locate.
      const double dx = at.x - kSearch, dy = at.y - kSearch;
      const double shift = std::hypot(dx, dy);
      worst = std::max(worst, shift);
      within += shift < 2.0 ? 1 : 0;
      mean_shift += Eigen::Vector2d(dx, dy);
      squared += shift * shift;
      ++patches;
    }
  }
  ASSERT_GE(patches, 10);
  mean_shift /= patches;
  const double rms = std::sqrt(squared / patches);
  std::printf(
      "orthophoto: %d valid cells; %d patches 3-15 m: RMS shift %.2f px, %d%% under 2 px, "
      "worst %.2f px, mean (%.2f, %.2f) px (ground pixel %.2f m)\n",
      ortho.valid_cells, patches, rms, 100 * within / patches, worst, mean_shift.x(),
      mean_shift.y(), ortho.grid.posting);
  EXPECT_LT(rms, 2.0);
  EXPECT_GE(within, 0.8 * patches);
  EXPECT_LT(mean_shift.norm(), 0.5);  // No systematic offset.
}

// On the true DTM a painted cell shows its own ground: the true ground under it is what the
// chosen image sees there (its range matches the rendered range), not a nearer rock or ridge.
// Without the depth test (infinite tolerance) cells behind them get painted with them.
TEST(Orthophoto, DepthTestKeepsOccludedCellsUnpainted) {
  const OrthoFixture& f = Fixture();
  const auto occluded_painted = [&](const OrthoOptions& options) {
    const Orthophoto ortho = MakeOrthophoto(f.truth_dtm, f.site, f.map, f.images, options);
    const Eigen::Vector2i offset = ortho.grid.OffsetIn(f.dtm.layers.grid);
    int wrong = 0;
    for (int row = 0; row < ortho.grid.height; ++row) {
      for (int col = 0; col < ortho.grid.width; ++col) {
        const int id = ortho.source_id.at<int32_t>(row, col);
        if (id < 0) continue;
        // The true ground under the cell: is it what the chosen image shows there?
        const Eigen::Vector2d xy = ortho.grid.CellCenter(col, row);
        const double z = f.truth_dtm.layers.elevation.at<float>(row + offset.y(), col + offset.x());
        const Eigen::Vector2d enu = f.Enu(xy, z);
        const Eigen::Vector3d truth_in_site =
            SiteFromEnu() * Eigen::Vector3d(enu.x(), enu.y(),
                                            f.scene.HeightAt(enu.x(), enu.y()) - f.georef.origin.h);
        const CahvorModel& camera = f.images[static_cast<size_t>(id)].camera_in_site;
        const std::optional<Eigen::Vector2d> pixel = camera.Project(truth_in_site);
        const cv::Mat& seen_range = f.ranges[static_cast<size_t>(id)];
        if (!pixel || pixel->x() < 0 || pixel->y() < 0 || pixel->x() > seen_range.cols - 1 ||
            pixel->y() > seen_range.rows - 1) {
          continue;
        }
        const float seen = seen_range.at<float>(static_cast<int>(std::lround(pixel->y())),
                                                static_cast<int>(std::lround(pixel->x())));
        const double range = (truth_in_site - camera.c).norm();
        if (range - seen > 0.05 + 0.01 * range) {
          ++wrong;
        }
      }
    }
    return std::make_pair(wrong, ortho.valid_cells);
  };
  const auto [wrong, valid] = occluded_painted(OrthoOptions{});
  OrthoOptions no_depth_test;
  no_depth_test.depth_tolerance_m = 1e6;
  const auto [wrong_without, valid_without] = occluded_painted(no_depth_test);
  std::printf("occluded cells painted: %d of %d with the depth test, %d of %d without\n", wrong,
              valid, wrong_without, valid_without);
  // What remains is the 10 cm DTM's discretisation of rocks and ridges at grazing incidence.
  EXPECT_LT(wrong, valid / 20);
  EXPECT_GT(wrong_without, 3 * wrong);
}

TEST(Orthophoto, ResolutionGrowsWithRangeAndLayersAgree) {
  const OrthoFixture& f = Fixture();
  const Orthophoto ortho = MakeOrthophoto(f.dtm, f.site, f.map, f.images, OrthoOptions{});
  const double focal = f.images[0].camera_in_site.FocalLengths().x();
  for (int row = 0; row < ortho.grid.height; row += 13) {
    for (int col = 0; col < ortho.grid.width; col += 13) {
      const bool valid = ortho.valid.at<uint8_t>(row, col) != 0;
      EXPECT_EQ(valid, std::isfinite(ortho.image.at<float>(row, col)));
      EXPECT_EQ(valid, ortho.source_id.at<int32_t>(row, col) >= 0);
      if (!valid) continue;
      // Footprint >= range / f (normal incidence), range >= 1.5 m mast height.
      EXPECT_GE(ortho.resolution.at<float>(row, col), 1.5 / focal);
    }
  }
  testing::TempDir dir;
  WriteOrthophoto(dir.path() / "ortho.tif", ortho);
  const RasterDataset dataset = RasterDataset::Open(dir.path() / "ortho.tif");
  EXPECT_EQ(dataset.info().band_count, 4);
  EXPECT_TRUE(Crs::FromWkt(dataset.info().crs_wkt, "ortho.tif").Describe().is_mars);
}

// A MER rover works tens of metres from its site's origin: the same cameras in a site frame whose
// origin lies 50 m away paint the same cells (the window follows the cameras, not the origin).
TEST(Orthophoto, CamerasFarFromTheSiteOriginPaintTheSameCells) {
  const OrthoFixture& f = Fixture();
  const Orthophoto near = MakeOrthophoto(f.dtm, f.site, f.map, f.images, OrthoOptions{});
  const Eigen::Vector3d rover_in_site(40.0, 30.0, 0.0);  // north, east, down [m]
  SiteGeoreference far_site = f.site;
  far_site.mbf_from_site =
      f.site.mbf_from_site * Rigid3d(Eigen::Quaterniond::Identity(), -rover_in_site);
  std::vector<OrthoSourceImage> far_images = f.images;
  for (OrthoSourceImage& image : far_images) {
    image.camera_in_site =
        image.camera_in_site.Transformed(Rigid3d(Eigen::Quaterniond::Identity(), rover_in_site));
  }
  const Orthophoto far = MakeOrthophoto(f.dtm, far_site, f.map, far_images, OrthoOptions{});
  ASSERT_GT(near.valid_cells, 10000);
  EXPECT_NEAR(far.valid_cells, near.valid_cells, 0.001 * near.valid_cells);
  EXPECT_NEAR(far.grid.x_left, near.grid.x_left, 1e-6);
  EXPECT_NEAR(far.grid.y_top, near.grid.y_top, 1e-6);
  EXPECT_EQ(far.grid.width, near.grid.width);
  EXPECT_EQ(far.grid.height, near.grid.height);
}

TEST(Orthophoto, RejectsBadInput) {
  const OrthoFixture& f = Fixture();
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MakeOrthophoto(f.dtm, f.site, f.map, {}, OrthoOptions{});
            }).find("no images"),
            std::string::npos);
  std::vector<OrthoSourceImage> color = {f.images[0]};
  color[0].id = 7;
  cv::cvtColor(f.images[0].image, color[0].image, cv::COLOR_GRAY2BGR);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MakeOrthophoto(f.dtm, f.site, f.map, color, OrthoOptions{});
            }).find("image 7: expected a single-channel image"),
            std::string::npos);
  OrthoOptions bad;
  bad.max_incidence_deg = 90.0;
  EXPECT_NE(testing::ErrorMessageOf([&] { bad.Check(); }).find("OrthoOptions.max_incidence_deg"),
            std::string::npos);
  // A DTM has four bands too, but it is not an orthophoto to read or blend; the orthophoto itself
  // reads back.
  testing::TempDir dir;
  WriteDtm(dir.path() / "dtm.tif", f.dtm);
  EXPECT_NE(testing::ErrorMessageOf([&] { ReadOrthophoto(dir.path() / "dtm.tif"); })
                .find("dtm.tif: expected an areomap orthophoto (bands image, valid, resolution_m, "
                      "source_id); band 1 is 'elevation'"),
            std::string::npos);
  const Orthophoto ortho = MakeOrthophoto(f.dtm, f.site, f.map, {f.images[0]}, OrthoOptions{});
  WriteOrthophoto(dir.path() / "ortho.tif", ortho);
  EXPECT_EQ(ReadOrthophoto(dir.path() / "ortho.tif").valid_cells, ortho.valid_cells);
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

// Large rasters are read by window: the DTM only within reach of the cameras, an orthophoto only
// over its painted cells; each window read equals that crop of the whole read.
TEST(Orthophoto, ReadsOnlyTheWindowsItNeeds) {
  const OrthoFixture& f = Fixture();
  testing::TempDir dir;
  WriteDtm(dir.path() / "dtm.tif", f.dtm);
  const std::optional<GridSpec> reach =
      OrthophotoWindow(f.dtm.layers.grid, f.site, f.map, {f.images[0]}, OrthoOptions{});
  ASSERT_TRUE(reach.has_value());
  const Dtm part = ReadDtm(dir.path() / "dtm.tif", *reach);
  const Eigen::Vector2i at = reach->OffsetIn(f.dtm.layers.grid);
  const cv::Rect crop(at.x(), at.y(), reach->width, reach->height);
  cv::Mat got = part.layers.elevation.clone(), want = f.dtm.layers.elevation(crop).clone();
  cv::patchNaNs(got, -1e9);
  cv::patchNaNs(want, -1e9);
  EXPECT_EQ(cv::norm(got, want, cv::NORM_INF), 0.0);
  // The orthophoto from the window equals the one from the whole DTM.
  const Orthophoto whole = MakeOrthophoto(f.dtm, f.site, f.map, {f.images[0]}, OrthoOptions{});
  const Orthophoto windowed = MakeOrthophoto(part, f.site, f.map, {f.images[0]}, OrthoOptions{});
  EXPECT_EQ(windowed.valid_cells, whole.valid_cells);
  EXPECT_EQ(windowed.grid.width, whole.grid.width);
  EXPECT_NEAR(windowed.grid.x_left, whole.grid.x_left, 1e-9);
  // A window off the DTM's grid is an error naming the file.
  GridSpec shifted = *reach;
  shifted.x_left += 0.37 * shifted.posting;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              ReadDtm(dir.path() / "dtm.tif", shifted);
            }).find("dtm.tif: the window asked for is not a window of the DTM's grid"),
            std::string::npos);

  // The painted cells' window of the orthophoto, and the read over it.
  WriteOrthophoto(dir.path() / "ortho.tif", whole);
  const std::optional<GridSpec> painted = OrthophotoValidWindow(dir.path() / "ortho.tif");
  ASSERT_TRUE(painted.has_value());
  const Orthophoto read = ReadOrthophoto(dir.path() / "ortho.tif", *painted);
  EXPECT_EQ(read.valid_cells, whole.valid_cells);
  EXPECT_LE(painted->width, whole.grid.width);
  const Eigen::Vector2i p = painted->OffsetIn(whole.grid);
  const cv::Mat inside = whole.valid(cv::Rect(p.x(), p.y(), painted->width, painted->height));
  EXPECT_EQ(cv::countNonZero(inside), whole.valid_cells);
  // Its edge rows and columns hold painted cells (the window is the smallest).
  EXPECT_GT(cv::countNonZero(read.valid.row(0)), 0);
  EXPECT_GT(cv::countNonZero(read.valid.col(read.valid.cols - 1)), 0);
  // An orthophoto with no painted cell has no window.
  Orthophoto blank = whole;
  blank.valid.setTo(0);
  blank.valid_cells = 0;
  WriteOrthophoto(dir.path() / "blank.tif", blank);
  EXPECT_FALSE(OrthophotoValidWindow(dir.path() / "blank.tif").has_value());
}

}  // namespace
}  // namespace areomap
