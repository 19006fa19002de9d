// One image of a crater catalogue over many images (`areomap craters IMAGE... --out DIR`): the
// crater job of crater_image.h run into the image's own folder, DIR/images/<folder>/, an
// independent unit whose result is files (a cluster runs one per task); the merge
// (crater_catalogue_merge.h) then reads every image's folder.
//
// An image folder holds craters.csv, craters.json, craters.gpkg (rims in the image's own
// projected Mars CRS), overlay.png and summary.json as `areomap craters IMAGE` writes them, and
// image.json: {"image", "status": "ok" | "failed", "error", "craters", "seconds", "warnings"}.
// A catalogue needs ground positions: an image without a geotransform and a projected Mars CRS
// (a plain PNG) fails with a message saying so. The catalogue's files and merge rules:
// docs/crater-catalogue.md.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "areomap/crater/crater_image.h"
#include "areomap/map/progress.h"

namespace areomap {

struct CatalogueImageRecord {
  std::string image;     // the raster's path as given
  bool ok = false;       // the job ran and wrote its files
  std::string error;     // why it failed; empty when ok
  int craters = 0;       // detected
  double seconds = 0.0;  // wall time of the job [s]
  std::vector<std::string> warnings;
};

// The folder of the `index`-th image (from 1) of a catalogue: the index with at least 3 digits
// and the file's stem, characters other than letters, digits, '.', '-' and '_' replaced by '_'
// ("007_MC11E-G"). Equal stems get distinct folders.
std::string CatalogueImageFolderName(int index, const std::filesystem::path& image);

// Runs the crater job (options with require_ground set) on `image` into `image_dir` (created if
// needed) and writes image.json last. A problem of the image (missing, unreadable, no ground
// positions, options that do not fit it) does not throw: the record and image.json say
// "failed" with the message, and the job's other files there are removed. Throws
// areomap::Error only when image_dir or image.json cannot be written. Progress: the sun
// estimate, then the detection.
CatalogueImageRecord RunCraterCatalogueImage(const std::filesystem::path& image,
                                             const std::filesystem::path& image_dir,
                                             const CraterImageOptions& options,
                                             const ProgressCallback& progress = nullptr);

// The images of a list file: one path a line, surrounding blanks trimmed, blank lines and lines
// starting with '#' skipped; relative paths as given (from the working directory). Throws
// areomap::Error naming the list and the line of a file that does not exist, or the list when it
// cannot be read.
std::vector<std::filesystem::path> ReadCatalogueImageList(const std::filesystem::path& list);

// Writes image_dir/image.json atomically (e.g. a runner recording an image that crashed).
void WriteCatalogueImageRecord(const std::filesystem::path& image_dir,
                               const CatalogueImageRecord& record);

// image_dir/image.json; throws areomap::Error naming the file when it is missing or malformed.
CatalogueImageRecord ReadCatalogueImageRecord(const std::filesystem::path& image_dir);

}  // namespace areomap
