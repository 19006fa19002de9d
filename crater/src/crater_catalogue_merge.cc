#include "areomap/crater/crater_catalogue_merge.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>

#include <cpl_quad_tree.h>

#include "areomap/crater/crater_catalogue.h"
#include "areomap/crater/same_crater.h"
#include "areomap/map/error.h"
#include "catalogue_files.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

// One crater of an image's catalogue in the common CRS: what the search needs.
struct Candidate {
  Eigen::Vector2d center;       // common CRS [m]
  double diameter = 0.0;        // rim diameter a + b [m of the common CRS]
  double scale = 1.0;           // common metres per image-CRS metre at the centre
  double relative_sigma = 0.0;  // hypot(sx, sy) / D in the image's pixels; +inf when unknown
  GIntBig fid = 0;              // the feature in the image's craters.gpkg
  int image = 0;                // index into the image folders
  bool partial = false;
  bool rim_fitted = true;
};

// Ranks `a` before `b` when its rim is the better fitted (the header's rule 1-4).
bool BetterFitted(const Candidate& a, const Candidate& b) {
  if (a.partial != b.partial) return !a.partial;
  if (a.rim_fitted != b.rim_fitted) return a.rim_fitted;
  if (a.relative_sigma != b.relative_sigma) return a.relative_sigma < b.relative_sigma;
  if (a.image != b.image) return a.image < b.image;
  return a.fid < b.fid;
}

// The craters of one image's catalogue, moved into the common CRS.
void ReadCandidates(CatalogueLayer& source, const CommonCrs& common, int image,
                    std::vector<Candidate>* out) {
  const CraterFieldIndex f(source);
  source.layer->SetIgnoredFields(std::vector<const char*>{"OGR_GEOMETRY", nullptr}.data());
  source.layer->ResetReading();
  const size_t first = out->size();
  std::vector<double> x, y;
  for (auto& feature : *source.layer) {
    Candidate c;
    c.image = image;
    c.fid = feature->GetFID();
    c.center = {feature->GetFieldAsDouble(f.map_x), feature->GetFieldAsDouble(f.map_y)};
    c.diameter =
        feature->GetFieldAsDouble(f.semi_major_m) + feature->GetFieldAsDouble(f.semi_minor_m);
    const double sigma = std::hypot(feature->GetFieldAsDouble(f.x_sigma_px),
                                    feature->GetFieldAsDouble(f.y_sigma_px));
    c.relative_sigma = sigma / feature->GetFieldAsDouble(f.diameter_px);
    if (!std::isfinite(c.relative_sigma) || !feature->IsFieldSetAndNotNull(f.x_sigma_px)) {
      c.relative_sigma = std::numeric_limits<double>::infinity();
    }
    c.partial = feature->GetFieldAsDouble(f.partial) != 0.0;
    c.rim_fitted = feature->GetFieldAsDouble(f.rim_fitted) != 0.0;
    out->push_back(c);
  }
  source.layer->SetIgnoredFields(nullptr);
  const auto transform = common.TransformFrom(source);
  if (!transform) return;
  // Centre and two points half a diameter east and north of it: the transformation's Jacobian,
  // whose determinant's root is the local scale of lengths (exact for a conformal change, the
  // geometric mean of the two directions' scales otherwise).
  const size_t n = out->size() - first;
  const auto half = [](const Candidate& c) {
    return std::isfinite(c.diameter) && c.diameter > 0.0 ? 0.5 * c.diameter : 1.0;
  };
  x.resize(3 * n);
  y.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    const Candidate& c = (*out)[first + i];
    const double h = half(c);
    x[3 * i] = c.center.x(), y[3 * i] = c.center.y();
    x[3 * i + 1] = c.center.x() + h, y[3 * i + 1] = c.center.y();
    x[3 * i + 2] = c.center.x(), y[3 * i + 2] = c.center.y() + h;
  }
  std::vector<int> ok(3 * n, FALSE);
  transform->Transform(static_cast<int>(3 * n), x.data(), y.data(), nullptr, ok.data());
  for (size_t i = 0; i < n; ++i) {
    Candidate& c = (*out)[first + i];
    if (!ok[3 * i] || !ok[3 * i + 1] || !ok[3 * i + 2]) {
      throw Error(source.path.string() + ": crater fid " + std::to_string(c.fid) +
                  " cannot be moved into " + common.name);
    }
    const double h = half(c);
    const Eigen::Vector2d p0(x[3 * i], y[3 * i]);
    const Eigen::Vector2d e = Eigen::Vector2d(x[3 * i + 1], y[3 * i + 1]) - p0;
    const Eigen::Vector2d nn = Eigen::Vector2d(x[3 * i + 2], y[3 * i + 2]) - p0;
    c.scale = std::sqrt(std::abs(e.x() * nn.y() - e.y() * nn.x())) / h;
    c.center = p0;
    c.diameter *= c.scale;
  }
}

// Marks the craters kept: greedy in BetterFitted order, each kept unless SameCraterEitherWay
// with one kept before (found through a quadtree on the kept centres).
std::vector<char> KeepBestOfEach(const std::vector<Candidate>& all) {
  std::vector<char> kept(all.size(), 0);
  if (all.empty()) return kept;
  std::vector<size_t> order(all.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return BetterFitted(all[a], all[b]); });
  CPLRectObj bounds{HUGE_VAL, HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  for (const Candidate& c : all) {
    bounds.minx = std::min(bounds.minx, c.center.x());
    bounds.miny = std::min(bounds.miny, c.center.y());
    bounds.maxx = std::max(bounds.maxx, c.center.x());
    bounds.maxy = std::max(bounds.maxy, c.center.y());
  }
  std::unique_ptr<CPLQuadTree, decltype(&CPLQuadTreeDestroy)> tree(
      CPLQuadTreeCreate(&bounds, nullptr), &CPLQuadTreeDestroy);
  CPLQuadTreeSetMaxDepth(tree.get(), CPLQuadTreeGetAdvisedMaxDepth(static_cast<int>(std::min(
                                         all.size(), size_t{std::numeric_limits<int>::max()}))));
  for (const size_t i : order) {
    const Candidate& c = all[i];
    const CraterCircle circle{c.center, c.diameter};
    bool duplicate = false;
    const double r = SameCraterSearchRadius(c.diameter);
    if (std::isfinite(r)) {
      const CPLRectObj near{c.center.x() - r, c.center.y() - r, c.center.x() + r, c.center.y() + r};
      int count = 0;
      void** found = CPLQuadTreeSearch(tree.get(), &near, &count);
      for (int k = 0; k < count && !duplicate; ++k) {
        const Candidate& other = all[reinterpret_cast<uintptr_t>(found[k]) - 1];
        duplicate = SameCraterEitherWay(circle, {other.center, other.diameter});
      }
      CPLFree(found);
    }
    if (duplicate) continue;
    kept[i] = 1;
    const CPLRectObj at{c.center.x(), c.center.y(), c.center.x(), c.center.y()};
    if (std::isfinite(c.center.x()) && std::isfinite(c.center.y())) {
      CPLQuadTreeInsertWithBounds(tree.get(), reinterpret_cast<void*>(uintptr_t{i + 1}), &at);
    }
  }
  return kept;
}

}  // namespace

CatalogueMergeSummary MergeCraterCatalogues(const std::vector<fs::path>& image_dirs,
                                            const fs::path& out_dir,
                                            const CatalogueMergeOptions& options,
                                            const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  CatalogueMergeSummary summary;
  for (const fs::path& dir : image_dirs) {
    const CatalogueImageRecord record = ReadCatalogueImageRecord(dir);
    CatalogueImageRow row{dir.filename().string(), record.image, record.ok, record.error};
    row.seconds = record.seconds;
    summary.images.push_back(row);
  }
  const double steps = 2.0 * static_cast<double>(std::max<size_t>(1, image_dirs.size()));
  const auto report = [&](size_t step, const char* stage) {
    if (progress && !progress(static_cast<double>(step) / steps, stage)) {
      throw Error("merge: cancelled");
    }
  };
  // Pass 1: every crater's centre, diameter and fit quality in the common CRS.
  std::vector<Candidate> all;
  std::vector<size_t> begin(image_dirs.size() + 1, 0);
  std::optional<CommonCrs> common;
  for (size_t i = 0; i < image_dirs.size(); ++i) {
    begin[i] = all.size();
    if (summary.images[i].ok) {
      CatalogueLayer layer = OpenCatalogueLayer(image_dirs[i] / "craters.gpkg");
      if (!common) common.emplace(options.crs, layer);
      ReadCandidates(layer, *common, static_cast<int>(i), &all);
    }
    report(i + 1, "merge: read");
  }
  begin[image_dirs.size()] = all.size();
  const std::vector<char> kept = KeepBestOfEach(all);
  // Pass 2: the kept craters' features, moved into the common CRS.
  CatalogueWriter writer(out_dir, common ? &*common : nullptr);
  for (size_t i = 0; i < image_dirs.size(); ++i) {
    CatalogueImageRow& row = summary.images[i];
    row.detected = static_cast<int>(begin[i + 1] - begin[i]);
    if (row.ok) {
      std::vector<CraterPlacement> placements;
      for (size_t k = begin[i]; k < begin[i + 1]; ++k) {
        const Candidate& c = all[k];
        placements.push_back({c.fid, kept[k] != 0, c.center, c.diameter, c.scale});
      }
      row.kept = writer.Add(OpenCatalogueLayer(image_dirs[i] / "craters.gpkg"), row, placements);
    }
    row.duplicates_removed = row.detected - row.kept;
    (row.ok ? summary.images_ok : summary.images_failed) += 1;
    summary.detected += row.detected;
    summary.kept += row.kept;
    summary.duplicates_removed += row.duplicates_removed;
    report(image_dirs.size() + i + 1, "merge: write");
  }
  writer.Commit(summary.images);
  summary.crs_name = common ? common->name : std::string();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

nlohmann::json CatalogueMergeSummaryJson(const CatalogueMergeSummary& s) {
  nlohmann::json failed = nlohmann::json::array();
  for (const CatalogueImageRow& row : s.images) {
    if (!row.ok) failed.push_back({{"image", row.image}, {"error", row.error}});
  }
  return {{"images", s.images.size()},
          {"images_ok", s.images_ok},
          {"images_failed", s.images_failed},
          {"failed", failed},
          {"craters_detected", s.detected},
          {"craters_kept", s.kept},
          {"duplicates_removed", s.duplicates_removed},
          {"crs", s.crs_name},
          {"merge_seconds", s.seconds}};
}

}  // namespace areomap
