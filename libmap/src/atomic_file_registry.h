// The temporary files of the AtomicFile objects alive in this process, for a signal handler to
// remove (libmap internal: OutputFolder's SIGINT / SIGTERM handler).
#pragma once

namespace areomap::internal {

// Removes every registered temporary file; async-signal-safe (unlink only).
void RemoveAtomicTempsInHandler();

}  // namespace areomap::internal
