#include <cctype>
#include <chrono>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "areomap/crater/crater_catalogue.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

// Every file the crater job writes into an image folder besides image.json.
constexpr const char* kJobFiles[] = {"craters.csv", "craters.json", "craters.gpkg", "overlay.png",
                                     "summary.json"};

nlohmann::json RecordJson(const CatalogueImageRecord& r) {
  return {{"image", r.image},     {"status", r.ok ? "ok" : "failed"},
          {"error", r.error},     {"craters", r.craters},
          {"seconds", r.seconds}, {"warnings", r.warnings}};
}

}  // namespace

std::string CatalogueImageFolderName(int index, const fs::path& image) {
  std::string stem = image.stem().string();
  for (char& c : stem) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (!(std::isalnum(u) || c == '.' || c == '-' || c == '_')) c = '_';
  }
  std::ostringstream name;
  name << std::setw(3) << std::setfill('0') << index << "_" << stem;
  return name.str();
}

CatalogueImageRecord RunCraterCatalogueImage(const fs::path& image, const fs::path& image_dir,
                                             const CraterImageOptions& options,
                                             const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  fs::create_directories(image_dir, ec);
  if (ec) throw Error(image_dir.string() + ": cannot create the image folder: " + ec.message());
  CatalogueImageRecord record;
  record.image = image.string();
  try {
    CraterImageOptions o = options;
    o.require_ground = true;
    const CraterImageJob job = PrepareCraterImage(image, o, SubProgress(progress, 0.0, 0.3));
    const CraterImageResult result =
        DetectCraterImage(job, image_dir, SubProgress(progress, 0.3, 1.0));
    WriteFileAtomically(image_dir / "summary.json",
                        CraterImageSummaryJson(job, result).dump(2) + "\n");
    record.ok = true;
    record.craters = result.craters;
    record.warnings = job.warnings;
    record.warnings.insert(record.warnings.end(), result.warnings.begin(), result.warnings.end());
  } catch (const std::exception& e) {
    record.ok = false;
    record.error = e.what();
    for (const char* name : kJobFiles) fs::remove(image_dir / name, ec);
  }
  record.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  WriteCatalogueImageRecord(image_dir, record);
  return record;
}

void WriteCatalogueImageRecord(const fs::path& image_dir, const CatalogueImageRecord& record) {
  WriteFileAtomically(image_dir / "image.json", RecordJson(record).dump(2) + "\n");
}

std::vector<fs::path> ReadCatalogueImageList(const fs::path& list) {
  std::ifstream in(list);
  if (!in) throw Error(list.string() + ": cannot read the image list");
  std::vector<fs::path> images;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const fs::path image = line.substr(first, line.find_last_not_of(" \t\r") + 1 - first);
    std::error_code ec;
    if (!fs::exists(image, ec)) {
      throw Error(list.string() + " line " + std::to_string(number) + ": " + image.string() +
                  ": no such file");
    }
    images.push_back(image);
  }
  if (in.bad()) throw Error(list.string() + ": cannot read the image list");
  return images;
}

CatalogueImageRecord ReadCatalogueImageRecord(const fs::path& image_dir) {
  const fs::path path = image_dir / "image.json";
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open (the image was not run into this folder)");
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  CatalogueImageRecord r;
  try {
    if (j.is_discarded()) throw std::runtime_error("not JSON");
    r.image = j.at("image").get<std::string>();
    const std::string status = j.at("status").get<std::string>();
    if (status != "ok" && status != "failed") throw std::runtime_error("status " + status);
    r.ok = status == "ok";
    r.error = j.at("error").get<std::string>();
    r.craters = j.at("craters").get<int>();
    r.seconds = j.at("seconds").get<double>();
    r.warnings = j.value("warnings", std::vector<std::string>{});
  } catch (const std::exception& e) {
    throw Error(path.string() +
                ": expected an image record (image, status ok|failed, error, craters, seconds): " +
                e.what());
  }
  return r;
}

}  // namespace areomap
