#include "bundle_simulation.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "areomap/adjustment/traverse_priors.h"
#include "areomap/samples/rover.h"

namespace areomap::testing {
namespace {

// Smooth terrain height [m] at (north, east) in the traverse frame.
double TerrainHeight(double north, double east) {
  return 3.0 * std::sin(north / 80.0) + 2.0 * std::cos(east / 55.0) +
         1.5 * std::sin((north + east) / 37.0);
}

// Ground point at (north, east) in the traverse frame (z down from site 0's ground).
Eigen::Vector3d Ground(double north, double east) {
  return {north, east, -(TerrainHeight(north, east) - TerrainHeight(0.0, 0.0))};
}

Eigen::Vector3d Gaussian3(std::mt19937& rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double x = gauss(rng), y = gauss(rng), z = gauss(rng);
  return {x, y, z};
}

// A stereo measurement of the true point `p_in_site` and the covariance a stereo system would
// report for it (evaluated at the measured point, as it must be in practice).
std::pair<Eigen::Vector3d, Eigen::Matrix3d> MeasureStereo(const Eigen::Vector3d& p_in_site,
                                                          const SimulatedNetworkOptions& o,
                                                          std::mt19937& rng) {
  const Eigen::Vector3d camera(0.0, 0.0, -o.mast_height_m);
  const Eigen::Matrix3d truth_covariance = StereoPointCovariance(p_in_site, camera, o.stereo);
  const Eigen::Matrix3d l = truth_covariance.llt().matrixL();
  const Eigen::Vector3d measured = p_in_site + l * Gaussian3(rng);
  return {measured, StereoPointCovariance(measured, camera, o.stereo)};
}

// "<prefix><a>-<b>" ids (snprintf: GCC 12 warns falsely on chained std::string +).
std::string Id(char prefix, int a, int b, int c = -1) {
  char text[48];
  if (c < 0) {
    std::snprintf(text, sizeof(text), "%c%d-%d", prefix, a, b);
  } else {
    std::snprintf(text, sizeof(text), "%c%d-%d-%d", prefix, a, b, c);
  }
  return text;
}

// Pixels of `x_in_site` in the left and right cameras of the first panorama pair that sees it
// in both (inside the image), with noise; none if no pair does.
void AddPixelObservations(const std::string& landmark, int site, const Eigen::Vector3d& x_in_site,
                          double believed_heading, const SimulatedNetworkOptions& o,
                          std::mt19937& rng, BundleInput& input) {
  const StereoCameraOptions navcam;
  const Rigid3d site_from_rover(
      Eigen::Quaterniond(Eigen::AngleAxisd(believed_heading, Eigen::Vector3d::UnitZ())),
      Eigen::Vector3d::Zero());
  const std::vector<StereoPointing> pointings = Panorama(10, RadFromDeg(-25.0));
  std::normal_distribution<double> gauss(0.0, o.pixel_sigma_px);
  for (size_t p = 0; p < pointings.size(); ++p) {
    const std::array<CahvorModel, 2> cameras = StereoCameras(navcam, pointings[p]);
    std::array<Eigen::Vector2d, 2> pixels;
    bool seen = true;
    for (int side = 0; side < 2; ++side) {
      const std::optional<Eigen::Vector2d> pixel =
          cameras[side].Transformed(site_from_rover).Project(x_in_site);
      seen = seen && pixel && pixel->x() >= 0 && pixel->y() >= 0 &&
             pixel->x() <= navcam.width - 1 && pixel->y() <= navcam.height - 1;
      if (pixel) pixels[side] = *pixel;
    }
    if (!seen) continue;
    for (int side = 0; side < 2; ++side) {
      ImageObservation image;
      image.landmark_id = landmark;
      image.site = site;
      image.camera_in_site = cameras[side].Transformed(site_from_rover);
      const double dx = gauss(rng), dy = gauss(rng);
      image.pixel = pixels[side] + Eigen::Vector2d(dx, dy);
      image.sigma_px = o.pixel_sigma_px;
      char name[48];
      std::snprintf(name, sizeof(name), "s%03d_navcam_p%02zu_%s", site, p,
                    side == 0 ? "left" : "right");
      image.image = name;
      input.image_observations.push_back(image);
    }
    return;
  }
}

bool Excluded(const SimulatedNetworkOptions& o, int site) {
  for (int s : o.sites_without_links) {
    if (s == site) return true;
  }
  return false;
}

}  // namespace

SimulatedNetwork SimulateNetwork(const SimulatedNetworkOptions& o) {
  const Traverse traverse = PlanTraverse(o.traverse, o.telemetry, o.half_extent_m, o.seed);
  std::mt19937 rng(o.seed * 7717u + 13u);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  SimulatedNetwork net;
  BundleInput& input = net.input;
  input.origin = Geographic{RadFromDeg(-14.5692), RadFromDeg(175.4729), -1900.0};
  input.site_count = static_cast<int>(traverse.truth.size());
  for (size_t k = 0; k < traverse.truth.size(); ++k) {
    const Eigen::Vector3d& p = traverse.truth[k].position;
    const double heading_error = traverse.telemetry[k].heading - traverse.truth[k].heading;
    const Eigen::Vector3d truth_position = Ground(p.x(), p.y());
    net.truth.emplace_back(
        Eigen::Quaterniond(Eigen::AngleAxisd(-heading_error, Eigen::Vector3d::UnitZ())),
        truth_position);
    // Telemetry: horizontal position dead-reckoned, height exact (inclinometers), frame believed
    // to be north-aligned.
    const Eigen::Vector3d& m = traverse.telemetry[k].position;
    net.telemetry.emplace_back(Eigen::Quaterniond::Identity(),
                               Eigen::Vector3d(m.x(), m.y(), truth_position.z()));
    if (k > 0) {
      net.length_m += (p - traverse.truth[k - 1].position).head<2>().norm();
    }
  }
  input.initial_poses = net.telemetry;

  // Leg priors from dead reckoning, with the error model's covariance.
  input.priors = DeadReckonedPriors(net.telemetry, o.telemetry.scale_sigma,
                                    RadFromDeg(o.telemetry.heading_drift_sigma_deg));

  // Tie points: ground landmarks seen from both ends of each leg.
  for (int b = 1; b < input.site_count; ++b) {
    const int a = b - 1;
    if (Excluded(o, a) || Excluded(o, b)) continue;
    const Rigid3d& ta = net.truth[static_cast<size_t>(a)];
    const Rigid3d& tb = net.truth[static_cast<size_t>(b)];
    const Eigen::Vector3d middle = 0.5 * (ta.translation + tb.translation);
    int made = 0;
    for (int attempt = 0; made < o.tie_points_per_leg && attempt < 1000 * o.tie_points_per_leg;
         ++attempt) {
      const double radius = o.tie_spread_m * std::sqrt(unit(rng));
      const double azimuth = 2.0 * std::numbers::pi * unit(rng);
      const Eigen::Vector3d x =
          Ground(middle.x() + radius * std::cos(azimuth), middle.y() + radius * std::sin(azimuth));
      const double range_a = (x - ta.translation).head<2>().norm();
      const double range_b = (x - tb.translation).head<2>().norm();
      if (std::min(range_a, range_b) < o.min_range_m ||
          std::max(range_a, range_b) > o.max_range_m) {
        continue;
      }
      TiePoint t;
      t.id = Id('t', a, b, made);
      t.site_a = a;
      t.site_b = b;
      std::tie(t.position_in_a, t.covariance_in_a) = MeasureStereo(ta.Inverse() * x, o, rng);
      std::tie(t.position_in_b, t.covariance_in_b) = MeasureStereo(tb.Inverse() * x, o, rng);
      if (o.pixel_observations) {
        AddPixelObservations(t.id, a, ta.Inverse() * x,
                             traverse.telemetry[static_cast<size_t>(a)].heading, o, rng, input);
        AddPixelObservations(t.id, b, tb.Inverse() * x,
                             traverse.telemetry[static_cast<size_t>(b)].heading, o, rng, input);
      }
      input.tie_points.push_back(t);
      ++made;
    }
  }

  // Control points: ground points near each site whose MBF position orbital data gives.
  const Rigid3d mbf_from_traverse = SiteFromMbf(input.body, input.origin).Inverse();
  for (int s = 0; s < input.site_count; ++s) {
    if (Excluded(o, s)) continue;
    const Rigid3d& ts = net.truth[static_cast<size_t>(s)];
    for (int i = 0; i < o.control_points_per_site; ++i) {
      const double range = o.min_range_m + (15.0 - o.min_range_m) * unit(rng);
      const double azimuth = 2.0 * std::numbers::pi * unit(rng);
      const Eigen::Vector3d x = Ground(ts.translation.x() + range * std::cos(azimuth),
                                       ts.translation.y() + range * std::sin(azimuth));
      ControlPoint c;
      c.id = Id('c', s, i);
      c.site = s;
      std::tie(c.position_in_site, c.covariance_in_site) = MeasureStereo(ts.Inverse() * x, o, rng);
      const Eigen::Vector3d true_mbf = mbf_from_traverse * x;
      const Eigen::Matrix3d mbf_from_enu =
          EnuFromMbf(input.body, GeographicFromMbf(input.body, true_mbf))
              .RotationMatrix()
              .transpose();
      const Eigen::Vector3d sigmas(o.control_sigma_horizontal_m, o.control_sigma_horizontal_m,
                                   o.control_sigma_vertical_m);
      c.position_mbf = true_mbf + mbf_from_enu * sigmas.cwiseProduct(Gaussian3(rng));
      c.covariance_mbf = mbf_from_enu * sigmas.cwiseAbs2().asDiagonal() * mbf_from_enu.transpose();
      input.control_points.push_back(c);
    }
  }
  // Heights of the site origins above the ellipsoid, e.g. from an orbital DTM.
  if (o.height_sigma_m > 0.0) {
    std::normal_distribution<double> gauss(0.0, o.height_sigma_m);
    for (int s = 0; s < input.site_count; ++s) {
      const Eigen::Vector3d mbf = mbf_from_traverse * net.truth[static_cast<size_t>(s)].translation;
      input.heights.push_back(
          {s, GeographicFromMbf(input.body, mbf).h + gauss(rng), o.height_sigma_m, "simulated"});
    }
  }
  return net;
}

SiteLinks LinksOfSite(const BundleInput& input, int site) {
  SiteLinks links;
  for (const RelativePosePrior& p : input.priors) {
    if (std::max(p.site_a, p.site_b) == site) links.priors.push_back(p);
  }
  for (const TiePoint& t : input.tie_points) {
    if (std::max(t.site_a, t.site_b) == site) links.tie_points.push_back(t);
  }
  for (const ControlPoint& c : input.control_points) {
    if (c.site == site) links.control_points.push_back(c);
  }
  return links;
}

}  // namespace areomap::testing
