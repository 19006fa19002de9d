#include "areomap/samples/mission.h"

#include <fstream>
#include <functional>
#include <numeric>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/coordinate_system.h"
#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/pds_label.h"
#include "areomap/map/raster_description.h"
#include "test_support.h"

namespace areomap {
namespace {

double Std(const std::vector<double>& v) {
  const double mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  double sum = 0.0;
  for (double x : v) sum += (x - mean) * (x - mean);
  return std::sqrt(sum / static_cast<double>(v.size() - 1));
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// A small, fast mission: 60 m square, two known craters, no background relief.
MissionOptions SmallMission() {
  MissionOptions o = MissionOptions::Preset("demo");
  o.scene.half_extent_m = 40.0;
  o.scene.crater_count = 0;
  o.scene.roughness_m = 0.0;
  Crater bowl;
  bowl.center = {-15.0, 12.0};
  bowl.semi_major = 8.0;
  bowl.semi_minor = 6.5;
  bowl.angle = 0.6;
  bowl.depth = 3.0;
  bowl.rim_height = 0.6;
  Crater flat = bowl;
  flat.center = {18.0, -16.0};
  flat.semi_major = 7.0;
  flat.semi_minor = 7.0;
  flat.flat_floor = true;
  flat.floor_fraction = 0.4;
  o.scene.explicit_craters = {bowl, flat};
  o.traverse.site_count = 3;
  o.traverse.min_leg_m = 8.0;
  o.traverse.max_leg_m = 10.0;
  o.navcam_pairs = 1;
  o.navcam.width = 256;
  o.navcam.height = 256;
  o.navcam.field_of_view_deg = 45.0;
  o.pancam_pairs = 1;
  o.pancam.width = 256;
  o.pancam.height = 256;
  o.render.near_radius_m = 2.0;  // Keep the test quick: small fine rings.
  o.render.mid_radius_m = 8.0;
  return o;
}

TEST(Traverse, TelemetryErrorsFollowTheModel) {
  TraverseOptions options;
  options.site_count = 1000;
  const TelemetryErrorModel model;  // 5 % scale, 2 deg drift per leg.
  const Traverse t = PlanTraverse(options, model, 5000.0, 7);
  ASSERT_EQ(t.leg_scale_errors.size(), 999u);
  // Sample std of 999 normal draws: relative standard error 1/sqrt(2 * 998) = 2.2 %; allow 3.2 SE.
  EXPECT_NEAR(Std(t.leg_scale_errors), model.scale_sigma, 0.07 * model.scale_sigma);
  EXPECT_NEAR(Std(t.leg_heading_errors), RadFromDeg(model.heading_drift_sigma_deg),
              0.07 * RadFromDeg(model.heading_drift_sigma_deg));
  // Legs respect the requested lengths and the traverse stays inside the scene.
  for (size_t i = 1; i < t.truth.size(); ++i) {
    const double leg = (t.truth[i].position - t.truth[i - 1].position).norm();
    EXPECT_GE(leg, options.min_leg_m - 1e-9);
    EXPECT_LE(leg, options.max_leg_m + 1e-9);
    EXPECT_LE(t.truth[i].position.head<2>().cwiseAbs().maxCoeff(), 5000.0);
  }
}

TEST(Traverse, RebuildsTelemetryLegsFromTheRecordedErrors) {
  const Traverse t = PlanTraverse(TraverseOptions{}, TelemetryErrorModel{}, 200.0, 3);
  double heading_error = 0.0;
  for (size_t i = 1; i < t.truth.size(); ++i) {
    heading_error += t.leg_heading_errors[i - 1];
    const Eigen::Vector2d truth_leg = (t.truth[i].position - t.truth[i - 1].position).head<2>();
    const Eigen::Vector2d measured =
        (t.telemetry[i].position - t.telemetry[i - 1].position).head<2>();
    // (north, east): a clockwise heading error is a rotation by +error in this frame.
    const Eigen::Vector2d expected =
        (1.0 + t.leg_scale_errors[i - 1]) * (Eigen::Rotation2Dd(heading_error) * truth_leg);
    EXPECT_LT((measured - expected).norm(), 1e-9) << i;
  }
}

TEST(Scene, RockPeaksAreTheTrueMaxima) {
  SceneOptions options;
  options.half_extent_m = 30.0;
  options.rock_path = {{-10.0, 0.0}, {10.0, 0.0}};
  options.rock_corridor_m = 6.0;
  options.rock_max_tilt_deg = 0.0;  // Upright: the peak is above the centre.
  const Scene scene(options);
  ASSERT_GT(scene.rocks().size(), 50u);
  int checked = 0;
  for (const Rock& r : scene.rocks()) {
    // Skip rocks overlapped by a neighbour: their top may be someone else's.
    bool alone = true;
    for (const Rock& o : scene.rocks()) {
      if (o.id != r.id &&
          (o.center - r.center).norm() < r.FootprintRadius() + o.FootprintRadius()) {
        alone = false;
      }
    }
    if (!alone) continue;
    const double peak = scene.HeightAt(r.center.x(), r.center.y());
    EXPECT_NEAR(peak, r.ground_z + r.height, 1e-9) << r.id;
    // Nowhere within the footprint is higher than the peak (the ground is nearly flat here).
    for (double dx = -r.a; dx <= r.a; dx += r.a / 5.0) {
      for (double dy = -r.a; dy <= r.a; dy += r.a / 5.0) {
        EXPECT_LE(scene.HeightAt(r.center.x() + dx, r.center.y() + dy), peak + 0.02) << r.id;
      }
    }
    ++checked;
  }
  EXPECT_GT(checked, 20);
}

TEST(Scene, RockSizesFollowGolombekRapp) {
  SceneOptions options;
  options.half_extent_m = 200.0;
  options.rock_path = {{-150.0, 0.0}, {150.0, 0.0}};
  options.rock_corridor_m = 40.0;
  options.rock_min_diameter_m = 0.2;
  options.rock_max_diameter_m = 2.0;
  options.max_rocks = 1000000;
  const Scene scene(options);
  // Cumulative fractional area of rocks with D >= 0.5 m over the corridor, against
  // F(0.5) - F(2.0) of the model; Poisson scatter of ~100s of rocks gives ~10 %.
  const double k = options.rock_abundance_k, q = 1.79 + 0.152 / k;
  double area = 0.0;
  for (const Rock& r : scene.rocks()) {
    if (2.0 * r.a >= 0.5) area += std::numbers::pi * r.a * r.a;
  }
  const double corridor = 300.0 * 80.0 + std::numbers::pi * 40.0 * 40.0;
  const double expected = k * (std::exp(-q * 0.5) - std::exp(-q * 2.0));
  EXPECT_NEAR(area / corridor, expected, 0.2 * expected);
}

TEST(Scene, RocksBeyondMaxRocksAreAnErrorNotAThinnedField) {
  SceneOptions options;
  options.half_extent_m = 60.0;
  options.rock_path = {{-30.0, 0.0}, {30.0, 0.0}};
  options.rock_corridor_m = 10.0;
  options.crater_count = 0;
  options.rock_abundance_k = 0.2;  // ~2.5 rocks per m^2 from 12 cm: ~3 800 in the corridor.
  options.max_rocks = 500;
  try {
    const Scene scene(options);
    FAIL() << "expected an error, got " << scene.rocks().size() << " rocks";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("SceneOptions.max_rocks"), std::string::npos) << e.what();
  }
  options.max_rocks = 100000;
  const Scene scene(options);
  EXPECT_GT(scene.rocks().size(), 2000u);
}

// Whether a scene with `options` is refused with an error naming `field`.
bool RefusedNaming(const SceneOptions& options, const std::string& field) {
  try {
    const Scene scene(options);
  } catch (const Error& e) {
    return std::string(e.what()).find(field) != std::string::npos;
  }
  return false;
}

// Fresh craters have d/D >= 0.15. Degraded ones may be as shallow as (1 - max) of that, keep their
// rims below their depths, and the strongly degraded have filled (flat) floors.
TEST(Scene, DegradedCratersAreShallowerWithLowerRimsAndFilledFloors) {
  SceneOptions options;
  options.crater_count = 60;
  options.crater_min_diameter_m = 10.0;
  options.crater_max_diameter_m = 40.0;
  const Scene fresh(options);
  const auto depth_ratio = [](const Crater& c) { return c.depth / (2.0 * c.semi_major); };
  for (const Crater& c : fresh.craters()) EXPECT_GE(depth_ratio(c), 0.15 - 1e-12);
  options.crater_max_degradation = 0.85;
  const Scene old(options);
  int shallow = 0, filled = 0;
  for (const Crater& c : old.craters()) {
    EXPECT_GT(c.depth, c.rim_height);
    EXPECT_GE(depth_ratio(c), 0.15 * (1.0 - 0.85) - 1e-12);
    if (depth_ratio(c) < 0.1) ++shallow;
    if (c.flat_floor && c.floor_fraction > 0.5) ++filled;
  }
  EXPECT_GE(shallow, 10);
  EXPECT_GE(filled, 5);
  options.crater_max_degradation = 0.95;
  EXPECT_TRUE(RefusedNaming(options, "SceneOptions.crater_max_degradation"));
}

TEST(Scene, CraterSpacingUnderOneLetsCratersOverlap) {
  SceneOptions options;
  options.half_extent_m = 100.0;
  options.crater_count = 40;
  options.crater_min_diameter_m = 20.0;
  options.crater_max_diameter_m = 40.0;
  const auto overlapping_pairs = [](const Scene& scene) {
    int n = 0;
    const std::vector<Crater>& c = scene.craters();
    for (size_t i = 0; i < c.size(); ++i) {
      for (size_t j = i + 1; j < c.size(); ++j) {
        if ((c[i].center - c[j].center).norm() < c[i].semi_major + c[j].semi_major) ++n;
      }
    }
    return n;
  };
  EXPECT_EQ(overlapping_pairs(Scene(options)), 0);
  options.crater_min_spacing = 0.6;
  EXPECT_GT(overlapping_pairs(Scene(options)), 0);
  options.crater_min_spacing = 0.4;
  EXPECT_TRUE(RefusedNaming(options, "SceneOptions.crater_min_spacing"));
}

TEST(Mission, CraterRimsInTheOrbitalDtmLieOnTheTrueEllipses) {
  testing::TempDir dir;
  const MissionOptions options = SmallMission();
  GenerateMission(options, dir.path());
  const RasterDataset dtm = RasterDataset::Open(dir.path() / "orbital/hirise_dtm.tif");
  const cv::Mat z = dtm.ReadWindowFloat(1, dtm.FullWindow());
  const GeoTransform& t = *dtm.info().geotransform;
  // craters.csv gives each centre in orbital image pixels (0.25 m); the DTM posting is 1 m.
  std::istringstream csv(ReadFile(dir.path() / "truth/craters.csv"));
  std::string line;
  std::getline(csv, line);
  int checked = 0;
  while (std::getline(csv, line)) {
    std::vector<double> v;
    std::stringstream fields(line);
    std::string cell;
    while (std::getline(fields, cell, ',')) v.push_back(std::stod(cell));
    const double col = v[5] / 4.0, row = v[6] / 4.0;  // Centre in DTM pixels.
    const double a = v[7], b = v[8], angle = RadFromDeg(v[9]);
    for (int k = 0; k < 36; ++k) {
      const double theta = 2.0 * std::numbers::pi * k / 36.0;  // From east toward north.
      const double u = std::cos(theta - angle), w = std::sin(theta - angle);
      const double r_true = 1.0 / std::sqrt(u * u / (a * a) + w * w / (b * b));
      double best_r = 0.0, best_z = -1e9;
      for (double r = 0.5 * r_true; r <= 1.5 * r_true; r += 0.05) {
        const double c = col + r * std::cos(theta) / t.c[1];
        const double rr = row + r * std::sin(theta) / t.c[5];  // c[5] < 0: north is up.
        cv::Mat sample;
        cv::getRectSubPix(z, cv::Size(1, 1),
                          cv::Point2f(static_cast<float>(c - 0.5), static_cast<float>(rr - 0.5)),
                          sample);
        if (sample.at<float>(0, 0) > best_z) {
          best_z = sample.at<float>(0, 0);
          best_r = r;
        }
      }
      // The rim crest is found within one DTM posting of the true ellipse.
      EXPECT_NEAR(best_r, r_true, 1.0) << "crater " << v[0] << " direction " << k;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 2);
}

TEST(Mission, SameSeedGivesByteIdenticalFiles) {
  testing::TempDir a, b;
  MissionOptions options = SmallMission();
  GenerateMission(options, a.path());
  GenerateMission(options, b.path());
  int compared = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(a.path())) {
    if (!entry.is_regular_file()) continue;
    const auto relative = std::filesystem::relative(entry.path(), a.path());
    EXPECT_EQ(ReadFile(entry.path()), ReadFile(b.path() / relative)) << relative;
    ++compared;
  }
  EXPECT_GE(compared, 7);
}

TEST(Mission, OrbitalProductsAreGeoreferencedAtTheSite) {
  testing::TempDir dir;
  const MissionOptions options = SmallMission();
  GenerateMission(options, dir.path());
  for (const char* file : {"orbital/hirise_ortho.tif", "orbital/hirise_dtm.tif"}) {
    const RasterDescription d = DescribeRaster(dir.path() / file);
    ASSERT_TRUE(d.crs.has_value()) << file;
    EXPECT_TRUE(d.crs->is_mars);
    const CornerCoordinate& centre = d.corners.back();
    // The map's latitude is that of the radial line through the site, which differs from the
    // site's foot-point latitude by h (lat_g - lat_c) = 5.5 m here (see MbfOnRadialLine); the
    // exact check is the pixel test below.
    EXPECT_NEAR(DegFromRad(centre.planetocentric->lat), options.site_lat_deg, 1.2e-4) << file;
    EXPECT_NEAR(DegFromRad(centre.planetocentric->lon), options.site_lon_deg, 1e-6) << file;
  }
  const RasterDataset image = RasterDataset::Open(dir.path() / "orbital/hirise_ortho.tif");
  EXPECT_EQ(image.info().data_type, "UInt16");
  // Site 0 (the ENU origin, on the ground) falls on the image centre through the file's own CRS,
  // as it would in a GIS: the radial-line convention of map-projected pixels is honoured.
  std::istringstream sites(ReadFile(dir.path() / "truth/sites.csv"));
  std::string header, site0;
  std::getline(sites, header);
  std::getline(sites, site0);
  std::vector<double> v;
  std::stringstream fields(site0);
  for (std::string cell; std::getline(fields, cell, ',');) v.push_back(std::stod(cell));
  const CoordinateSystemContext context;
  const auto pixel = CoordinateSystem::Parse(
      "pixel:" + (dir.path() / "orbital/hirise_ortho.tif").string(), context);
  const auto ocentric = CoordinateSystem::Parse("planetocentric", context);
  const Eigen::Vector3d at = pixel.FromMbf(ocentric.ToMbf({v[5], v[6], v[7]}));
  EXPECT_NEAR(at.x(), image.info().width / 2.0, 0.01);
  EXPECT_NEAR(at.y(), image.info().height / 2.0, 0.01);
  double min_dn = 0.0, max_dn = 0.0;
  cv::minMaxLoc(image.ReadWindow(1, image.FullWindow()), &min_dn, &max_dn);
  EXPECT_LE(max_dn, 1023.0);  // 10-bit.
  EXPECT_GT(max_dn - min_dn, 100.0);
}

TEST(Mission, ManifestListsEachSitesStereoImagesWithReadableLabels) {
  testing::TempDir dir;
  const MissionOptions options = SmallMission();
  const MissionSummary summary = GenerateMission(options, dir.path());
  EXPECT_EQ(summary.rover_images,
            2 * (options.navcam_pairs + options.pancam_pairs) * options.traverse.site_count);
  const nlohmann::json manifest = nlohmann::json::parse(ReadFile(dir.path() / "mission.json"));
  ASSERT_EQ(manifest.at("sites").size(), static_cast<size_t>(options.traverse.site_count));
  for (const auto& site : manifest.at("sites")) {
    ASSERT_EQ(site.at("images").size(), 4u);  // Navcam and Pancam, left and right.
    EXPECT_EQ(site.at("images").at(2).at("instrument"), "PANCAM_LEFT");
    for (const auto& image : site.at("images")) {
      const auto label_path = dir.path() / image.at("label").get<std::string>();
      const ProductGeometry geometry =
          ParseProductGeometry(nlohmann::json::parse(ReadFile(label_path)), label_path.string());
      ASSERT_TRUE(geometry.camera.has_value());
      EXPECT_EQ(geometry.camera->model_type, "CAHVOR");
      EXPECT_EQ(geometry.frames.at(0).index.at(0), site.at("site").get<int>());
      const cv::Mat pixels = ReadImage(dir.path() / image.at("image").get<std::string>());
      EXPECT_EQ(pixels.type(), CV_16UC1);
      EXPECT_EQ(pixels.cols, 256);
      double max_dn = 0.0;
      cv::minMaxLoc(pixels, nullptr, &max_dn);
      EXPECT_LE(max_dn, 4095.0);  // 12-bit (Table 1.1).
    }
  }
}

TEST(Mission, LandingSitesAreGusevAndMeridiani) {
  EXPECT_NEAR(LandingSite("gusev").first, -14.5692, 1e-9);
  EXPECT_NEAR(LandingSite("meridiani").second, 354.4734, 1e-9);
  EXPECT_NE(testing::ErrorMessageOf([] { LandingSite("jezero"); }).find("gusev or meridiani"),
            std::string::npos);
}

TEST(Mission, BadOptionsAreNamed) {
  EXPECT_THROW(MissionOptions::Preset("huge"), Error);
  MissionOptions options = MissionOptions::Preset("demo");
  options.traverse.min_leg_m = -5.0;
  try {
    options.Check();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("TraverseOptions.min_leg_m"), std::string::npos);
  }
  options = MissionOptions::Preset("demo");
  EXPECT_THROW(GenerateMission(options, "/proc/areomap-unwritable"), Error);
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

TEST(MissionManifest, ReadsWhatTheGeneratorWrote) {
  testing::TempDir dir;
  const MissionOptions options = SmallMission();
  GenerateMission(options, dir.path());
  const MissionManifest mission = ReadMissionManifest(dir.path());
  ASSERT_EQ(mission.sites.size(), 3u);
  EXPECT_NEAR(DegFromRad(mission.origin.lat), options.site_lat_deg, 1e-12);
  for (const MissionSite& site : mission.sites) {
    ASSERT_EQ(site.pairs.size(), 2u);  // One Navcam and one Pancam pair.
    EXPECT_EQ(site.pairs[0].instrument, "NAVCAM");
    EXPECT_EQ(site.pairs[1].instrument, "PANCAM");
    EXPECT_TRUE(std::filesystem::exists(site.pairs[1].right_label));
  }
  ASSERT_EQ(mission.telemetry.size(), 3u);
  ASSERT_EQ(mission.truth_sites.size(), 3u);
  EXPECT_EQ(mission.truth_sites[0].position, Eigen::Vector3d::Zero());
  EXPECT_GT((mission.truth_sites[2].position - mission.telemetry[2].position).norm(), 0.0);
  ASSERT_NE(mission.FirstOrbital("image"), nullptr);
  EXPECT_TRUE(std::filesystem::exists(mission.FirstOrbital("dtm")->path));
  // Every file the manifest names, for the run's fingerprint: mission.json first.
  EXPECT_EQ(mission.files.front().filename(), "mission.json");
  for (const auto& file : mission.files) EXPECT_TRUE(std::filesystem::exists(file)) << file;
  EXPECT_GT(mission.files.size(), 2u + mission.orbital.size() + 3u * 2u * 4u - 1u);

  // An orbital product of an unknown kind is named with the value expected.
  {
    const auto manifest = dir.path() / "mission.json";
    std::string text;
    {
      std::ifstream in(manifest);
      text.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string good = text;
    const size_t at = text.find("\"kind\": \"dtm\"");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, 13, "\"kind\": \"xyz\"");
    std::ofstream(manifest) << text;
    const std::string kind_message =
        testing::ErrorMessageOf([&] { ReadMissionManifest(dir.path()); });
    EXPECT_NE(kind_message.find("].kind is \"xyz\"; expected \"image\" or \"dtm\""),
              std::string::npos)
        << kind_message;
    std::ofstream(manifest) << good;

    // A site listed twice is named as such, not as a site the telemetry lacks.
    nlohmann::json twice = nlohmann::json::parse(good);
    twice["sites"][2]["site"] = twice["sites"][0]["site"];
    std::ofstream(manifest) << twice.dump();
    const std::string twice_message =
        testing::ErrorMessageOf([&] { ReadMissionManifest(dir.path()); });
    EXPECT_NE(twice_message.find("sites[2].site 0 repeats sites[0]"), std::string::npos)
        << twice_message;
    std::ofstream(manifest) << good;
  }

  // A missing image is reported, naming the manifest and the file, before any work.
  std::filesystem::remove(mission.sites[1].pairs[0].left_image);
  const std::string message = testing::ErrorMessageOf([&] { ReadMissionManifest(dir.path()); });
  EXPECT_NE(message.find("mission.json"), std::string::npos) << message;
  EXPECT_NE(message.find("navcam_p00_left.png, which does not exist"), std::string::npos)
      << message;
}

// Values of the right JSON type but out of range, or of the wrong type, are named with the key
// and the rule, never read as something else (pair 1e20 as -2147483648, site 1.5 as 1).
TEST(MissionManifest, NamesTheKeyOfAnOutOfRangeOrMistypedValue) {
  testing::TempDir dir;
  MissionOptions options = SmallMission();
  options.navcam_pairs = 1;
  options.pancam_pairs = 0;
  options.traverse.site_count = 2;
  GenerateMission(options, dir.path());
  const auto manifest = dir.path() / "mission.json";
  nlohmann::json good;
  std::ifstream(manifest) >> good;
  const auto message_with = [&](const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json bad = good;
    edit(bad);
    std::ofstream(manifest) << bad.dump();
    return testing::ErrorMessageOf([&] { ReadMissionManifest(dir.path()); });
  };
  const std::vector<std::pair<std::function<void(nlohmann::json&)>, std::string>> cases = {
      {[](nlohmann::json& j) { j["orbital"][0]["sun_azimuth_deg"] = "east"; },
       "\"orbital[].sun_azimuth_deg\" is \"east\"; expected an azimuth in [-360, 360]"},
      {[](nlohmann::json& j) { j["body"]["a_m"] = 0; },
       "\"body.a_m\" is 0; expected a finite equatorial radius > 0 [m]"},
      {[](nlohmann::json& j) { j["sites"][0]["images"][0]["pair"] = 1e20; },
       "\"sites[0].images[].pair\" is 1e+20; expected an integer in [0, 65535]"},
      {[](nlohmann::json& j) { j["sites"][1]["site"] = 1.5; },
       "\"sites[].site\" is 1.5; expected an integer in [0, 999999]"},
      {[](nlohmann::json& j) { j["orbital"][0]["gsd_m"] = -1; },
       "\"orbital[].gsd_m\" is -1; expected a ground sample distance in (0, 1e6] m"},
      {[](nlohmann::json& j) { j["origin"]["h_m"] = 1e300; },
       "\"origin.h_m\" is 1e+300; expected a height in [-100000, 100000] m"},
      // Found by fuzz/mission_manifest_fuzzer: an object as "name" escaped as json::type_error.
      {[](nlohmann::json& j) {
         j["name"] = {{"a_m", 3396190.0}};
       },
       "\"name\" has the wrong type"},
  };
  for (const auto& [edit, expected] : cases) {
    const std::string message = message_with(edit);
    EXPECT_NE(message.find("mission.json: key " + expected), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace areomap
