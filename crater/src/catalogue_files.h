// The files of the crater catalogue merge (crater_catalogue_merge.h): reading an image's
// craters.gpkg through OGR, the common CRS, and writing the merged craters.gpkg, craters.csv and
// images.csv. Failure: areomap::Error naming the file and what was expected.
#pragma once

#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <Eigen/Core>

#include "areomap/crater/crater_catalogue_merge.h"
#include "areomap/map/atomic_file.h"

namespace areomap {

// Layer "craters" of an image's craters.gpkg (WriteCratersGeoPackage), open for reading.
struct CatalogueLayer {
  std::filesystem::path path;
  GDALDatasetUniquePtr dataset;
  OGRLayer* layer = nullptr;
};

// Throws when the file is missing, not a GeoPackage, or has no layer "craters" with a CRS.
CatalogueLayer OpenCatalogueLayer(const std::filesystem::path& gpkg);

// The columns of a crater layer that the merge reads; throws naming the file and a missing column.
struct CraterFieldIndex {
  explicit CraterFieldIndex(const CatalogueLayer& source);
  int id, map_x, map_y, semi_major_m, semi_minor_m, diameter_px, x_sigma_px, y_sigma_px, partial,
      rim_fitted;
};

// The merged catalogue's CRS: the one given (user text), else the first merged layer's. Must be
// a projected Mars CRS in metres.
class CommonCrs {
 public:
  CommonCrs(const std::string& user_crs, const CatalogueLayer& first);
  // From `source`'s CRS into this one; null when they are the same CRS.
  std::unique_ptr<OGRCoordinateTransformation> TransformFrom(const CatalogueLayer& source) const;

  OGRSpatialReference srs;  // traditional GIS axis order
  std::string name;
};

// Where one crater of an image lands in the merged catalogue.
struct CraterPlacement {
  GIntBig fid = 0;         // its feature in the image's craters.gpkg
  bool keep = false;       // kept (not a duplicate)
  Eigen::Vector2d center;  // common CRS [m]
  double diameter = 0.0;   // [m of the common CRS]
  double scale = 1.0;      // common metres per image-CRS metre
};

// Writes craters.gpkg and craters.csv (created at the first image added) and images.csv.
class CatalogueWriter {
 public:
  // `common` null: no image is ok, no craters.gpkg.
  CatalogueWriter(std::filesystem::path out_dir, const CommonCrs* common);
  ~CatalogueWriter();
  // Writes the kept craters of `source`, whose features in reading order are `placements`;
  // returns how many.
  int Add(const CatalogueLayer& source, const CatalogueImageRow& row,
          const std::vector<CraterPlacement>& placements);
  // Writes images.csv and moves the three files into place.
  void Commit(const std::vector<CatalogueImageRow>& images);

 private:
  void Start(const OGRFeatureDefn& source_fields);
  void WriteCsvRow(const OGRFeature& feature);

  std::filesystem::path out_dir_;
  const CommonCrs* common_;
  std::optional<AtomicFile> gpkg_file_;
  GDALDatasetUniquePtr gpkg_;
  OGRLayer* layer_ = nullptr;
  AtomicFile csv_file_;
  std::ofstream csv_;
  GIntBig next_id_ = 1;
};

}  // namespace areomap
