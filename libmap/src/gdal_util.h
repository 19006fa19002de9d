// Private helpers around GDAL's global state (driver registration, error handler).
#pragma once

#include <string>

namespace areomap::internal {

// GDAL's block cache unless the user sets GDAL_CACHEMAX [bytes]. GDAL's own default is 5 % of
// the machine's memory (1.2 GB on a 24 GB machine), which a strip-by-strip read of a large
// raster fills with blocks it never reads again; every areomap reader works in windows, so a
// small cache costs no speed and bounds memory by the work, not the raster.
inline constexpr long long kGdalCacheBytes = 128LL << 20;

// Registers GDAL drivers once per process (thread-safe) and sets the block cache to
// kGdalCacheBytes where the environment does not set GDAL_CACHEMAX.
void EnsureGdalInitialized();

// While alive, GDAL errors go to no console (libraries never print); the last message is kept
// for our own exception text through LastGdalError().
class QuietGdalErrors {
 public:
  QuietGdalErrors();
  ~QuietGdalErrors();
  QuietGdalErrors(const QuietGdalErrors&) = delete;
  QuietGdalErrors& operator=(const QuietGdalErrors&) = delete;
};

// GDAL's last error message, or "no detail from GDAL".
std::string LastGdalError();

}  // namespace areomap::internal
