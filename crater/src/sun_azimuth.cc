#include "areomap/crater/sun_azimuth.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Core>

#include "areomap/crater/crater_raster.h"
#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "bilinear_sample.h"
#include "ring_sampler.h"

namespace areomap {
namespace {

using internal::kRingSamples;
using internal::RingSampler;
using internal::RingStats;

constexpr double kAgreementHalfWidthDeg = 60.0;
constexpr double kKernelConcentration = 4.0;  // von Mises kappa: ~30 degrees wide

// Azimuth [deg, clockwise from up] of a pixel-frame direction (x right, y down).
double AzimuthOf(const Eigen::Vector2d& d) {
  const double az = DegFromRad(std::atan2(d.x(), -d.y()));
  return az < 0.0 ? az + 360.0 : az;
}

double AngleBetweenDeg(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 360.0);
  return std::min(d, 360.0 - d);
}

// The azimuth towards the sun one crater's shading votes for; nullopt without a clear dipole
// (under min_dipole x the surroundings' std) or with most samples off the image or nodata.
std::optional<double> Vote(const cv::Mat& image, const Ellipse& e, double min_dipole) {
  const RingSampler ring(e);
  // Dipole sum (v - mean) u = sum v u - mean sum u, u the unit vector from the centre.
  Eigen::Vector2d sum_vu = Eigen::Vector2d::Zero(), sum_u = Eigen::Vector2d::Zero();
  RingStats inside, outside;
  for (const double rho : {0.3, 0.45, 0.6, 0.75}) {
    for (int k = 0; k < kRingSamples; ++k) {
      const Eigen::Vector2d p = ring.Point(rho, k);
      const double v = internal::SampleBilinear(image, p.x(), p.y());
      if (!std::isfinite(v)) continue;
      const Eigen::Vector2d u = (p - e.center).normalized();
      sum_vu += v * u;
      sum_u += u;
      inside.Add(v);
    }
  }
  for (const double rho : {1.3, 1.6, 1.9}) {
    for (int k = 0; k < kRingSamples; ++k) {
      const Eigen::Vector2d p = ring.Point(rho, k);
      outside.Add(internal::SampleBilinear(image, p.x(), p.y()));
    }
  }
  // Mostly off the image or nodata: no vote.
  if (inside.n < kRingSamples || outside.n < kRingSamples) return std::nullopt;
  const Eigen::Vector2d dipole = (sum_vu - inside.Mean() * sum_u) / inside.n;
  const double scale = outside.Std();
  if (!(scale > 0.0) || dipole.norm() < min_dipole * scale) return std::nullopt;
  return AzimuthOf(-dipole);  // bright wall away from the sun
}

}  // namespace

void SunAzimuthOptions::Check() const {
  RequireOption(min_dipole > 0.0 && std::isfinite(min_dipole), "SunAzimuthOptions.min_dipole",
                "> 0");
  RequireOption(min_votes >= 1, "SunAzimuthOptions.min_votes", ">= 1");
  RequireOption(min_agreement > 0.0 && min_agreement <= 1.0, "SunAzimuthOptions.min_agreement",
                "(0, 1]");
  RequireOption(candidate_min_diameter_px >= CraterDetectorOptions::kSmallestDiameterPx,
                "SunAzimuthOptions.candidate_min_diameter_px", ">= 4 px");
  RequireOption(overview_size_px >= 256, "SunAzimuthOptions.overview_size_px", ">= 256 px");
}

SunAzimuthEstimate EstimateSunAzimuth(const cv::Mat& image,
                                      const std::vector<CraterDetection>& candidates,
                                      const SunAzimuthOptions& options) {
  options.Check();
  cv::Mat image32;
  if (image.depth() == CV_32F) {
    image32 = image;
  } else {
    image.convertTo(image32, CV_32F);
  }
  SunAzimuthEstimate out;
  out.candidates = static_cast<int>(candidates.size());
  std::vector<double> votes;
  for (const CraterDetection& c : candidates) {
    if (const auto vote = Vote(image32, c.ellipse, options.min_dipole)) votes.push_back(*vote);
  }
  out.votes = static_cast<int>(votes.size());
  if (votes.empty()) return out;
  // Mode of the votes' kernel density, 1 degree steps.
  double best = 0.0, best_density = -1.0;
  for (int step = 0; step < 360; ++step) {
    double density = 0.0;
    for (const double v : votes) {
      density += std::exp(kKernelConcentration * (std::cos(RadFromDeg(v - step)) - 1.0));
    }
    if (density > best_density) best_density = density, best = step;
  }
  // Circular mean of the votes near the mode.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  int near = 0;
  for (const double v : votes) {
    if (AngleBetweenDeg(v, best) > kAgreementHalfWidthDeg) continue;
    mean += Eigen::Vector2d(std::sin(RadFromDeg(v)), -std::cos(RadFromDeg(v)));
    ++near;
  }
  out.azimuth_deg = AzimuthOf(mean);
  out.agreement = static_cast<double>(near) / static_cast<double>(votes.size());
  out.reliable = out.votes >= options.min_votes && out.agreement >= options.min_agreement;
  return out;
}

SunAzimuthEstimate EstimateSunAzimuthInRaster(const RasterDataset& dataset,
                                              const CraterDetectorOptions& detector,
                                              const SunAzimuthOptions& options,
                                              const ProgressCallback& progress) {
  options.Check();
  const RasterInfo& info = dataset.info();
  const int factor = DecimationFactor(info.width, info.height, options.overview_size_px);
  const cv::Mat overview = ReadDecimated(dataset, dataset.FullWindow(), factor);
  CraterDetectorOptions search = detector;
  search.sun_azimuth_deg.reset();
  search.shading_template.enabled = false;
  search.upsample_small_craters = false;
  search.min_diameter_px =
      std::max(options.candidate_min_diameter_px, detector.min_diameter_px / factor);
  search.max_diameter_px = detector.max_diameter_px / factor;
  if (search.max_diameter_px > 0.0 && search.max_diameter_px <= search.min_diameter_px) {
    search.max_diameter_px = 0.0;  // the limits leave nothing to search: use every size
  }
  const std::vector<CraterDetection> candidates =
      DetectCraters(overview, RimSource::kImage, search, progress);
  return EstimateSunAzimuth(overview, candidates, options);
}

}  // namespace areomap
