// The rock matching of two sites as one job: MatchSitePair (rock_matching.h) on the two sites'
// rocks, and its files. What `areomap rocks match` and the mission run's leg units both run, so
// the two write the same files from the same match.
//
// Files (atomically) into `dir`, which must exist: matches.csv (WriteRockMatchesCsv),
// tie_points.json (the adjustment's input format, bundle_io.h), faults.json and faults.txt
// (PairFaultReport). Frames and units as in rock_matching.h. Failure: throws areomap::Error for bad
// options or a file that cannot be written; a pair that does not match is a result (its fault
// report's outcome).
#pragma once

#include <filesystem>

#include "areomap/landmarks/rock_matching.h"

namespace areomap {

SitePairMatch MatchRockPair(const SiteRocks& a, const SiteRocks& b, const RockMatchingPrior& prior,
                            const RockMatchingOptions& options, const std::filesystem::path& dir);

}  // namespace areomap
