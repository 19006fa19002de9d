#include "areomap/pipeline/rock_pair.h"

#include <nlohmann/json.hpp>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/landmarks/rock_output.h"
#include "areomap/map/atomic_file.h"

namespace areomap {

SitePairMatch MatchRockPair(const SiteRocks& a, const SiteRocks& b, const RockMatchingPrior& prior,
                            const RockMatchingOptions& options, const std::filesystem::path& dir) {
  SitePairMatch match = MatchSitePair(a, b, prior, options);
  WriteFileAtomically(dir / "faults.json", match.report.ToJson().dump(2));
  WriteFileAtomically(dir / "faults.txt", match.report.ToText());
  WriteRockMatchesCsv(dir / "matches.csv", a, b, match);
  WriteFileAtomically(dir / "tie_points.json",
                      nlohmann::json{{"tie_points", TiePointsToJson(match.tie_points)}}.dump(2));
  return match;
}

}  // namespace areomap
