// PointCloud files: binary little-endian PLY that PDAL, CloudCompare and MeshLab open.
//
// Layout (one `vertex` element, one record per StereoPoint, in this order):
//   double x y z                                   position [m] in the cloud's frame
//   double cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz   covariance upper triangle [m^2]
//   float  intensity                               left-image value in [0, 1]
//   float  left_x left_y                           left-image pixel (pixel centres at integers)
//   ushort image_id                                stereo pair of the site
// The header carries the cloud's metadata as comments:
//   comment areomap_frame <free text>
//   comment areomap_site <int>
//   comment areomap_camera_center <x> <y> <z>      [m], printed with 17 significant digits
// so a write → read round trip is exact.
//
// The reader accepts the properties in any order and in any PLY scalar type (so files edited by
// other tools still load), but every property above must be present.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>

#include "areomap/map/point_cloud.h"

namespace areomap {

// Writes `cloud` atomically (temporary name, then rename). Throws areomap::Error naming `path`
// when the cloud holds a non-finite point (CheckPointCloud; an empty cloud is allowed), the frame
// text contains a line break, or the file cannot be written. Nothing is left under `path` on
// failure.
void WritePointCloudPly(const PointCloud& cloud, const std::filesystem::path& path);

// Reads a file written by WritePointCloudPly. Throws areomap::Error naming the file and the field
// (header line, property, vertex index) when the file is missing, not binary little-endian PLY,
// lacks a property or the metadata comments, is truncated, or holds a non-finite point.
PointCloud ReadPointCloudPly(const std::filesystem::path& path);
// Same from a seekable binary stream; `source` names it in errors.
PointCloud ReadPointCloudPly(std::istream& in, const std::string& source);

}  // namespace areomap
