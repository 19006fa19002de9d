// Real texture: crops of a real MOC narrow-angle orthoimage (../shared/data/moc, sinusoidal,
// 4.68 m/px) warped with known shifts and small rotations, under another illumination, with
// nodata holes, stand in for the rover orthophoto; the full image is the orbital image.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_match.h"
#include "test_support.h"

namespace areomap {
namespace {

struct WarpedCrop {
  OrthoImage ortho;
  OrbitalPrior prior;
  Eigen::Vector2d true_centre_px;  // Orbital pixel the ortho's centre truly shows.
  Eigen::Vector2d true_corner_px;  // ... and its top-left corner.
};

// An ortho of `size` px at half the MOC's pixel size, centred (telemetry) on orbital pixel
// `centre`, truly showing the ground `error_px` away and turned by `rotation_deg`.
WarpedCrop MakeWarpedCrop(const std::filesystem::path& path, const Eigen::Vector2d& centre,
                          const Eigen::Vector2d& error_px, double rotation_deg, uint32_t seed) {
  const RasterDataset dataset = RasterDataset::Open(path);
  const cv::Mat image = dataset.ReadWindowFloat(1, dataset.FullWindow());
  const GeoTransform& gt = *dataset.info().geotransform;
  constexpr int kSize = 160;
  constexpr double kScale = 0.5;  // Ortho pixel / orbital pixel.
  const double t = rotation_deg * std::numbers::pi / 180.0;
  // Telemetry: ortho pixel p -> orbital pixel centre + kScale (p - c). Truth: the same turned
  // by t (counter-clockwise on the map = clockwise in pixel axes) and moved by -error.
  Eigen::Matrix2d rot;
  rot << std::cos(t), std::sin(t), -std::sin(t), std::cos(t);
  const Eigen::Vector2d c(kSize / 2.0, kSize / 2.0);
  const auto truth = [&](const Eigen::Vector2d& p) {
    return centre - error_px + kScale * rot * (p - c);
  };
  cv::Mat map_x(kSize, kSize, CV_32F), map_y(kSize, kSize, CV_32F);
  for (int r = 0; r < kSize; ++r) {
    for (int col = 0; col < kSize; ++col) {
      const Eigen::Vector2d q = truth({col + 0.5, r + 0.5});
      map_x.at<float>(r, col) = static_cast<float>(q.x() - 0.5);
      map_y.at<float>(r, col) = static_cast<float>(q.y() - 0.5);
    }
  }
  WarpedCrop out;
  cv::remap(image, out.ortho.image, map_x, map_y, cv::INTER_CUBIC, cv::BORDER_CONSTANT,
            std::numeric_limits<float>::quiet_NaN());
  // Another illumination: gain, offset and a gamma; sensor noise; nodata holes.
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  for (int r = 0; r < kSize; ++r) {
    for (int col = 0; col < kSize; ++col) {
      float& v = out.ortho.image.at<float>(r, col);
      v = 2.0f * std::pow(v, 1.3f) + 0.05f + noise(rng);
    }
  }
  std::uniform_int_distribution<int> where(0, kSize - 1), radius(5, 14);
  for (int k = 0; k < 8; ++k) {
    cv::circle(out.ortho.image, {where(rng), where(rng)}, radius(rng),
               cv::Scalar(std::numeric_limits<float>::quiet_NaN()), cv::FILLED);
  }
  const Eigen::Vector2d origin_px = centre - kScale * c;
  const Eigen::Vector2d origin = gt.PixelToMap(origin_px.x(), origin_px.y());
  out.ortho.geotransform.c = {origin.x(), gt.c[1] * kScale, 0.0, origin.y(), 0.0, gt.c[5] * kScale};
  out.ortho.crs_wkt = dataset.info().crs_wkt;
  out.ortho.source = "moc_crop";
  const PixelGrid grid(out.ortho.geotransform, out.ortho.crs_wkt, "moc_crop");
  out.prior.position = *grid.PixelToGeographic(c);
  out.prior.sigma_m = 15.0 * 4.676;
  out.true_centre_px = truth(c);
  out.true_corner_px = truth({0.0, 0.0});
  return out;
}

TEST(OrbitalMatchMoc, RecoversWarpedCropsOfARealOrthoimage) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto path = areomap::testing::SharedDataDir() / "moc" / "E0201461.tiny.cub";
  const OrbitalImage orbital = OrbitalImage::Open(path);
  struct Case {
    Eigen::Vector2d centre, error;
    double rotation_deg;
  };
  const Case cases[] = {{{150.3, 210.8}, {7.3, -4.6}, 0.0},
                        {{320.0, 300.0}, {-11.2, 6.7}, 2.0},
                        {{250.5, 120.2}, {3.4, 12.1}, -3.0},
                        {{180.0, 360.0}, {-8.8, -9.9}, 1.0}};
  uint32_t seed = 1;
  for (const Case& k : cases) {
    SCOPED_TRACE(::testing::Message() << "centre " << k.centre.transpose() << ", error "
                                      << k.error.transpose() << ", rotation " << k.rotation_deg);
    const WarpedCrop crop = MakeWarpedCrop(path, k.centre, k.error, k.rotation_deg, seed++);
    OrbitalMatchOptions options;
    options.max_rotation_deg = 4.0;
    options.template_options.reliable_range_m = 0.0;
    const OrbitalMatch m = MatchOrthoToOrbital(crop.ortho, orbital, crop.prior, options);
    ASSERT_TRUE(m.matched) << m.BriefReport();
    // Template pixel of the ortho's centre and corner -> orbital pixel under the correction.
    const GridMapping to_orbital(PixelGrid(crop.ortho.geotransform, crop.ortho.crs_wkt, "crop"),
                                 PixelGrid(orbital.geotransform(), orbital.crs_wkt(), "moc"));
    const auto corrected = [&](const Eigen::Vector2d& ortho_px) {
      const Eigen::Vector2d telemetry = to_orbital.Apply(ortho_px);
      return m.TemplateToOrbital(telemetry - Eigen::Vector2d(m.templ.col0, m.templ.row0));
    };
    const double centre_error = (corrected({80.0, 80.0}) - crop.true_centre_px).norm();
    const double corner_error = (corrected({0.0, 0.0}) - crop.true_corner_px).norm();
    std::printf("MOC crop: error %.3f px at the centre, %.3f px at the corner; %s\n", centre_error,
                corner_error, m.BriefReport().c_str());
    EXPECT_LE(centre_error, 0.5) << m.BriefReport();
    EXPECT_LE(corner_error, 0.5) << m.BriefReport();
    EXPECT_NEAR(m.rotation_rad * 180.0 / std::numbers::pi, k.rotation_deg, 0.5);
  }
}

}  // namespace
}  // namespace areomap
