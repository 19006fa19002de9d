// Rock catalogues and site-pair matches as files: CSV (one row per rock / per match) and JSON
// (everything, with every fitted model). Positions are in the cloud's site frame (x north, y east,
// z down [m]); sizes in metres, areas in m^2, volumes in m^3. Clouds carry no georeference, so no
// GeoPackage is written. Files are written atomically; a write failure throws areomap::Error
// naming the file.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "areomap/landmarks/rock_extraction.h"
#include "areomap/landmarks/rock_matching.h"

namespace areomap {

// One rock: peak, covariance, height, plane, surface, models (best first).
nlohmann::json RockToJson(const ExtractedRock& rock);
nlohmann::json RockExtractionSummaryToJson(const RockExtractionSummary& summary);

// rocks.csv: id, peak x/y/z, sigma_x/y/z, range, height, plane normal, surface points, ground
// sigma, best model (shape, h, a, b, RMS eq. 2.13, volume, exact surface area) or empty fields.
void WriteRocksCsv(const std::filesystem::path& path, const std::vector<ExtractedRock>& rocks);
void WriteRocksJson(const std::filesystem::path& path, const std::vector<ExtractedRock>& rocks);

// matches.csv: one row per accepted rock pair (rock ids, both peaks in their own site frames,
// their largest horizontal sigmas, model cost, votes, normal angle, distance ratio).
void WriteRockMatchesCsv(const std::filesystem::path& path, const SiteRocks& a, const SiteRocks& b,
                         const SitePairMatch& match);

// rocks.png: a map of the cloud seen from above (x up, y right; points shaded by elevation, the
// colour scale stretched over the 2nd-98th percentiles) within `max_range_m` of the camera, with
// each rock's surface reach circled (red: modeled, orange: not) and its id written beside it.
// `pixels` is the image edge. With no point in range (or an empty cloud) the map is blank with a
// note saying so. Throws areomap::Error when the file cannot be written.
void WriteRocksPlotPng(const std::filesystem::path& path, const PointCloud& cloud,
                       const std::vector<ExtractedRock>& rocks, double max_range_m,
                       int pixels = 1000);

// The rocks over the left image the cloud came from (pair `image_id` of the site), for
// rocks_image.png: each rock's surface points painted at their left-image pixels
// (StereoPoint::left_x/y, rounded; red: modeled, orange: not), its peak marked with a yellow cross
// and its id and height written beside it. `image` is 8- or 16-bit grey, RGB or RGBA (16-bit is
// stretched to 8 bits, alpha dropped); returns 8-bit RGB. Throws areomap::Error naming
// `image_name` for another pixel layout or when no rock point falls inside the image (the wrong
// image or pair). Rendering before writing lets a caller fail before it writes anything.
cv::Mat RenderRocksImage(const cv::Mat& image, const PointCloud& cloud,
                         const std::vector<ExtractedRock>& rocks, int image_id,
                         const std::string& image_name);

}  // namespace areomap
