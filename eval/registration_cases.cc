#include "registration_cases.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/raster.h"
#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/part_consistency.h"
#include "areomap/samples/orbital.h"
#include "orbital_trial.h"

namespace areomap::eval {
namespace {

namespace fs = std::filesystem;

// Where the real images' grid lies (IAU_2015:49910 metres): near the equator, east of 0.
constexpr double kX0 = 100000.0;
constexpr double kY0 = 20000.0;

struct Source {
  std::string family;
  fs::path path;
};

std::vector<Source> RealSources(const fs::path& data_dir, int max_per_family) {
  std::vector<Source> out;
  const auto add_family = [&](const std::string& family, const fs::path& dir,
                              const std::string& ext) {
    std::vector<fs::path> files;
    if (!fs::is_directory(dir)) return;
    for (const auto& e : fs::directory_iterator(dir)) {
      if (e.path().extension() == ext) files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    if (max_per_family > 0 && static_cast<int>(files.size()) > max_per_family) {
      files.resize(max_per_family);
    }
    for (const fs::path& f : files) out.push_back({family, f});
  };
  add_family("ctx", data_dir / "craters-train" / "ctx-mc11e", ".png");
  add_family("hrsc", data_dir / "craters-train" / "hrsc-bandeira", ".png");
  add_family("moc", data_dir / "moc", ".cub");
  return out;
}

bool IsStructural(const std::string& reason) {
  return !reason.empty() && reason.find("false-match probability") == std::string::npos;
}

CaseResult Outcome(const OrbitalMatch& m, const std::string& family, const std::string& kind,
                   const std::string& image, bool positive, double sigma_m) {
  CaseResult r;
  r.family = family;
  r.kind = kind;
  r.image = image;
  r.positive = positive;
  r.prior_sigma_m = sigma_m;
  r.matched = m.matched;
  r.error_px = std::numeric_limits<double>::quiet_NaN();
  r.false_match_probability = m.false_match_probability;
  r.correlation = m.correlation;
  r.peak_z = m.peak_z;
  r.null = m.null;
  r.null_level = m.null_level;
  r.search_radius_px = m.search_radius_px;
  r.reason = m.reason;
  r.part_contradiction = m.part_contradiction;
  // A quadrant that fits elsewhere refuses the match at every threshold (the verdict names the
  // false-match probability first where both refuse).
  r.structural_refusal = !m.overlaps || m.template_pixels == 0 || IsStructural(m.reason) ||
                         m.part_contradiction >= kMinContradiction;
  return r;
}

// A rover's fan (wedge) or a ring, with holes, centred on an n x n image of `px_m` pixels.
cv::Mat FootprintMask(int n, double px_m, const std::string& kind, double radius_m,
                      std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  cv::Mat mask(n, n, CV_8U, cv::Scalar(255));
  const double c = n / 2.0;
  if (kind == "wedge") {
    const double az = 360.0 * u(rng), fov = 90.0 + 110.0 * u(rng);
    for (int r = 0; r < n; ++r) {
      for (int col = 0; col < n; ++col) {
        const double east = (col + 0.5 - c) * px_m, north = (c - r - 0.5) * px_m;
        const double range = std::hypot(east, north);
        const double a =
            std::remainder(std::atan2(east, north) * 180.0 / std::numbers::pi - az, 360.0);
        if (range < 3.0 || std::abs(a) > fov / 2.0) mask.at<uchar>(r, col) = 0;
      }
    }
    for (int k = 0; k < 6; ++k) {
      cv::circle(mask, cv::Point(static_cast<int>(u(rng) * n), static_cast<int>(u(rng) * n)),
                 static_cast<int>((2.0 + 4.0 * u(rng)) / px_m), cv::Scalar(0), cv::FILLED);
    }
  } else if (kind == "ring") {
    const double inner = 15.0 + 25.0 * u(rng);
    cv::circle(mask, cv::Point(n / 2, n / 2), static_cast<int>(inner / px_m), cv::Scalar(0),
               cv::FILLED);
    for (int k = 0; k < 10; ++k) {
      const double a = 2.0 * std::numbers::pi * u(rng);
      const double d = (inner + (radius_m - inner) * u(rng)) / px_m;
      cv::circle(
          mask,
          cv::Point(static_cast<int>(c + d * std::cos(a)), static_cast<int>(c + d * std::sin(a))),
          static_cast<int>((2.0 + 6.0 * u(rng)) / px_m), cv::Scalar(0), cv::FILLED);
    }
  }
  return mask;
}

void AddNoise(cv::Mat& image, double sigma, std::mt19937& rng) {
  std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma));
  for (auto it = image.begin<float>(); it != image.end<float>(); ++it) *it += noise(rng);
}

// One real-image case: the template's true centre `truth` and its telemetry centre `telemetry`
// [orbital px, GDAL convention].
CaseResult RunRealCase(const cv::Mat& normalized, const OrbitalImage& orbital,
                       const PixelGrid& orbital_grid, const Source& source, const std::string& kind,
                       bool positive, const Eigen::Vector2d& truth,
                       const Eigen::Vector2d& telemetry, double sigma_m, const CaseOptions& options,
                       const OrbitalMatchOptions& match, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double g = options.orbital_gsd_m;
  const double k = kind == "gsd" ? 4.0 + 8.0 * u(rng) : 2.0;  // Ortho px per orbital px.
  const double radius_px = options.template_radius_m / g;
  const int n = 2 * static_cast<int>(std::ceil((radius_px + 2.0) * k));
  cv::Mat map_x(n, n, CV_32F), map_y(n, n, CV_32F);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      map_x.at<float>(r, c) = static_cast<float>(truth.x() + (c + 0.5 - n / 2.0) / k - 0.5);
      map_y.at<float>(r, c) = static_cast<float>(truth.y() + (r + 0.5 - n / 2.0) / k - 0.5);
    }
  }
  OrthoImage ortho;
  cv::remap(normalized, ortho.image, map_x, map_y, cv::INTER_CUBIC, cv::BORDER_CONSTANT,
            std::numeric_limits<float>::quiet_NaN());
  if (kind == "radiometric") {
    const double gamma = 0.6 + u(rng), gain = 0.5 + 1.5 * u(rng), offset = 0.4 * u(rng) - 0.2;
    for (auto it = ortho.image.begin<float>(); it != ortho.image.end<float>(); ++it) {
      *it = static_cast<float>(gain * std::pow(std::clamp(*it, 0.0f, 1.0f), gamma) + offset);
    }
    AddNoise(ortho.image, 0.02 + 0.03 * u(rng), rng);
  } else if (kind == "gsd") {
    cv::GaussianBlur(ortho.image, ortho.image, cv::Size(), 0.7);
    AddNoise(ortho.image, 0.02, rng);
  } else if (kind == "blur") {
    const double sigma_orbital_px = 1.0 + u(rng);
    cv::GaussianBlur(ortho.image, ortho.image, cv::Size(), sigma_orbital_px * k);
    AddNoise(ortho.image, 0.01, rng);
  } else {
    AddNoise(ortho.image, 0.01, rng);
  }
  ortho.mask = FootprintMask(n, g / k, kind, options.template_radius_m, rng);
  ortho.image.setTo(std::numeric_limits<float>::quiet_NaN(), ortho.mask == 0);
  ortho.mask.release();
  ortho.geotransform.c = {kX0 + g * (telemetry.x() - n / (2.0 * k)), g / k, 0.0,
                          kY0 - g * (telemetry.y() - n / (2.0 * k)), 0.0,   -g / k};
  ortho.crs_wkt = orbital.crs_wkt();
  ortho.source = source.path.filename().string() + "-" + kind;
  const PixelGrid ortho_grid(ortho.geotransform, ortho.crs_wkt, ortho.source);
  OrbitalPrior prior;
  prior.position = *ortho_grid.PixelToGeographic({n / 2.0, n / 2.0});
  prior.sigma_m = sigma_m;
  OrbitalMatchOptions o = match;
  o.template_options.reliable_range_m = options.template_radius_m;
  const OrbitalMatch m = MatchOrthoToOrbital(ortho, orbital, prior, o);
  CaseResult r =
      Outcome(m, source.family, kind, source.path.filename().string(), positive, sigma_m);
  if (positive && m.overlaps && m.template_pixels > 0) {
    r.error_px = (orbital_grid.GeographicToPixel(m.corrected_position) - truth).norm();
  }
  return r;
}

// A hillshade of `dtm` (heights [m], rows southwards, `posting_m` square) lit from azimuth
// `az_deg` (clockwise from north) and elevation `el_deg`.
cv::Mat Hillshade(const cv::Mat& dtm, double posting_m, double az_deg, double el_deg) {
  const double az = az_deg * std::numbers::pi / 180.0, el = el_deg * std::numbers::pi / 180.0;
  const Eigen::Vector3d sun(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
  cv::Mat out(dtm.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (int r = 1; r + 1 < dtm.rows; ++r) {
    for (int c = 1; c + 1 < dtm.cols; ++c) {
      const double dzdx = (dtm.at<float>(r, c + 1) - dtm.at<float>(r, c - 1)) / (2 * posting_m);
      const double dzdy = -(dtm.at<float>(r + 1, c) - dtm.at<float>(r - 1, c)) / (2 * posting_m);
      const Eigen::Vector3d normal = Eigen::Vector3d(-dzdx, -dzdy, 1.0).normalized();
      out.at<float>(r, c) = static_cast<float>(std::max(0.0, normal.dot(sun)));
    }
  }
  return out;
}

}  // namespace

void CaseOptions::Check() const {
  RequireOption(cases_per_image >= 1, "CaseOptions.cases_per_image", ">= 1");
  RequireOption(max_images_per_family >= 0, "CaseOptions.max_images_per_family", ">= 0");
  RequireOption(orbital_gsd_m > 0.0, "CaseOptions.orbital_gsd_m", "> 0 m");
  RequireOption(template_radius_m > 0.0, "CaseOptions.template_radius_m", "> 0 m");
  RequireOption(!prior_sigmas_m.empty(), "CaseOptions.prior_sigmas_m", "at least one sigma");
  for (const double s : prior_sigmas_m) {
    RequireOption(s > 0.0, "CaseOptions.prior_sigmas_m", "sigmas > 0 m");
  }
  for (const std::string& k : kinds) {
    RequireOption(k == "radiometric" || k == "gsd" || k == "blur" || k == "wedge" || k == "ring",
                  "CaseOptions.kinds", "radiometric, gsd, blur, wedge or ring");
  }
  RequireOption(generated_trials >= 0, "CaseOptions.generated_trials", ">= 0");
}

std::vector<CaseResult> RunRealImageCases(const fs::path& data_dir, const CaseOptions& options,
                                          const OrbitalMatchOptions& match) {
  options.Check();
  std::vector<CaseResult> out;
  const std::string wkt = Crs::FromUserInput("IAU_2015:49910").Wkt();
  const double g = options.orbital_gsd_m;
  const std::vector<Source> sources = RealSources(data_dir, options.max_images_per_family);
  for (size_t s = 0; s < sources.size(); ++s) {
    const RasterDataset dataset = RasterDataset::Open(sources[s].path);
    cv::Mat image = dataset.ReadWindowFloat(1, dataset.FullWindow());
    // The template is cut from the image scaled to [0, 1] between its 1st and 99th percentiles.
    std::vector<float> values;
    for (auto it = image.begin<float>(); it != image.end<float>(); ++it) {
      if (std::isfinite(*it)) values.push_back(*it);
    }
    if (values.size() < 100) throw Error(sources[s].path.string() + ": no valid pixels");
    std::nth_element(values.begin(), values.begin() + values.size() / 100, values.end());
    const float lo = values[values.size() / 100];
    std::nth_element(values.begin(), values.begin() + values.size() * 99 / 100, values.end());
    const float hi = values[values.size() * 99 / 100];
    cv::Mat normalized = (image - lo) / std::max(hi - lo, 1e-6f);
    GeoRaster raster;
    raster.bands.push_back(image);
    raster.geotransform.c = {kX0, g, 0.0, kY0, 0.0, -g};
    raster.crs_wkt = wkt;
    const OrbitalImage orbital = OrbitalImage::FromGeoRaster(raster, sources[s].path.filename());
    const PixelGrid orbital_grid(raster.geotransform, wkt, "orbital");
    const double radius_px = options.template_radius_m / g;
    for (size_t kind = 0; kind < options.kinds.size(); ++kind) {
      for (int c = 0; c < options.cases_per_image; ++c) {
        for (const bool positive : {true, false}) {
          std::seed_seq seq{options.seed, static_cast<uint32_t>(s), static_cast<uint32_t>(kind),
                            static_cast<uint32_t>(c), static_cast<uint32_t>(positive)};
          std::mt19937 rng(seq);
          std::uniform_real_distribution<double> u(0.0, 1.0);
          std::normal_distribution<double> gauss(0.0, 1.0);
          const double sigma_m =
              options
                  .prior_sigmas_m[static_cast<size_t>(
                                      u(rng) * static_cast<double>(options.prior_sigmas_m.size())) %
                                  options.prior_sigmas_m.size()];
          const double window_px = 3.0 * sigma_m / g;
          const double margin = radius_px + window_px + 4.0;
          const auto in_image = [&](const Eigen::Vector2d& p, double m) {
            return p.x() >= m && p.y() >= m && p.x() <= image.cols - m && p.y() <= image.rows - m;
          };
          const auto draw = [&](double m) {
            return Eigen::Vector2d(m + (image.cols - 2 * m) * u(rng),
                                   m + (image.rows - 2 * m) * u(rng));
          };
          bool found = false;
          Eigen::Vector2d truth, telemetry;
          for (int attempt = 0; attempt < 200 && !found; ++attempt) {
            if (positive) {
              truth = draw(margin);
              Eigen::Vector2d e(gauss(rng), gauss(rng));
              e = e.cwiseMax(-2.5).cwiseMin(2.5) * sigma_m / g;
              telemetry = truth + e;
              found = in_image(telemetry, margin);
            } else {
              truth = draw(radius_px + 4.0);
              telemetry = draw(margin);
              found = (telemetry - truth).lpNorm<Eigen::Infinity>() > window_px + radius_px + 4.0;
            }
            found = found && in_image(truth, radius_px + 4.0);
          }
          if (!found) continue;  // The image cannot hold this window (the MOC crop at 80 m).
          out.push_back(RunRealCase(normalized, orbital, orbital_grid, sources[s],
                                    options.kinds[kind], positive, truth, telemetry, sigma_m,
                                    options, match, rng));
        }
      }
    }
  }
  return out;
}

std::vector<CaseResult> RunGeneratedCases(const CaseOptions& options,
                                          const OrbitalMatchOptions& match) {
  options.Check();
  std::vector<CaseResult> out;
  for (int t = 0; t < options.generated_trials; ++t) {
    testing::TrialOptions o;
    o.seed = options.seed * 1000u + static_cast<uint32_t>(t);
    const testing::Trial trial = testing::MakeTrial(o);
    const std::string name = "seed " + std::to_string(o.seed);
    const PixelGrid orbital_grid(trial.orbital->geotransform(), trial.orbital->crs_wkt(),
                                 "orbital");
    const PixelGrid truth_grid(trial.ortho_truth, trial.ortho.crs_wkt, "truth");
    const Eigen::Vector2d truth_px = orbital_grid.GeographicToPixel(*truth_grid.PixelToGeographic(
        {trial.ortho.image.cols / 2.0, trial.ortho.image.rows / 2.0}));
    const auto run = [&](const OrthoImage& ortho, const std::string& kind,
                         const OrbitalMatchOptions& mo) {
      const OrbitalMatch pos = MatchOrthoToOrbital(ortho, *trial.orbital, trial.prior, mo);
      CaseResult p = Outcome(pos, "generated", kind, name, true, trial.prior.sigma_m);
      if (pos.overlaps && pos.template_pixels > 0) {
        p.error_px = (orbital_grid.GeographicToPixel(pos.corrected_position) - truth_px).norm();
      }
      out.push_back(p);
      const OrbitalMatch neg = MatchOrthoToOrbital(ortho, *trial.decoy, trial.prior, mo);
      out.push_back(Outcome(neg, "generated", kind, name, false, trial.prior.sigma_m));
    };
    run(trial.ortho, "second-sun", match);

    // Cross-modal: a hillshade of the orbital DTM under another sun, +-20 m around the rover,
    // georeferenced with the trial's telemetry error.
    PixelWindow all{0, 0, trial.dtm->width(), trial.dtm->height()};
    const cv::Mat dtm = trial.dtm->ReadWindow(all);
    const GeoTransform& dgt = trial.dtm->geotransform();
    const double posting = std::abs(dgt.c[1]);
    std::mt19937 rng(o.seed * 31u + 7u);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // Lit as the orbital image (OrbitalImageOptions' sun), known to +-10 degrees.
    const OrbitalImageOptions sun;
    const cv::Mat shade = Hillshade(dtm, posting, sun.sun_azimuth_deg + 20.0 * (u(rng) - 0.5),
                                    sun.sun_elevation_deg + 20.0 * (u(rng) - 0.5));
    const Eigen::Vector2d rover_map =
        trial.ortho_truth.PixelToMap(trial.ortho.image.cols / 2.0, trial.ortho.image.rows / 2.0);
    const Eigen::Vector2d rover_px = dgt.MapToPixel(rover_map.x(), rover_map.y());
    constexpr double kHalf = 20.0;
    const int half = static_cast<int>(std::ceil(kHalf / posting));
    const int col0 = static_cast<int>(std::lround(rover_px.x())) - half;
    const int row0 = static_cast<int>(std::lround(rover_px.y())) - half;
    const cv::Rect crop =
        cv::Rect(col0, row0, 2 * half, 2 * half) & cv::Rect(0, 0, dtm.cols, dtm.rows);
    OrthoImage hill;
    hill.image = shade(crop).clone();
    hill.crs_wkt = trial.dtm->crs_wkt();
    hill.source = "hillshade";
    const Eigen::Vector2d origin = dgt.PixelToMap(crop.x, crop.y) + trial.telemetry_error_en_m;
    hill.geotransform.c = {origin.x(), dgt.c[1], dgt.c[2], origin.y(), dgt.c[4], dgt.c[5]};
    OrbitalMatchOptions hm = match;
    hm.template_options.reliable_range_m = kHalf;
    run(hill, "hillshade", hm);
  }
  return out;
}

std::string CaseResultsCsv(const std::vector<CaseResult>& results) {
  std::ostringstream out;
  out << "family,kind,image,positive,prior_sigma_m,matched,error_px,false_match_probability,"
         "correlation,peak_z,null_mean,null_stddev,null_lambda_x,null_lambda_y,null_samples,"
         "null_level,search_radius_px,part_contradiction,structural_refusal,reason\n";
  out.precision(6);
  for (const CaseResult& r : results) {
    std::string reason = r.reason;
    std::replace(reason.begin(), reason.end(), ',', ';');
    out << r.family << "," << r.kind << "," << r.image << "," << r.positive << ","
        << r.prior_sigma_m << "," << r.matched << "," << r.error_px << ","
        << r.false_match_probability << "," << r.correlation << "," << r.peak_z << ","
        << r.null.mean << "," << r.null.stddev << "," << r.null.lambda_x << "," << r.null.lambda_y
        << "," << r.null.samples << "," << r.null_level << "," << r.search_radius_px << ","
        << r.part_contradiction << "," << r.structural_refusal << "," << reason << "\n";
  }
  return out.str();
}

}  // namespace areomap::eval
