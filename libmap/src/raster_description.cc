#include "areomap/map/raster_description.h"

namespace areomap {

RasterDescription DescribeRaster(const std::filesystem::path& path) {
  const RasterDataset dataset = RasterDataset::Open(path);
  RasterDescription out;
  out.info = dataset.info();
  for (const char* domain : {"json:PDS", "json:VICAR"}) {
    if (auto label = dataset.LabelJson(domain)) {
      out.product = ParseProductGeometry(*label, path.string());
      break;
    }
  }
  if (out.info.crs_wkt.empty() || !out.info.geotransform) return out;

  const Crs crs = Crs::FromWkt(out.info.crs_wkt, path.string());
  const CrsTransform transform(crs);
  out.crs = transform.description();
  const double w = out.info.width;
  const double h = out.info.height;
  const std::vector<std::pair<std::string, Eigen::Vector2d>> corners = {
      {"upper_left", {0.0, 0.0}},
      {"lower_left", {0.0, h}},
      {"upper_right", {w, 0.0}},
      {"lower_right", {w, h}},
      {"center", {w / 2.0, h / 2.0}}};
  for (const auto& [name, pixel] : corners) {
    CornerCoordinate corner;
    corner.name = name;
    corner.pixel = pixel;
    corner.map = out.info.geotransform->PixelToMap(pixel.x(), pixel.y());
    corner.own_lon_lat_deg = transform.ToOwnGeographic(corner.map);
    corner.planetocentric = transform.ToPlanetocentric(corner.map);
    out.corners.push_back(std::move(corner));
  }
  return out;
}

}  // namespace areomap
