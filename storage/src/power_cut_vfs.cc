// The power-cut VFS (ambdiag/storage/power_cut.h). Writes go to the real
// file at once (the file is the page cache's view, which every connection
// of the process reads); for each tracked file the VFS keeps, since its last
// fsync, the list of writes and truncations with the bytes they replaced.
// The cut undoes them in reverse order and cuts the file back to its size at
// the last fsync, which restores the synced image exactly; with a seed it
// then re-applies a random subset of them in their order.
#include "ambdiag/storage/power_cut.h"

#include <fcntl.h>
#include <signal.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace ambdiag::storage::power_cut {
namespace {

struct Op {
  bool truncate = false;
  sqlite3_int64 offset = 0;           // write offset, or the new size of a truncation
  std::vector<unsigned char> before;  // the bytes it replaced (up to the old end of file)
  std::vector<unsigned char> after;   // a write's bytes
};

struct FileState {
  sqlite3_int64 synced_size = 0;
  std::vector<Op> pending;  // since the last fsync, in order
};

struct State {
  std::mutex mu;
  Plan plan;
  std::map<std::string, FileState> files;  // by path: every handle of a file shares one page cache
  std::uint64_t writes = 0, syncs = 0;
  sqlite3_vfs* base = nullptr;
  sqlite3_vfs vfs{};
  bool installed = false;
};

State& state() {
  static State s;
  return s;
}

std::atomic<bool> g_signalled{false};
extern "C" void on_cut_signal(int) { g_signalled = true; }

// Under s.mu, before a write or fsync: is this the moment?
bool due(State& s, Plan::Count what, std::uint64_t n) {
  if (s.plan.count == Plan::Count::signal) return g_signalled.load();
  return s.plan.count == what && n == s.plan.at;
}

struct ShimFile {
  sqlite3_file base;   // pMethods: the shim's
  std::string* path;   // tracked file, else null
  sqlite3_file* real;  // the unix VFS's file, in the same allocation after this struct
};

sqlite3_int64 size_of(sqlite3_file* f) {
  sqlite3_int64 n = 0;
  return f->pMethods->xFileSize(f, &n) == SQLITE_OK ? n : 0;
}

std::vector<unsigned char> read_range(sqlite3_file* f, sqlite3_int64 from, sqlite3_int64 to) {
  std::vector<unsigned char> out;
  if (to <= from) return out;
  out.resize(static_cast<size_t>(to - from));
  f->pMethods->xRead(f, out.data(), static_cast<int>(out.size()), from);  // a short read fills with zeros
  return out;
}

void put(int fd, const std::vector<unsigned char>& bytes, sqlite3_int64 offset) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::pwrite(fd, bytes.data() + done, bytes.size() - done, offset + static_cast<off_t>(done));
    if (n <= 0) ::_exit(kExitCode + 1);  // the simulation itself failed: say so by another code
    done += static_cast<size_t>(n);
  }
}

// The power fails: every tracked file as the disk holds it, then the process ends.
[[noreturn]] void cut(State& s) {
  std::mt19937_64 rng(s.plan.seed.value_or(0));
  for (auto& [path, f] : s.files) {
    const int fd = ::open(path.c_str(), O_RDWR);
    if (fd < 0) continue;  // deleted meanwhile
    for (auto it = f.pending.rbegin(); it != f.pending.rend(); ++it)
      put(fd, it->before, it->offset);
    if (::ftruncate(fd, f.synced_size) != 0) ::_exit(kExitCode + 1);
    if (s.plan.seed)
      for (const Op& op : f.pending) {
        if (rng() & 1) continue;  // lost
        if (op.truncate) {
          if (::ftruncate(fd, op.offset) != 0) ::_exit(kExitCode + 1);
        } else {
          put(fd, op.after, op.offset);
        }
      }
    ::fsync(fd);
    ::close(fd);
  }
  std::fprintf(stderr, "ambdiag: simulated power cut after %llu writes and %llu fsyncs of the database files\n",
               static_cast<unsigned long long>(s.writes), static_cast<unsigned long long>(s.syncs));
  ::_exit(kExitCode);  // holds s.mu: no other thread writes on the way out
}

ShimFile* shim(sqlite3_file* f) { return reinterpret_cast<ShimFile*>(f); }

int x_close(sqlite3_file* f) {
  ShimFile* p = shim(f);
  const int rc = p->real->pMethods->xClose(p->real);
  delete p->path;
  return rc;
}
int x_read(sqlite3_file* f, void* buf, int n, sqlite3_int64 off) {
  return shim(f)->real->pMethods->xRead(shim(f)->real, buf, n, off);
}
int x_write(sqlite3_file* f, const void* buf, int n, sqlite3_int64 off) {
  ShimFile* p = shim(f);
  if (!p->path) return p->real->pMethods->xWrite(p->real, buf, n, off);
  State& s = state();
  std::lock_guard lock(s.mu);
  ++s.writes;
  if (due(s, Plan::Count::writes, s.writes)) cut(s);
  Op op;
  op.offset = off;
  op.before = read_range(p->real, off, std::min<sqlite3_int64>(off + n, size_of(p->real)));
  op.after.assign(static_cast<const unsigned char*>(buf), static_cast<const unsigned char*>(buf) + n);
  const int rc = p->real->pMethods->xWrite(p->real, buf, n, off);
  if (rc == SQLITE_OK) s.files[*p->path].pending.push_back(std::move(op));
  return rc;
}
int x_truncate(sqlite3_file* f, sqlite3_int64 size) {
  ShimFile* p = shim(f);
  if (!p->path) return p->real->pMethods->xTruncate(p->real, size);
  State& s = state();
  std::lock_guard lock(s.mu);
  Op op;
  op.truncate = true;
  op.offset = size;
  op.before = read_range(p->real, size, size_of(p->real));
  const int rc = p->real->pMethods->xTruncate(p->real, size);
  if (rc == SQLITE_OK) s.files[*p->path].pending.push_back(std::move(op));
  return rc;
}
int x_sync(sqlite3_file* f, int flags) {
  ShimFile* p = shim(f);
  if (!p->path) return p->real->pMethods->xSync(p->real, flags);
  State& s = state();
  std::lock_guard lock(s.mu);
  ++s.syncs;
  if (due(s, Plan::Count::syncs, s.syncs)) cut(s);
  const int rc = p->real->pMethods->xSync(p->real, flags);
  if (rc == SQLITE_OK) {
    FileState& st = s.files[*p->path];
    st.pending.clear();
    st.synced_size = size_of(p->real);
  }
  return rc;
}
int x_file_size(sqlite3_file* f, sqlite3_int64* n) { return shim(f)->real->pMethods->xFileSize(shim(f)->real, n); }
int x_lock(sqlite3_file* f, int l) { return shim(f)->real->pMethods->xLock(shim(f)->real, l); }
int x_unlock(sqlite3_file* f, int l) { return shim(f)->real->pMethods->xUnlock(shim(f)->real, l); }
int x_check_reserved(sqlite3_file* f, int* out) {
  return shim(f)->real->pMethods->xCheckReservedLock(shim(f)->real, out);
}
int x_file_control(sqlite3_file* f, int op, void* arg) {
  return shim(f)->real->pMethods->xFileControl(shim(f)->real, op, arg);
}
int x_sector_size(sqlite3_file* f) { return shim(f)->real->pMethods->xSectorSize(shim(f)->real); }
int x_device(sqlite3_file* f) { return shim(f)->real->pMethods->xDeviceCharacteristics(shim(f)->real); }
int x_shm_map(sqlite3_file* f, int pg, int sz, int extend, void volatile** out) {
  return shim(f)->real->pMethods->xShmMap(shim(f)->real, pg, sz, extend, out);
}
int x_shm_lock(sqlite3_file* f, int offset, int n, int flags) {
  return shim(f)->real->pMethods->xShmLock(shim(f)->real, offset, n, flags);
}
void x_shm_barrier(sqlite3_file* f) { shim(f)->real->pMethods->xShmBarrier(shim(f)->real); }
int x_shm_unmap(sqlite3_file* f, int del) { return shim(f)->real->pMethods->xShmUnmap(shim(f)->real, del); }
// No memory-mapped reads: every read goes through x_read (mmap_size is 0 anyway).
int x_fetch(sqlite3_file*, sqlite3_int64, int, void** out) {
  *out = nullptr;
  return SQLITE_OK;
}
int x_unfetch(sqlite3_file*, sqlite3_int64, void*) { return SQLITE_OK; }

const sqlite3_io_methods kMethods = {3,          x_close,       x_read,        x_write,   x_truncate,
                                     x_sync,     x_file_size,   x_lock,        x_unlock,  x_check_reserved,
                                     x_file_control, x_sector_size, x_device,  x_shm_map, x_shm_lock,
                                     x_shm_barrier, x_shm_unmap, x_fetch,      x_unfetch};

int x_open(sqlite3_vfs*, sqlite3_filename name, sqlite3_file* f, int flags, int* out_flags) {
  State& s = state();
  ShimFile* p = shim(f);
  p->real = reinterpret_cast<sqlite3_file*>(p + 1);
  p->path = nullptr;
  f->pMethods = nullptr;
  const int rc = s.base->xOpen(s.base, name, p->real, flags, out_flags);
  if (rc != SQLITE_OK) return rc;
  // The files a power cut can damage: the database and its log (or journal).
  if (name && (flags & (SQLITE_OPEN_MAIN_DB | SQLITE_OPEN_WAL | SQLITE_OPEN_MAIN_JOURNAL))) {
    p->path = new std::string(name);
    std::lock_guard lock(s.mu);
    if (!s.files.count(*p->path)) s.files[*p->path].synced_size = size_of(p->real);  // on disk as found
  }
  f->pMethods = &kMethods;
  return SQLITE_OK;
}

int x_delete(sqlite3_vfs*, const char* name, int sync_dir) {
  State& s = state();
  const int rc = s.base->xDelete(s.base, name, sync_dir);
  std::lock_guard lock(s.mu);
  s.files.erase(name);  // a deletion counts as durable
  return rc;
}

}  // namespace

void install(const Plan& plan) {
  if ((plan.count == Plan::Count::writes || plan.count == Plan::Count::syncs) && plan.at == 0)
    throw std::invalid_argument("power_cut::install: the cut needs a count >= 1");
  State& s = state();
  std::lock_guard lock(s.mu);
  s.plan = plan;
  if (plan.count == Plan::Count::signal) {
    struct sigaction sa {};
    sa.sa_handler = on_cut_signal;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGUSR2, &sa, nullptr);
  }
  if (s.installed) return;
  s.base = sqlite3_vfs_find(nullptr);
  s.vfs = *s.base;  // the unix VFS's own calls (paths, time, randomness) as they are
  s.vfs.zName = "ambdiag-powercut";
  s.vfs.szOsFile = static_cast<int>(sizeof(ShimFile)) + s.base->szOsFile;
  s.vfs.pNext = nullptr;
  s.vfs.xOpen = x_open;
  s.vfs.xDelete = x_delete;
  if (sqlite3_vfs_register(&s.vfs, 1) != SQLITE_OK) throw std::runtime_error("power_cut: sqlite3_vfs_register failed");
  s.installed = true;
}

void install_from_env() {
  const char* v = std::getenv("AMBDIAG_POWER_CUT");
  if (!v || !*v) return;
  Plan plan;
  const std::string text = v;
  const auto colon = text.find(':');
  const std::string kind = text.substr(0, colon);
  if (kind == "track" && colon == std::string::npos) {
    plan.count = Plan::Count::none;
    std::atexit([] {
      std::fprintf(stderr, "ambdiag: power-cut VFS saw %llu writes and %llu fsyncs of the database files\n",
                   static_cast<unsigned long long>(writes_seen()), static_cast<unsigned long long>(syncs_seen()));
    });
  } else if (kind == "signal" && colon == std::string::npos) {
    plan.count = Plan::Count::signal;
  } else if ((kind == "writes" || kind == "syncs") && colon != std::string::npos) {
    plan.count = kind == "writes" ? Plan::Count::writes : Plan::Count::syncs;
    char* end = nullptr;
    plan.at = std::strtoull(text.c_str() + colon + 1, &end, 10);
    if (*end || plan.at == 0) throw std::invalid_argument("AMBDIAG_POWER_CUT: the count must be an integer >= 1");
  } else {
    throw std::invalid_argument("AMBDIAG_POWER_CUT: must be track, signal, writes:N or syncs:N, not '" + text + "'");
  }
  if (const char* seed = std::getenv("AMBDIAG_POWER_CUT_SEED"); seed && *seed) {
    char* end = nullptr;
    plan.seed = std::strtoull(seed, &end, 10);
    if (*end) throw std::invalid_argument("AMBDIAG_POWER_CUT_SEED: must be an unsigned integer");
  }
  install(plan);
}

std::uint64_t writes_seen() {
  std::lock_guard lock(state().mu);
  return state().writes;
}

std::uint64_t syncs_seen() {
  std::lock_guard lock(state().mu);
  return state().syncs;
}

}  // namespace ambdiag::storage::power_cut
