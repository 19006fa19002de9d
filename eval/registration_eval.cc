// The registration decision on the evaluation set (registration_cases.h): per family and kind,
// positives accepted within 1 px and negatives accepted at the default max_false_match, and the
// reliability curve (stated false-match probability against the observed rate of accepted
// negatives) over thresholds. docs/benchmarks.md, "Registration decision", has the figures.
//
// Run: build/release/eval/areomap_eval_registration [--data DIR] [--seed N] [--cases N]
//        [--images N] [--trials N] [--csv FILE]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>

#include "registration_cases.h"

namespace {

using areomap::eval::CaseResult;

void PrintTable(const std::vector<CaseResult>& results, double alpha) {
  struct Count {
    int positives = 0, within = 0, wrong = 0, negatives = 0, false_accepts = 0;
  };
  std::map<std::string, Count> counts;
  for (const CaseResult& r : results) {
    for (const std::string& key :
         {r.family + " " + r.kind, r.family + " all", std::string("all")}) {
      Count& c = counts[key];
      if (r.positive) {
        ++c.positives;
        if (r.AcceptedAt(alpha) && r.error_px <= 1.0) ++c.within;
        if (r.AcceptedAt(alpha) && !(r.error_px <= 1.0)) ++c.wrong;
      } else {
        ++c.negatives;
        if (r.AcceptedAt(alpha)) ++c.false_accepts;
      }
    }
  }
  std::printf("max_false_match %g\n", alpha);
  std::printf(
      "| set | positives | accepted within 1 px | accepted > 1 px off | negatives | "
      "negatives accepted |\n|---|---|---|---|---|---|\n");
  for (const auto& [key, c] : counts) {
    std::printf("| %s | %d | %d (%.1f %%) | %d | %d | %d (%.2f %%) |\n", key.c_str(), c.positives,
                c.within, c.positives ? 100.0 * c.within / c.positives : 0.0, c.wrong, c.negatives,
                c.false_accepts, c.negatives ? 100.0 * c.false_accepts / c.negatives : 0.0);
  }
}

void PrintReliability(const std::vector<CaseResult>& results) {
  std::printf("\nReliability: stated false-match probability (threshold) vs observed\n");
  std::printf(
      "| max_false_match | negatives accepted (observed rate) | positives accepted within "
      "1 px |\n|---|---|---|\n");
  for (const double alpha : {1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 0.05, 0.1, 0.3, 1.0}) {
    int n = 0, fa = 0, p = 0, pa = 0;
    for (const CaseResult& r : results) {
      if (r.positive) {
        ++p;
        pa += r.AcceptedAt(alpha) && r.error_px <= 1.0;
      } else {
        ++n;
        fa += r.AcceptedAt(alpha);
      }
    }
    std::printf("| %g | %d / %d = %.4f | %d / %d = %.3f |\n", alpha, fa, n,
                n ? static_cast<double>(fa) / n : 0.0, pa, p,
                p ? static_cast<double>(pa) / p : 0.0);
  }
}

}  // namespace

int main(int argc, char** argv) {
  areomap::eval::CaseOptions options;
  std::string data = AREOMAP_SHARED_DATA_DIR, csv;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--data")
      data = value;
    else if (key == "--seed")
      options.seed = static_cast<uint32_t>(std::stoul(value));
    else if (key == "--cases")
      options.cases_per_image = std::stoi(value);
    else if (key == "--images")
      options.max_images_per_family = std::stoi(value);
    else if (key == "--trials")
      options.generated_trials = std::stoi(value);
    else if (key == "--csv")
      csv = value;
    else {
      std::fprintf(stderr, "error: unknown option %s\n", key.c_str());
      return 2;
    }
  }
  try {
    const areomap::OrbitalMatchOptions match;
    std::vector<CaseResult> real = areomap::eval::RunRealImageCases(data, options, match);
    std::vector<CaseResult> generated = areomap::eval::RunGeneratedCases(options, match);
    std::printf("Real images (%s), seed %u\n", data.c_str(), options.seed);
    PrintTable(real, match.max_false_match);
    PrintReliability(real);
    std::printf("\nGenerated, seed %u\n", options.seed);
    PrintTable(generated, match.max_false_match);
    PrintReliability(generated);
    if (!csv.empty()) {
      std::vector<CaseResult> all = real;
      all.insert(all.end(), generated.begin(), generated.end());
      std::ofstream(csv) << areomap::eval::CaseResultsCsv(all);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
