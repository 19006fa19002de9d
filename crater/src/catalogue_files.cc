#include "catalogue_files.h"

#include <cmath>
#include <iomanip>

#include "areomap/map/crs.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

// A CSV text field, quoted when it holds a comma, a quote or a line break (RFC 4180).
std::string CsvText(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) {
    quoted += c;
    if (c == '"') quoted += '"';
  }
  return quoted + "\"";
}

int FieldOrThrow(const CatalogueLayer& source, const char* name) {
  const int index = source.layer->GetLayerDefn()->GetFieldIndex(name);
  if (index < 0) {
    throw Error(source.path.string() + ": expected a column '" + name +
                "' in layer 'craters' (a crater catalogue areomap wrote)");
  }
  return index;
}

// The merged layer's own columns, before the image's.
constexpr const char* kSourceImage = "source_image";
constexpr const char* kSourceFolder = "source_folder";
constexpr const char* kSourceId = "source_id";
constexpr const char* kDiameterM = "diameter_m";

}  // namespace

CatalogueLayer OpenCatalogueLayer(const fs::path& gpkg) {
  GDALAllRegister();
  CatalogueLayer source;
  source.path = gpkg;
  std::error_code ec;
  if (!fs::is_regular_file(gpkg, ec)) {
    throw Error(gpkg.string() +
                ": no such file (the image is recorded ok in image.json; run it "
                "again)");
  }
  const char* drivers[] = {"GPKG", nullptr};
  source.dataset.reset(GDALDataset::Open(gpkg.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers,
                                         nullptr, nullptr));
  if (!source.dataset) throw Error(gpkg.string() + ": not a readable GeoPackage");
  source.layer = source.dataset->GetLayerByName("craters");
  if (source.layer == nullptr) throw Error(gpkg.string() + ": expected a layer 'craters'");
  if (source.layer->GetSpatialRef() == nullptr) {
    throw Error(gpkg.string() + ": layer 'craters' has no CRS");
  }
  return source;
}

CraterFieldIndex::CraterFieldIndex(const CatalogueLayer& s)
    : id(FieldOrThrow(s, "id")),
      map_x(FieldOrThrow(s, "map_x")),
      map_y(FieldOrThrow(s, "map_y")),
      semi_major_m(FieldOrThrow(s, "semi_major_m")),
      semi_minor_m(FieldOrThrow(s, "semi_minor_m")),
      diameter_px(FieldOrThrow(s, "diameter_px")),
      x_sigma_px(FieldOrThrow(s, "x_sigma_px")),
      y_sigma_px(FieldOrThrow(s, "y_sigma_px")),
      partial(FieldOrThrow(s, "partial")),
      rim_fitted(FieldOrThrow(s, "rim_fitted")) {}

CommonCrs::CommonCrs(const std::string& user_crs, const CatalogueLayer& first) {
  char* wkt = nullptr;
  first.layer->GetSpatialRef()->exportToWkt(
      &wkt, std::vector<const char*>{"FORMAT=WKT2_2019", nullptr}.data());
  const std::string first_wkt = wkt != nullptr ? wkt : "";
  CPLFree(wkt);
  const Crs crs = user_crs.empty() ? Crs::FromWkt(first_wkt, first.path.string())
                                   : Crs::FromUserInput(user_crs);
  crs.RequireMars();
  const CrsDescription d = crs.Describe();
  name = d.name;
  srs.importFromWkt(crs.Wkt().c_str());
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (!d.is_projected || std::abs(srs.GetLinearUnits() - 1.0) > 1e-12) {
    throw Error(crs.source() + ": the catalogue's CRS '" + name +
                "' is not a projected CRS in metres; a merge compares craters in metres (give "
                "images in a projected Mars CRS)");
  }
}

std::unique_ptr<OGRCoordinateTransformation> CommonCrs::TransformFrom(
    const CatalogueLayer& source) const {
  OGRSpatialReference from(*source.layer->GetSpatialRef());
  from.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (from.IsSame(&srs)) return nullptr;
  std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&from, &srs));
  if (!t) {
    throw Error(source.path.string() + ": PROJ finds no transformation from its CRS to '" + name +
                "'");
  }
  return t;
}

CatalogueWriter::CatalogueWriter(fs::path out_dir, const CommonCrs* common)
    : out_dir_(std::move(out_dir)), common_(common), csv_file_(out_dir_ / "craters.csv") {
  csv_.open(csv_file_.temp_path());
  if (!csv_) throw Error((out_dir_ / "craters.csv").string() + ": cannot write");
  csv_ << std::setprecision(10);
}

CatalogueWriter::~CatalogueWriter() = default;

void CatalogueWriter::Start(const OGRFeatureDefn& source_fields) {
  const fs::path path = out_dir_ / "craters.gpkg";
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (driver == nullptr) throw Error(path.string() + ": GDAL has no GPKG driver");
  gpkg_file_.emplace(path);
  gpkg_.reset(driver->Create(gpkg_file_->temp_path().c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  if (!gpkg_) throw Error(path.string() + ": cannot create GeoPackage");
  OGRSpatialReference srs(common_->srs);
  layer_ = gpkg_->CreateLayer("craters", &srs, wkbPolygon, nullptr);
  if (layer_ == nullptr) throw Error(path.string() + ": cannot create layer 'craters'");
  const auto create = [&](const OGRFieldDefn& f) {
    OGRFieldDefn copy(&f);
    if (layer_->CreateField(&copy) != OGRERR_NONE) {
      throw Error(path.string() + ": cannot create column '" + f.GetNameRef() + "'");
    }
  };
  create(OGRFieldDefn("id", OFTInteger64));
  create(OGRFieldDefn(kSourceImage, OFTString));
  create(OGRFieldDefn(kSourceFolder, OFTString));
  create(OGRFieldDefn(kSourceId, OFTInteger));
  create(OGRFieldDefn(kDiameterM, OFTReal));
  for (int k = 0; k < source_fields.GetFieldCount(); ++k) {
    const OGRFieldDefn* f = source_fields.GetFieldDefn(k);
    if (std::string(f->GetNameRef()) != "id") create(*f);
  }
  if (layer_->StartTransaction() != OGRERR_NONE) {
    throw Error(path.string() + ": cannot start a transaction");
  }
  const OGRFeatureDefn* defn = layer_->GetLayerDefn();
  for (int k = 0; k < defn->GetFieldCount(); ++k) {
    csv_ << (k > 0 ? "," : "") << defn->GetFieldDefn(k)->GetNameRef();
  }
  csv_ << "\n";
}

int CatalogueWriter::Add(const CatalogueLayer& source, const CatalogueImageRow& row,
                         const std::vector<CraterPlacement>& placements) {
  if (layer_ == nullptr) Start(*source.layer->GetLayerDefn());
  const CraterFieldIndex in(source);
  const OGRFeatureDefn* out_defn = layer_->GetLayerDefn();
  const OGRFeatureDefn* in_defn = source.layer->GetLayerDefn();
  std::vector<int> to(in_defn->GetFieldCount(), -1);
  for (int k = 0; k < in_defn->GetFieldCount(); ++k) {
    if (k != in.id) to[k] = out_defn->GetFieldIndex(in_defn->GetFieldDefn(k)->GetNameRef());
  }
  const auto transform = common_->TransformFrom(source);
  source.layer->ResetReading();
  size_t next = 0;
  int written = 0;
  for (auto& feature : *source.layer) {
    if (next >= placements.size() || placements[next].fid != feature->GetFID()) {
      throw Error(source.path.string() + ": changed while the catalogue was being merged");
    }
    const CraterPlacement& p = placements[next++];
    if (!p.keep) continue;
    OGRFeature out(layer_->GetLayerDefn());
    out.SetField("id", next_id_++);
    out.SetField(kSourceImage, row.image.c_str());
    out.SetField(kSourceFolder, row.folder.c_str());
    out.SetField(kSourceId, feature->GetFieldAsInteger(in.id));
    out.SetField(kDiameterM, p.diameter);
    for (int k = 0; k < in_defn->GetFieldCount(); ++k) {
      if (to[k] >= 0 && feature->IsFieldSetAndNotNull(k)) {
        out.SetField(to[k], feature->GetRawFieldRef(k));
      }
    }
    out.SetField("map_x", p.center.x());
    out.SetField("map_y", p.center.y());
    for (const int k : {in.semi_major_m, in.semi_minor_m}) {
      if (feature->IsFieldSetAndNotNull(k)) {
        out.SetField(to[k], feature->GetFieldAsDouble(k) * p.scale);
      }
    }
    if (const OGRGeometry* rim = feature->GetGeometryRef()) {
      std::unique_ptr<OGRGeometry> g(rim->clone());
      if (transform && g->transform(transform.get()) != OGRERR_NONE) {
        throw Error(source.path.string() + ": the rim of crater fid " +
                    std::to_string(feature->GetFID()) + " cannot be moved into " + common_->name);
      }
      out.SetGeometryDirectly(g.release());
    }
    if (layer_->CreateFeature(&out) != OGRERR_NONE) {
      throw Error((out_dir_ / "craters.gpkg").string() + ": cannot write a crater of " +
                  source.path.string());
    }
    WriteCsvRow(out);
    ++written;
  }
  if (next != placements.size()) {
    throw Error(source.path.string() + ": changed while the catalogue was being merged");
  }
  return written;
}

void CatalogueWriter::WriteCsvRow(const OGRFeature& feature) {
  const OGRFeatureDefn* defn = feature.GetDefnRef();
  for (int k = 0; k < defn->GetFieldCount(); ++k) {
    if (k > 0) csv_ << ",";
    if (!feature.IsFieldSetAndNotNull(k)) continue;
    switch (defn->GetFieldDefn(k)->GetType()) {
      case OFTInteger:
      case OFTInteger64:
        csv_ << feature.GetFieldAsInteger64(k);
        break;
      case OFTReal: {
        const double v = feature.GetFieldAsDouble(k);
        if (std::isfinite(v)) csv_ << v;
        break;
      }
      default:
        csv_ << CsvText(feature.GetFieldAsString(k));
    }
  }
  csv_ << "\n";
}

void CatalogueWriter::Commit(const std::vector<CatalogueImageRow>& images) {
  if (layer_ == nullptr)
    csv_ << "id," << kSourceImage << "," << kSourceFolder << "," << kSourceId << "," << kDiameterM
         << "\n";
  csv_.close();
  if (!csv_) throw Error((out_dir_ / "craters.csv").string() + ": cannot write");
  if (layer_ != nullptr) {
    if (layer_->CommitTransaction() != OGRERR_NONE) {
      throw Error((out_dir_ / "craters.gpkg").string() + ": cannot commit the craters");
    }
    gpkg_.reset();
  }
  std::ostringstream table;
  table << std::setprecision(6)
        << "folder,image,status,craters_detected,craters_kept,duplicates_removed,seconds,error\n";
  for (const CatalogueImageRow& r : images) {
    table << CsvText(r.folder) << "," << CsvText(r.image) << "," << (r.ok ? "ok" : "failed") << ","
          << r.detected << "," << r.kept << "," << r.duplicates_removed << "," << r.seconds << ","
          << CsvText(r.error) << "\n";
  }
  WriteFileAtomically(out_dir_ / "images.csv", table.str());
  csv_file_.Commit();
  if (gpkg_file_) gpkg_file_->Commit();
}

}  // namespace areomap
