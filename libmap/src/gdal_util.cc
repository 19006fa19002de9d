#include "gdal_util.h"

#include <mutex>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>

namespace areomap::internal {

void EnsureGdalInitialized() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    if (CPLGetConfigOption("GDAL_CACHEMAX", nullptr) == nullptr) GDALSetCacheMax64(kGdalCacheBytes);
  });
}

QuietGdalErrors::QuietGdalErrors() {
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
}

QuietGdalErrors::~QuietGdalErrors() { CPLPopErrorHandler(); }

std::string LastGdalError() {
  const char* message = CPLGetLastErrorMsg();
  return (message != nullptr && *message != '\0') ? std::string(message)
                                                  : std::string("no detail from GDAL");
}

}  // namespace areomap::internal
