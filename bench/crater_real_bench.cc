// Crater detection quality on real labelled images, four detectors in one run, each with its
// default options and no per-image flags: the combined default of `areomap craters`, the learned
// detector alone, the edge detector alone (the sun estimated from the image as `areomap craters`
// does for both that use it) and OpenCV's HoughCircles.
// Usage:
//   areomap_bench_crater_real [DATA_DIR]     (default ../shared/data)
// Images: craters/ (HRSC north half, never trained on), each hrsc-bandeira crop (HRSC, measured
// only), and the three ctx-mc11e images held out of training (C, F, L; labels that >= 2 of the
// six annotators agreed on). Scored for craters >= 8 px with crater_score.h's rule; per diameter
// bin for the HRSC image. Results: docs/benchmarks.md (Craters), docs/crater-model.md.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_raster.h"
#include "areomap/crater/crater_score.h"
#include "areomap/crater/learned_detector.h"
#include "areomap/crater/sun_azimuth.h"
#include "areomap/map/csv.h"
#include "areomap/map/error.h"

namespace {

namespace fs = std::filesystem;
using areomap::CraterCircle;
using areomap::CraterScore;

struct LabelledImage {
  std::string set;
  fs::path image;
  std::vector<CraterCircle> truth;
};

// x_px, y_px, diameter_px and, where present, annotators (kept when >= min_annotators).
std::vector<CraterCircle> ReadLabels(const fs::path& path, int min_annotators) {
  std::ifstream in(path);
  if (!in) throw areomap::Error(path.string() + ": cannot read the labels");
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = areomap::SplitCsvLine(line);
  int annotators_col = -1;
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == "annotators") annotators_col = static_cast<int>(i);
  }
  std::vector<CraterCircle> out;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = areomap::SplitCsvLine(line);
    if (f.size() < 3) continue;
    if (annotators_col >= 0 && std::stoi(f[static_cast<size_t>(annotators_col)]) < min_annotators)
      continue;
    out.push_back({{std::stod(f[0]), std::stod(f[1])}, std::stod(f[2])});
  }
  return out;
}

std::vector<LabelledImage> Images(const fs::path& data) {
  std::vector<LabelledImage> images;
  images.push_back({"hrsc-north", data / "craters/hrsc_nanedi_north.png",
                    ReadLabels(data / "craters/hrsc_nanedi_north_craters.csv", 0)});
  for (const char* tile : {"tile1_24", "tile1_25", "tile2_24", "tile3_24", "tile3_25"}) {
    const fs::path dir = data / "craters-train/hrsc-bandeira";
    images.push_back({"hrsc-bandeira", dir / (std::string(tile) + ".png"),
                      ReadLabels(dir / (std::string(tile) + "_craters.csv"), 0)});
  }
  for (const char* letter : {"C", "F", "L"}) {
    const fs::path dir = data / "craters-train/ctx-mc11e";
    const std::string stem = std::string("MC11E-") + letter;
    images.push_back(
        {"ctx-held-out", dir / (stem + ".png"), ReadLabels(dir / (stem + "_craters.csv"), 2)});
  }
  return images;
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<CraterCircle> Learned(const areomap::RasterDataset& dataset) {
  areomap::CraterDetectorOptions options;
  options.method = areomap::CraterMethod::kLearned;
  return areomap::CirclesOf(
      areomap::DetectCratersInRaster(dataset, areomap::RimSource::kImage, options));
}

// `method` with the sun estimated as `areomap craters` does for the edge detector.
std::vector<CraterCircle> WithEstimatedSun(const areomap::RasterDataset& dataset,
                                           areomap::CraterMethod method) {
  areomap::CraterDetectorOptions options;
  options.method = method;
  const areomap::SunAzimuthEstimate sun = areomap::EstimateSunAzimuthInRaster(dataset, options);
  if (sun.reliable) options.sun_azimuth_deg = sun.azimuth_deg;
  return areomap::CirclesOf(
      areomap::DetectCratersInRaster(dataset, areomap::RimSource::kImage, options));
}

std::vector<CraterCircle> Edges(const areomap::RasterDataset& dataset) {
  return WithEstimatedSun(dataset, areomap::CraterMethod::kEdges);
}

// The default of `areomap craters` on images.
std::vector<CraterCircle> Combined(const areomap::RasterDataset& dataset) {
  return WithEstimatedSun(dataset, areomap::CraterMethod::kCombined);
}

// HoughCircles on the 8-bit image after a 1 px Gaussian blur, for 8-200 px rims.
std::vector<CraterCircle> Hough(const areomap::RasterDataset& dataset) {
  const cv::Mat image = dataset.ReadWindowFloat(1, dataset.FullWindow());
  cv::Mat gray, blurred;
  cv::normalize(image, gray, 0, 255, cv::NORM_MINMAX, CV_8U);
  cv::GaussianBlur(gray, blurred, cv::Size(), 1.0);
  std::vector<cv::Vec3f> circles;
  cv::HoughCircles(blurred, circles, cv::HOUGH_GRADIENT, 1.0, 6.0, 100, 20, 4, 100);
  std::vector<CraterCircle> out;
  for (const cv::Vec3f& c : circles) out.push_back({{c[0] + 0.5, c[1] + 0.5}, 2.0 * c[2]});
  return out;
}

struct Tally {
  int truth = 0, detected = 0, matched_truth = 0, matched_detected = 0;
  void Add(const areomap::CraterMatchStats& s) {
    truth += s.truth;
    detected += s.detected;
    matched_truth += s.matched_truth;
    matched_detected += s.matched_detected;
  }
  double Precision() const { return detected ? double(matched_detected) / detected : 0.0; }
  double Recall() const { return truth ? double(matched_truth) / truth : 0.0; }
  double F1() const {
    const double p = Precision(), r = Recall();
    return p + r > 0.0 ? 2.0 * p * r / (p + r) : 0.0;
  }
};

}  // namespace

int main(int argc, char** argv) {
  const fs::path data = argc > 1 ? fs::path(argv[1]) : fs::path("../shared/data");
  try {
    const std::vector<LabelledImage> images = Images(data);
    const std::vector<double> bins = {8.0, 16.0, 32.0, 64.0, 1e9};
    using Detector = std::vector<CraterCircle> (*)(const areomap::RasterDataset&);
    const std::vector<std::pair<const char*, Detector>> detectors = {
        {"combined", Combined}, {"learned", Learned}, {"edges", Edges}, {"hough", Hough}};
    std::printf("craters >= 8 px; match: centre < 0.5 x true radius, diameter within 30 %%\n");
    std::printf("%-14s %-16s %-8s %6s %6s %7s %7s %7s %8s\n", "set", "image", "method", "truth",
                "det", "P", "R", "F1", "wall_s");
    std::vector<std::vector<Tally>> pooled(detectors.size());
    std::vector<std::string> sets;
    for (const LabelledImage& image : images) {
      const areomap::RasterDataset dataset = areomap::RasterDataset::Open(image.image);
      for (size_t k = 0; k < detectors.size(); ++k) {
        const auto start = std::chrono::steady_clock::now();
        const std::vector<CraterCircle> found = detectors[k].second(dataset);
        const double wall = Seconds(start);
        const CraterScore s = areomap::ScoreCraters(image.truth, found, bins);
        std::printf("%-14s %-16s %-8s %6d %6d %7.3f %7.3f %7.3f %8.2f\n", image.set.c_str(),
                    image.image.stem().c_str(), detectors[k].first, s.all.truth, s.all.detected,
                    s.all.precision, s.all.recall, s.all.f1, wall);
        if (image.set == "hrsc-north") {
          for (const auto& b : s.bins) {
            std::printf("%-14s   %5.0f-%-8.0f %-8s %6d %6d %7.3f %7.3f %7.3f\n", "", b.min_diameter,
                        b.max_diameter, detectors[k].first, b.truth, b.detected, b.precision,
                        b.recall, b.f1);
          }
        }
        const auto set = std::find(sets.begin(), sets.end(), image.set);
        const size_t set_index = static_cast<size_t>(set - sets.begin());
        if (set == sets.end()) sets.push_back(image.set);
        for (auto& p : pooled) p.resize(sets.size());
        pooled[k][set_index].Add(s.all);
      }
    }
    std::printf("\npooled per set (craters >= 8 px)\n%-14s %-8s %6s %6s %7s %7s %7s\n", "set",
                "method", "truth", "det", "P", "R", "F1");
    for (size_t s = 0; s < sets.size(); ++s) {
      for (size_t k = 0; k < detectors.size(); ++k) {
        const Tally& t = pooled[k][s];
        std::printf("%-14s %-8s %6d %6d %7.3f %7.3f %7.3f\n", sets[s].c_str(), detectors[k].first,
                    t.truth, t.detected, t.Precision(), t.Recall(), t.F1());
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
