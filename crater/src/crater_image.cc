#include "areomap/crater/crater_image.h"

#include <algorithm>
#include <iomanip>
#include <sstream>

#include "areomap/crater/crater_model.h"
#include "areomap/crater/crater_output.h"
#include "areomap/crater/crater_raster.h"
#include "areomap/crater/learned_detector.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

// The detector's diameter limits in pixels of `job`'s raster; throws when the smallest is below
// what the detector can find.
void SetDiameterLimits(const CraterImageOptions& o, CraterImageJob* job) {
  const std::string input = job->image.string();
  if (o.diameters_in_metres && !(job->pixel_size_m > 0.0)) {
    throw Error(input + ": --units m needs a georeferenced raster in a projected Mars CRS " +
                "(this one has no geotransform or CRS); give diameters in px");
  }
  const double to_px = o.diameters_in_metres ? 1.0 / job->pixel_size_m : 1.0;
  job->detector.min_diameter_px = o.min_diameter * to_px;
  job->detector.max_diameter_px = o.max_diameter * to_px;
  if (!(job->detector.min_diameter_px >= CraterDetectorOptions::kSmallestDiameterPx)) {
    std::ostringstream text;
    text << "--min-diameter: " << o.min_diameter;
    if (o.diameters_in_metres) {
      text << " m (" << job->detector.min_diameter_px << " px of " << job->pixel_size_m << " m on "
           << input << ")";
    } else {
      text << " px";
    }
    text << " is below the smallest rim diameter detected, "
         << CraterDetectorOptions::kSmallestDiameterPx << " px";
    throw Error(text.str());
  }
}

// The sun azimuth the detector uses: given, else (an image) estimated from the shading of
// craters found without it. Throws when shading templates are asked for and no sun is known.
std::optional<double> ChooseSunAzimuth(const CraterImageOptions& o,
                                       const ProgressCallback& progress, CraterImageJob* job) {
  const CraterDetectorOptions& options = job->detector;
  if (o.dtm) {
    job->sun_azimuth_source = "none (DTM)";
    return std::nullopt;
  }
  if (o.sun_azimuth_deg) {
    job->sun_azimuth_source = "given";
    return o.sun_azimuth_deg;
  }
  job->sun_azimuth_source = "none";
  // The learned detector needs no sun: its rim fits run without the shading checks.
  if (options.method == CraterMethod::kLearned) return std::nullopt;
  if (!o.estimate_sun) {
    if (options.shading_template.enabled) {
      throw Error(
          "craters: --shading-templates needs a sun azimuth: give --sun-azimuth, or "
          "drop --no-sun-estimate");
    }
    return std::nullopt;
  }
  const SunAzimuthEstimate e = EstimateSunAzimuthInRaster(job->dataset, options, {}, progress);
  job->sun_estimate = e;
  std::ostringstream text;
  text << std::fixed << std::setprecision(0) << e.votes << " of " << e.candidates
       << " craters found without a sun show a bright and a dark wall; " << std::setprecision(2)
       << e.agreement << " of them agree";
  const std::string input = job->image.string();
  if (!e.reliable) {
    if (options.shading_template.enabled) {
      throw Error(
          "craters: --shading-templates needs a sun azimuth: give --sun-azimuth (the "
          "estimate from " +
          input + " is not reliable: " + text.str() + ")");
    }
    job->warnings.push_back("no sun azimuth given and none could be estimated from " + input +
                            " (" + text.str() +
                            "): the shading checks are off, expect more false detections "
                            "(nested rims, mounds); give --sun-azimuth");
    return std::nullopt;
  }
  job->sun_azimuth_source = "estimated";
  std::ostringstream note;
  note << "sun azimuth estimated from the image: " << std::fixed << std::setprecision(1)
       << e.azimuth_deg << " deg (" << text.str() << ")";
  job->notes.push_back(note.str());
  return e.azimuth_deg;
}

// Crater models (depth, floor, ratios) measured on the DTM around each rim.
void MeasureModels(const CraterImageJob& job, CraterCatalog* catalog) {
  const RasterInfo& info = job.dataset.info();
  for (CatalogCrater& c : catalog->craters) {
    const Ellipse& e = c.detection.ellipse;
    const double reach = 1.2 * e.semi_major + 4.0;
    const int c0 = std::max(0, static_cast<int>(e.center.x() - reach));
    const int r0 = std::max(0, static_cast<int>(e.center.y() - reach));
    const int c1 = std::min(info.width, static_cast<int>(e.center.x() + reach) + 1);
    const int r1 = std::min(info.height, static_cast<int>(e.center.y() + reach) + 1);
    if (c1 <= c0 || r1 <= r0) continue;
    Ellipse local = e;
    local.center -= Eigen::Vector2d(c0, r0);
    c.model = MeasureCraterOnDtm(job.dataset.ReadWindowFloat(1, {c0, r0, c1 - c0, r1 - r0}), local,
                                 job.detector.dtm_posting);
  }
}

}  // namespace

void CraterImageOptions::Check() const {
  if (!(min_diameter > 0.0)) throw Error("craters: min_diameter must be > 0");
  if (!(max_diameter >= 0.0)) throw Error("craters: max_diameter must be >= 0 (0: no limit)");
  if (!(overlay_max_side >= 1)) throw Error("craters: overlay_max_side must be >= 1");
  if (detector.shading_template.enabled && !dtm && detector.method == CraterMethod::kLearned) {
    throw Error(
        "craters: --shading-templates belongs to --method edges (the learned detector finds "
        "degraded bowls without it)");
  }
  if (detector.shading_template.enabled && dtm) {
    throw Error(
        "craters: --shading-templates needs an image, not a DTM (the bowl's shading depends on "
        "where the sun is)");
  }
}

void CheckCraterModel(const CraterImageOptions& options) {
  if (!options.dtm && options.detector.method != CraterMethod::kEdges) {
    CraterNetwork{options.detector.learned.model_path};
  }
}

CraterImageJob PrepareCraterImage(const std::filesystem::path& image,
                                  const CraterImageOptions& options,
                                  const ProgressCallback& progress) {
  CraterImageJob job(image, RasterDataset::Open(image));
  const RasterInfo& info = job.dataset.info();
  job.dtm = options.dtm;
  job.source = options.dtm ? RimSource::kDtm : RimSource::kImage;
  job.overlay_max_side = options.overlay_max_side;
  job.detector = options.detector;
  job.detector.method = options.dtm ? CraterMethod::kEdges : options.detector.method;
  // Ground size of a pixel, to turn metres into pixels and DTM heights into slopes.
  const CraterCatalog probe = MakeCraterCatalog({}, info);
  job.pixel_size_m = probe.pixel_size_m;
  job.georeferenced = probe.IsGeoreferenced();
  if (options.require_ground && !(job.georeferenced && job.pixel_size_m > 0.0)) {
    throw Error(image.string() +
                ": a crater catalogue needs ground positions, and this raster has no " +
                (job.georeferenced ? "projected CRS in metres (it is geographic)"
                                   : "georeference (geotransform and Mars CRS)") +
                "; give a georeferenced GeoTIFF or ISIS cube in a projected Mars CRS");
  }
  SetDiameterLimits(options, &job);
  job.detector.dtm_posting = job.pixel_size_m > 0.0 ? job.pixel_size_m : 1.0;
  job.detector.Check();
  // A missing or unreadable model is reported before any work or output.
  CheckCraterModel(options);
  if (job.detector.method != CraterMethod::kEdges) {
    job.model = job.detector.learned.model_path.empty() ? std::string("built-in")
                                                        : job.detector.learned.model_path;
  }
  job.detector.sun_azimuth_deg = ChooseSunAzimuth(options, progress, &job);
  return job;
}

CraterImageResult DetectCraterImage(const CraterImageJob& job, const std::filesystem::path& out_dir,
                                    const ProgressCallback& progress) {
  const RasterInfo& info = job.dataset.info();
  const std::vector<CraterDetection> found =
      DetectCratersInRaster(job.dataset, job.source, job.detector, progress);
  CraterCatalog catalog = MakeCraterCatalog(found, info);
  if (job.dtm) MeasureModels(job, &catalog);
  CraterImageResult result;
  WriteCratersCsv(out_dir / "craters.csv", catalog);
  WriteCratersJson(out_dir / "craters.json", catalog);
  result.files = {"craters.csv", "craters.json", "overlay.png"};
  if (catalog.IsGeoreferenced()) {
    WriteCratersGeoPackage(out_dir / "craters.gpkg", catalog);
    result.files.push_back("craters.gpkg");
  }
  const int factor = DecimationFactor(info.width, info.height, job.overlay_max_side);
  WriteCraterOverlay(
      out_dir / "overlay.png",
      ReadDecimated(job.dataset, job.dataset.FullWindow(), factor, &result.valid_pixels), found,
      job.overlay_max_side);
  result.craters = static_cast<int>(found.size());
  for (const CraterDetection& d : found) {
    result.partial += d.partial ? 1 : 0;
    result.rims_fitted += d.rim_fitted ? 1 : 0;
    result.edge_detected += d.edge_detected ? 1 : 0;
  }
  if (result.valid_pixels == 0) {
    result.warnings.push_back(job.image.string() +
                              " has no valid pixel (every pixel is nodata or NaN): nothing was "
                              "searched");
  }
  return result;
}

nlohmann::json CraterImageSummaryJson(const CraterImageJob& job, const CraterImageResult& result) {
  const RasterInfo& info = job.dataset.info();
  const CraterDetectorOptions& options = job.detector;
  nlohmann::json summary = {
      {"command", "craters"},
      {"input", job.image.string()},
      {"source", job.dtm ? "dtm" : "image"},
      {"method", ToString(options.method)},
      {"model", job.model},
      {"rims_fitted", result.rims_fitted},
      {"edge_detected", result.edge_detected},
      {"width_px", info.width},
      {"height_px", info.height},
      {"georeferenced", job.georeferenced},
      {"pixel_size_m", job.pixel_size_m},
      {"min_diameter_px", options.min_diameter_px},
      {"max_diameter_px", options.max_diameter_px},
      {"upsample_small_craters", options.upsample_small_craters},
      // whether that level was searched: only for minimum diameters under 16 px
      {"upsampled_level_searched", options.SearchesUpsampledLevel()},
      {"sun_azimuth_deg",
       options.sun_azimuth_deg ? nlohmann::json(*options.sun_azimuth_deg) : nlohmann::json()},
      {"valid_pixels", result.valid_pixels},
      {"craters", result.craters},
      {"partial", result.partial},
      {"files", result.files},
      {"sun_azimuth_source", job.sun_azimuth_source}};
  if (job.sun_estimate) summary["sun_azimuth_estimate"] = SunAzimuthEstimateJson(*job.sun_estimate);
  return summary;
}

}  // namespace areomap
