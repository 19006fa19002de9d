#include "areomap/map/site_georeference.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "areomap/samples/orbital.h"
#include "test_support.h"

namespace areomap {
namespace {

const Geographic kGusev{RadFromDeg(-14.5692), RadFromDeg(175.4729), -1920.0};

TEST(SiteGeoreference, AtOriginPutsTheSiteOriginThere) {
  const SiteGeoreference site = SiteGeoreference::AtOrigin(Body::Mars2000(), kGusev);
  const Geographic origin = site.Origin();
  EXPECT_NEAR(origin.lat, kGusev.lat, 1e-12);
  EXPECT_NEAR(origin.lon, kGusev.lon, 1e-12);
  EXPECT_NEAR(origin.h, kGusev.h, 1e-6);
  // z down: a point 10 m below the origin in the site frame is 10 m lower.
  const Geographic below =
      GeographicFromMbf(site.body, site.mbf_from_site * Eigen::Vector3d(0.0, 0.0, 10.0));
  EXPECT_NEAR(below.h, kGusev.h - 10.0, 1e-6);
}

TEST(SiteGeoreference, SiteInMissionIsDisplacedByItsPose) {
  const Body body = Body::Mars2000();
  // Site 3 lies 30 m north, 40 m east and 2 m lower than the mission origin.
  const Rigid3d mission_from_site(Eigen::Quaterniond::Identity(), Eigen::Vector3d(30, 40, 2));
  const SiteGeoreference site = SiteGeoreference::InMission(body, kGusev, mission_from_site);
  const Eigen::Vector3d mission_origin = MbfFromGeographic(body, kGusev);
  EXPECT_NEAR((site.mbf_from_site.translation - mission_origin).norm(), std::sqrt(2504.0), 1e-3);
  // The local ENU frame of the origin sees the site 40 m east, 30 m north and 2 m down.
  const Eigen::Vector3d enu = EnuFromMbf(body, kGusev) * site.mbf_from_site.translation;
  EXPECT_NEAR(enu.x(), 40.0, 1e-6);
  EXPECT_NEAR(enu.y(), 30.0, 1e-6);
  EXPECT_NEAR(enu.z(), -2.0, 1e-6);
}

// A point of the generator's scene, through a site frame and our local map, lands where the
// generator's orbital products put it (their pixel -> ENU mapping, orbital.cc), within 1 mm.
TEST(MapFrame, LocalMapOverlaysTheGeneratorsOrbitalProducts) {
  SceneGeoreference scene_georef;
  scene_georef.origin = kGusev;
  const Body body = scene_georef.body;
  const MapFrame map = MapFrame::LocalEquirectangular(body, kGusev);
  const MapProjection orbital = scene_georef.Projection();
  EXPECT_EQ(map.Wkt(), orbital.Wkt());
  const Rigid3d enu_from_mbf = scene_georef.EnuFromMbf();
  const Eigen::Vector3d site_in_enu(-35.0, 60.0, 1.7);  // Site origin, ENU [m].
  const Rigid3d mission_from_site(Eigen::Quaterniond::Identity(), SiteFromEnu() * site_in_enu);
  const SiteGeoreference site = SiteGeoreference::InMission(body, kGusev, mission_from_site);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-200.0, 200.0), dz(-5.0, 5.0);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d point_in_enu(u(rng), u(rng), dz(rng));
    const Eigen::Vector3d p_in_site = SiteFromEnu() * (point_in_enu - site_in_enu);
    const Eigen::Vector3d on_map = map.MapFromMbf(site.mbf_from_site * p_in_site);
    // The generator: map (x, y) -> radial line at the height -> ENU.
    const Geographic g = orbital.Inverse(on_map.head<2>());
    const Eigen::Vector3d back = enu_from_mbf * MbfOnRadialLine(body, g.lat, g.lon, on_map.z());
    EXPECT_NEAR(back.x(), point_in_enu.x(), 1e-3);
    EXPECT_NEAR(back.y(), point_in_enu.y(), 1e-3);
    // The ENU plane rises above the ellipsoid by d^2 / 2R with the distance d from its origin.
    const double curvature = point_in_enu.head<2>().squaredNorm() / (2.0 * body.a);
    EXPECT_NEAR(on_map.z(), kGusev.h + point_in_enu.z() + curvature, 2e-4);
  }
}

TEST(MapFrame, MbfFromMapInvertsMapFromMbf) {
  const Body body = Body::Mars2000();
  const MapFrame local = MapFrame::LocalEquirectangular(body, kGusev);
  const MapFrame crs = MapFrame::FromCrs(body, Crs::FromUserInput("IAU_2015:49912"));
  const SiteGeoreference site = SiteGeoreference::AtOrigin(body, kGusev);
  for (const MapFrame* map : {&local, &crs}) {
    for (const Eigen::Vector3d& p_in_site :
         {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(20, -15, 1.5),
          Eigen::Vector3d(-300, 250, -8)}) {
      const Eigen::Vector3d p = site.mbf_from_site * p_in_site;
      EXPECT_LT((map->MbfFromMap(map->MapFromMbf(p)) - p).norm(), 1e-5);
    }
  }
}

// PROJ's IAU_2015:49910 is x = R lon, y = R lat on the IAU sphere (R = 3396190 m).
TEST(MapFrame, CrsOnRequestFollowsProj) {
  const Body body = Body::Mars2000();
  const MapFrame map = MapFrame::FromCrs(body, Crs::FromUserInput("IAU_2015:49910"));
  const SiteGeoreference site = SiteGeoreference::AtOrigin(body, kGusev);
  const Eigen::Vector3d p = site.mbf_from_site * Eigen::Vector3d(12.0, -7.0, 0.5);
  const Spherical s = SphericalFromMbf(p);
  const Eigen::Vector3d on_map = map.MapFromMbf(p);
  EXPECT_NEAR(on_map.x(), 3396190.0 * s.lon, 1e-3);
  EXPECT_NEAR(on_map.y(), 3396190.0 * s.lat, 1e-3);
  EXPECT_NEAR(on_map.z(), kGusev.h - 0.5, 1e-3);
}

TEST(MapFrame, RejectsGeographicAndNonMarsCrs) {
  const Body body = Body::Mars2000();
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MapFrame::FromCrs(body, Crs::FromUserInput("IAU_2015:49900"));
            }).find("projected CRS"),
            std::string::npos);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MapFrame::FromCrs(body, Crs::FromUserInput("EPSG:32633"));
            }).find("not on Mars"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap
