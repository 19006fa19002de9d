#include "areomap/crater/crater_score.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/map/numbers.h"

namespace areomap {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return m;
}

bool InBin(double d, double lo, double hi) { return d >= lo && d < hi; }

CraterMatchStats Stats(const std::vector<CraterCircle>& truth,
                       const std::vector<CraterCircle>& detections,
                       const std::vector<int>& truth_match, const std::vector<int>& det_match,
                       double lo, double hi) {
  CraterMatchStats s;
  s.min_diameter = lo;
  s.max_diameter = hi;
  std::vector<double> center_errors, diameter_errors;
  for (size_t t = 0; t < truth.size(); ++t) {
    if (!InBin(truth[t].diameter, lo, hi)) continue;
    ++s.truth;
    if (truth_match[t] < 0) continue;
    ++s.matched_truth;
    const CraterCircle& d = detections[static_cast<size_t>(truth_match[t])];
    center_errors.push_back((d.center - truth[t].center).norm());
    diameter_errors.push_back(std::abs(d.diameter / truth[t].diameter - 1.0));
  }
  for (size_t k = 0; k < detections.size(); ++k) {
    if (!InBin(detections[k].diameter, lo, hi)) continue;
    ++s.detected;
    if (det_match[k] >= 0) ++s.matched_detected;
  }
  s.precision = s.detected > 0 ? static_cast<double>(s.matched_detected) / s.detected : kNaN;
  s.recall = s.truth > 0 ? static_cast<double>(s.matched_truth) / s.truth : kNaN;
  s.f1 =
      s.precision + s.recall > 0.0 ? 2.0 * s.precision * s.recall / (s.precision + s.recall) : 0.0;
  s.median_center_error = Median(center_errors);
  s.median_diameter_error = Median(diameter_errors);
  return s;
}

}  // namespace

CraterScore ScoreCraters(const std::vector<CraterCircle>& truth,
                         const std::vector<CraterCircle>& detections,
                         const std::vector<double>& bin_edges) {
  if (bin_edges.size() < 2 || !std::is_sorted(bin_edges.begin(), bin_edges.end())) {
    throw Error("crater score: bin edges must be at least two ascending diameters");
  }
  struct Candidate {
    double cost;
    int t, d;
  };
  std::vector<Candidate> candidates;
  for (size_t t = 0; t < truth.size(); ++t) {
    const double radius = 0.5 * truth[t].diameter;
    for (size_t d = 0; d < detections.size(); ++d) {
      const double distance = (detections[d].center - truth[t].center).norm();
      const double ratio = detections[d].diameter / truth[t].diameter;
      if (distance < 0.5 * radius && ratio >= 0.7 && ratio <= 1.3) {
        candidates.push_back(
            {distance / radius + std::abs(ratio - 1.0), static_cast<int>(t), static_cast<int>(d)});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.cost < b.cost; });
  std::vector<int> truth_match(truth.size(), -1), det_match(detections.size(), -1);
  CraterScore score;
  for (const Candidate& c : candidates) {
    if (truth_match[static_cast<size_t>(c.t)] >= 0 || det_match[static_cast<size_t>(c.d)] >= 0) {
      continue;
    }
    truth_match[static_cast<size_t>(c.t)] = c.d;
    det_match[static_cast<size_t>(c.d)] = c.t;
    score.matches.emplace_back(c.t, c.d);
  }
  score.all = Stats(truth, detections, truth_match, det_match, bin_edges.front(), bin_edges.back());
  for (size_t i = 0; i + 1 < bin_edges.size(); ++i) {
    score.bins.push_back(
        Stats(truth, detections, truth_match, det_match, bin_edges[i], bin_edges[i + 1]));
  }
  return score;
}

std::vector<CraterCircle> ReadCraterCsv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open crater CSV");
  return ReadCraterCsv(in, path.string());
}

std::vector<CraterCircle> ReadCraterCsv(std::istream& in, const std::string& source) {
  std::string line;
  if (!std::getline(in, line)) throw Error(source + ": empty file, expected a CSV header");
  std::vector<std::string> header = SplitCsvLine(line);
  for (std::string& cell : header) {
    cell.erase(std::remove_if(cell.begin(), cell.end(), ::isspace), cell.end());
  }
  const auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) {
      throw Error(source + ": header has no column '" + name +
                  "' (expected x_px, y_px, diameter_px)");
    }
    return static_cast<size_t>(it - header.begin());
  };
  const size_t cx = column("x_px"), cy = column("y_px"), cd = column("diameter_px");
  std::vector<CraterCircle> craters;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::vector<std::string> cells = SplitCsvLine(line);
    const auto value = [&](size_t i) {
      if (i >= cells.size()) {
        throw Error(source + " line " + std::to_string(line_number) + ": too few columns");
      }
      try {
        size_t used = 0;
        const double v = std::stod(cells[i], &used);
        if (std::isfinite(v)) return v;
      } catch (const std::exception&) {
      }
      throw Error(source + " line " + std::to_string(line_number) + ": '" + cells[i] +
                  "' is not a finite number");
    };
    CraterCircle c{{value(cx), value(cy)}, value(cd)};
    if (!(c.diameter > 0.0)) {
      throw Error(source + " line " + std::to_string(line_number) + ": diameter_px must be > 0");
    }
    craters.push_back(c);
  }
  return craters;
}

std::vector<CraterCircle> CirclesOf(const std::vector<Ellipse>& ellipses) {
  std::vector<CraterCircle> circles;
  circles.reserve(ellipses.size());
  for (const Ellipse& e : ellipses) circles.push_back({e.center, e.semi_major + e.semi_minor});
  return circles;
}

std::vector<CraterCircle> CirclesOf(const std::vector<CraterDetection>& detections) {
  std::vector<CraterCircle> circles;
  circles.reserve(detections.size());
  for (const CraterDetection& d : detections) circles.push_back({d.ellipse.center, d.Diameter()});
  return circles;
}

}  // namespace areomap
