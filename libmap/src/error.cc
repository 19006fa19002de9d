#include "areomap/map/error.h"

namespace areomap {

void RequireOption(bool ok, std::string_view field, std::string_view rule) {
  if (!ok) throw Error(std::string(field) + " is invalid: expected " + std::string(rule));
}

}  // namespace areomap
