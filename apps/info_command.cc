// areomap info FILE...: what a raster is and where it lies on Mars.
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "areomap/map/error.h"
#include "areomap/map/raster.h"
#include "areomap/map/raster_description.h"
#include "commands.h"

namespace areomap::cli {
namespace {

nlohmann::json ToJson(const RasterDescription& d, LongitudeDomain domain) {
  nlohmann::json j;
  j["file"] = d.info.path.string();
  j["driver"] = d.info.driver;
  j["width"] = d.info.width;
  j["height"] = d.info.height;
  j["bands"] = d.info.band_count;
  j["data_type"] = d.info.data_type;
  j["nodata"] = d.info.nodata ? nlohmann::json(*d.info.nodata) : nlohmann::json();
  j["scale"] = d.info.scale;
  j["offset"] = d.info.offset;
  if (d.info.geotransform) j["geotransform"] = d.info.geotransform->c;
  if (d.crs) {
    const CrsDescription& c = *d.crs;
    j["crs"] = {{"name", c.name},
                {"authority", c.authority},
                {"is_mars", c.is_mars},
                {"ellipsoid", c.ellipsoid_name},
                {"semi_major_m", c.body.a},
                {"semi_minor_m", c.body.b},
                {"is_sphere", c.body.IsSphere()},
                {"latitude_type", ToString(c.latitude_type)},
                {"longitude_direction", ToString(c.longitude_direction)},
                {"projection", c.projection_method},
                {"parameters", c.projection_parameters}};
  }
  for (const CornerCoordinate& corner : d.corners) {
    nlohmann::json cj = {{"name", corner.name},
                         {"pixel", {corner.pixel.x(), corner.pixel.y()}},
                         {"map", {corner.map.x(), corner.map.y()}}};
    if (corner.own_lon_lat_deg) {
      cj["own_lon_deg"] = corner.own_lon_lat_deg->x();
      cj["own_lat_deg"] = corner.own_lon_lat_deg->y();
    }
    if (corner.planetocentric) {
      cj["planetocentric_lat_deg"] = DegFromRad(corner.planetocentric->lat);
      cj["east_lon_deg"] = DegFromRad(WrapLongitude(corner.planetocentric->lon, domain));
    }
    j["corners"].push_back(cj);
  }
  if (d.product) {
    nlohmann::json p;
    p["instrument_id"] = d.product->instrument_id;
    if (d.product->camera) {
      p["camera_model"] = {{"type", d.product->camera->model_type},
                           {"reference_frame", d.product->camera->reference_frame},
                           {"components", d.product->camera->components}};
    }
    for (const CoordinateFrameLabel& f : d.product->frames) {
      const auto& q = f.label_quaternion_wxyz;
      const auto& t = f.reference_from_frame.translation;
      p["frames"].push_back({{"group", f.group},
                             {"frame", f.name},
                             {"reference_frame", f.reference_frame},
                             {"index", f.index},
                             {"quaternion_wxyz", q},
                             {"offset_m", {t.x(), t.y(), t.z()}}});
    }
    j["product"] = p;
  }
  return j;
}

std::string Text(const RasterDescription& d, LongitudeDomain domain) {
  std::ostringstream out;
  out << std::setprecision(10);
  out << d.info.path.string() << "\n";
  out << "  driver " << d.info.driver << ", " << d.info.width << " x " << d.info.height << " px, "
      << d.info.band_count << " band(s) of " << d.info.data_type;
  if (d.info.nodata) out << ", nodata " << *d.info.nodata;
  if (d.info.scale != 1.0 || d.info.offset != 0.0) {
    out << ", value = " << d.info.scale << " * stored + " << d.info.offset;
  }
  out << "\n";
  if (!d.crs) {
    out << "  no CRS (not georeferenced)\n";
  } else {
    const CrsDescription& c = *d.crs;
    out << "  CRS: " << c.name << (c.authority.empty() ? "" : " (" + c.authority + ")") << "\n";
    out << "    body: " << (c.is_mars ? "Mars" : "NOT Mars") << ", " << c.ellipsoid_name
        << (c.body.IsSphere() ? ", sphere R = " : ", ellipsoid a = ") << c.body.a << " m";
    if (!c.body.IsSphere()) out << ", b = " << c.body.b << " m";
    out << "\n    latitude " << ToString(c.latitude_type) << ", longitude positive "
        << ToString(c.longitude_direction) << "\n";
    if (c.is_projected) {
      out << "    projection: " << c.projection_method;
      for (const auto& [name, value] : c.projection_parameters)
        out << ", " << name << " = " << value;
      out << "\n";
    }
    if (d.info.geotransform) {
      out << "    pixel size: " << d.info.geotransform->c[1] << " x " << -d.info.geotransform->c[5]
          << " (CRS units)\n";
    }
  }
  if (!d.corners.empty()) {
    out << "  corners: map x, y | planetocentric lat, east lon ("
        << (domain == LongitudeDomain::kZeroTo360 ? "0-360" : "+-180") << ") [deg]\n";
    for (const CornerCoordinate& corner : d.corners) {
      out << "    " << std::left << std::setw(12) << corner.name << std::right << std::fixed
          << std::setprecision(3) << std::setw(16) << corner.map.x() << std::setw(16)
          << corner.map.y() << " | ";
      if (corner.planetocentric) {
        out << std::setprecision(8) << std::setw(13) << DegFromRad(corner.planetocentric->lat)
            << std::setw(14) << DegFromRad(WrapLongitude(corner.planetocentric->lon, domain));
      } else {
        out << "outside the projection";
      }
      out << std::defaultfloat << std::setprecision(10) << "\n";
    }
  }
  if (d.product) {
    if (!d.product->instrument_id.empty())
      out << "  instrument: " << d.product->instrument_id << "\n";
    if (d.product->camera) {
      out << "  camera model " << d.product->camera->model_type << " in "
          << d.product->camera->reference_frame << ":\n";
      for (const auto& [id, values] : d.product->camera->components) {
        out << "    " << id << " =";
        for (double v : values) out << " " << v;
        out << "\n";
      }
    }
    for (const CoordinateFrameLabel& f : d.product->frames) {
      const auto& q = f.label_quaternion_wxyz;
      const auto& t = f.reference_from_frame.translation;
      out << "  frame " << f.name << " -> " << f.reference_frame << ": q(wxyz) = " << q[0] << " "
          << q[1] << " " << q[2] << " " << q[3] << ", offset = " << t.x() << " " << t.y() << " "
          << t.z() << " m\n";
    }
  }
  return out.str();
}

// Fraction of band 1's pixels that are valid (finite, not nodata): every pixel is read, in
// strips (ReadDecimated), so memory stays small whatever the raster's size.
double ValidFraction(const std::string& file) {
  const RasterDataset dataset = RasterDataset::Open(file);
  const RasterInfo& info = dataset.info();
  const int factor = DecimationFactor(info.width, info.height, 1024);
  int64_t valid = 0;
  ReadDecimated(dataset, dataset.FullWindow(), factor, &valid);
  // ReadDecimated reads whole blocks only: the pixels it read are the blocks' pixels.
  const double read = static_cast<double>(info.width / factor * factor) *
                      static_cast<double>(info.height / factor * factor);
  return read > 0.0 ? static_cast<double>(valid) / read : 0.0;
}

}  // namespace

// What `areomap info --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kInfoDetails =
    "Size, type, nodata, the share of valid pixels of band 1 (a warning when there is none), the\n"
    "CRS in Mars terms (body, radii, latitude type, longitude direction, projection), corner\n"
    "coordinates in planetocentric latitude / east longitude; for MER products the camera model\n"
    "(CAHV/CAHVOR/CAHVORE components) and the frames named in the label (e.g. `ROVER_FRAME ->\n"
    "SITE_FRAME` quaternion and offset). `--json` for scripts, `--lon-domain 180|360`. Reads\n"
    "GeoTIFF, PDS3 `.IMG`, ISIS3 `.cub`, VICAR, JPEG 2000, PNG — anything GDAL reads.";

void AddInfoCommand(CLI::App& app, const GlobalOptions& /*global*/) {
  auto* cmd = app.add_subcommand(
      "info", "Describe rasters: size, type, Mars CRS, corner coordinates, camera and frames");
  cmd->footer(kInfoDetails);
  auto files = std::make_shared<std::vector<std::string>>();
  auto json = std::make_shared<bool>(false);
  auto domain = std::make_shared<std::string>("360");
  cmd->add_option("files", *files, "Rasters (GeoTIFF, PDS3 .IMG, ISIS3 .cub, VICAR, JP2, PNG...)")
      ->required();
  cmd->add_flag("--json", *json, "Print one JSON document instead of text");
  cmd->add_option("--lon-domain", *domain, "Longitude domain of printed corners: 180 or 360")
      ->check(CLI::IsMember({"180", "360"}))
      ->capture_default_str();
  cmd->callback([files, json, domain] {
    const LongitudeDomain lon_domain = LongitudeDomainFromString(*domain);
    nlohmann::json all = nlohmann::json::array();
    int failures = 0;
    for (const std::string& file : *files) {
      try {
        const RasterDescription d = DescribeRaster(file);
        const double valid = ValidFraction(file);
        if (*json) {
          all.push_back(ToJson(d, lon_domain));
          all.back()["valid_fraction_band1"] = valid;
        } else {
          std::cout << Text(d, lon_domain) << "  valid pixels (band 1): " << std::fixed
                    << std::setprecision(1) << 100.0 * valid << " %\n"
                    << std::defaultfloat;
        }
        if (valid == 0.0) {
          std::fprintf(stderr,
                       "warning: %s: band 1 has no valid pixel (every pixel is nodata or "
                       "NaN)\n",
                       file.c_str());
        }
      } catch (const Error& e) {
        // One bad file does not hide the others; the exit status reports it.
        if (files->size() == 1) throw;
        std::fprintf(stderr, "error: %s\n", e.what());
        ++failures;
      }
    }
    if (*json) std::cout << all.dump(2) << "\n";
    if (failures > 0) throw CLI::RuntimeError(1);
  });
}

}  // namespace areomap::cli
