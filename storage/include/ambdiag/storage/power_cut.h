// A simulated power cut of the server host, for tests (docs/storage.md,
// "Durability"). A SQLite VFS ("ambdiag-powercut", a shim over the default
// unix VFS) passes every call through and remembers, per database and log
// file, what was written since the file's last fsync. At the cut it puts
// back the bytes and size each file had at its last fsync, which is what a
// disk keeps when the power fails (the page cache is lost), and the process
// ends at once with exit code kExitCode: the way SQLite's own crash tests
// model a power failure. With a seed, a random subset of the writes since
// the last fsync survives instead (a disk cache writes back in any order).
//
// Off unless asked for. The storage library reads the environment when it
// opens its first connection:
//   AMBDIAG_POWER_CUT=writes:N  cut just before the N-th write (counted over
//   AMBDIAG_POWER_CUT=syncs:N   all tracked files of the process), or fsync
//   AMBDIAG_POWER_CUT=signal    cut at the first write or fsync after SIGUSR2
//                               (a test picks the moment, e.g. while a job runs)
//   AMBDIAG_POWER_CUT=track     the VFS without a cut (a baseline); prints the
//                               writes and fsyncs seen when the process exits
//   AMBDIAG_POWER_CUT_SEED=S    keep a random half of the unsynced writes
// Tests in one process may call install() instead, before opening.
#pragma once

#include <cstdint>
#include <optional>

namespace ambdiag::storage::power_cut {

inline constexpr int kExitCode = 86;  // the process ended by a simulated power cut

struct Plan {
  enum class Count { none, writes, syncs, signal };
  Count count = Count::none;
  std::uint64_t at = 0;                  // the N-th write or fsync (1-based)
  std::optional<std::uint64_t> seed;     // keep a seeded random subset of the unsynced writes
};

// Registers the VFS as the process' default (once) and sets the plan; every
// connection opened afterwards goes through it. Throws std::invalid_argument
// for a plan counting writes or syncs with at == 0. Count::signal installs a
// SIGUSR2 handler (it only sets a flag; the cut happens in the next write or
// fsync of a tracked file).
void install(const Plan& plan);
// Reads AMBDIAG_POWER_CUT and AMBDIAG_POWER_CUT_SEED; installs if set.
// Throws std::invalid_argument naming the variable for a bad value.
void install_from_env();

// Writes and fsyncs seen so far on tracked files (0 when not installed).
std::uint64_t writes_seen();
std::uint64_t syncs_seen();

}  // namespace ambdiag::storage::power_cut
