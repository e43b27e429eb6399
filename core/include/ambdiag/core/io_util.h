// Small file helpers shared by the readers and writers.
#pragma once

#include <string>

namespace ambdiag {

// Reads a whole file; throws InputError naming the path if it cannot.
std::string read_file_bytes(const std::string& path);
// Writes via a temporary file in the same folder, fsync and rename, so a
// crash leaves either the old file or the new one, never half of either.
void write_file_atomic(const std::string& path, const std::string& bytes);

}  // namespace ambdiag
