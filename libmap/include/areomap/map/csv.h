// Plain comma-separated text as areomap writes and reads it (truth tables, catalogues): no
// quoting, no escaped commas. Fields are returned as written; callers parse and name the file
// and line in their errors.
#pragma once

#include <string>
#include <vector>

namespace areomap {

// Splits one line at every comma; a trailing '\r' (a CRLF file) is dropped. "" gives no fields.
std::vector<std::string> SplitCsvLine(const std::string& line);

}  // namespace areomap
