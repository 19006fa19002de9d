// Private helpers around GDAL's global state (driver registration, error handler).
#pragma once

#include <string>

namespace areomap::internal {

// Registers GDAL drivers once per process (thread-safe).
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
