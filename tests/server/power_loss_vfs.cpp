#include "tests/server/power_loss_vfs.h"

#include <sqlite3.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <stdexcept>

namespace springfit::testing {
namespace {

// A file as the page cache holds it.
struct Image {
  std::mutex mutex;
  std::string bytes;
};

struct VfsState {
  sqlite3_vfs vfs{};
  sqlite3_vfs* real = nullptr;
  std::mutex mutex;
  std::map<std::string, std::shared_ptr<Image>> images;  // by full path
  std::map<std::string, int> syncs;                      // by full path
  std::atomic<bool> cut{false};
};
VfsState* state = nullptr;

// Our part of an open file; the real VFS's file follows it in the same allocation.
struct LossyFile {
  sqlite3_file base;
  std::shared_ptr<Image> image;  // null: a temporary file, passed through
  std::string path;
};

// The most bytes handed to the real VFS's xRead or xWrite at once: the unix VFS masks sizes
// above 128 KiB.
constexpr std::size_t kPiece = 64 * 1024;

constexpr int RealOffset() {
  return static_cast<int>((sizeof(LossyFile) + 15) / 16 * 16);
}

LossyFile* Lossy(sqlite3_file* f) {
  return reinterpret_cast<LossyFile*>(f);
}
sqlite3_file* Real(sqlite3_file* f) {
  return reinterpret_cast<sqlite3_file*>(reinterpret_cast<char*>(f) + RealOffset());
}

int Close(sqlite3_file* f) {
  sqlite3_file* real = Real(f);
  const int rc = real->pMethods ? real->pMethods->xClose(real) : SQLITE_OK;
  Lossy(f)->~LossyFile();
  return rc;
}

int Read(sqlite3_file* f, void* out, int amount, sqlite3_int64 offset) {
  LossyFile* file = Lossy(f);
  if (!file->image) return Real(f)->pMethods->xRead(Real(f), out, amount, offset);
  std::lock_guard lock(file->image->mutex);
  const std::string& bytes = file->image->bytes;
  const auto size = static_cast<sqlite3_int64>(bytes.size());
  const sqlite3_int64 available = std::clamp<sqlite3_int64>(size - offset, 0, amount);
  if (available > 0) std::memcpy(out, bytes.data() + offset, static_cast<std::size_t>(available));
  if (available < amount) {
    std::memset(static_cast<char*>(out) + available, 0,
                static_cast<std::size_t>(amount - available));
    return SQLITE_IOERR_SHORT_READ;
  }
  return SQLITE_OK;
}

int Write(sqlite3_file* f, const void* data, int amount, sqlite3_int64 offset) {
  LossyFile* file = Lossy(f);
  if (!file->image) return Real(f)->pMethods->xWrite(Real(f), data, amount, offset);
  std::lock_guard lock(file->image->mutex);
  std::string& bytes = file->image->bytes;
  const auto end = static_cast<std::size_t>(offset + amount);
  if (bytes.size() < end) bytes.resize(end, '\0');
  std::memcpy(bytes.data() + offset, data, static_cast<std::size_t>(amount));
  return SQLITE_OK;
}

int Truncate(sqlite3_file* f, sqlite3_int64 size) {
  LossyFile* file = Lossy(f);
  if (!file->image) return Real(f)->pMethods->xTruncate(Real(f), size);
  std::lock_guard lock(file->image->mutex);
  file->image->bytes.resize(static_cast<std::size_t>(size), '\0');
  return SQLITE_OK;
}

// The one way anything reaches the disk: the file's image, whole, then the real sync.
int Sync(sqlite3_file* f, int flags) {
  LossyFile* file = Lossy(f);
  sqlite3_file* real = Real(f);
  if (!file->image) return real->pMethods->xSync(real, flags);
  if (state->cut.load()) return SQLITE_OK;
  {
    std::lock_guard lock(state->mutex);
    ++state->syncs[file->path];
  }
  std::lock_guard lock(file->image->mutex);
  const std::string& bytes = file->image->bytes;
  int rc = real->pMethods->xTruncate(real, static_cast<sqlite3_int64>(bytes.size()));
  // In pieces: the unix VFS writes at most 128 KiB per call (it masks larger sizes).
  for (std::size_t at = 0; rc == SQLITE_OK && at < bytes.size(); at += kPiece) {
    const std::size_t n = std::min(kPiece, bytes.size() - at);
    rc = real->pMethods->xWrite(real, bytes.data() + at, static_cast<int>(n),
                                static_cast<sqlite3_int64>(at));
  }
  if (rc == SQLITE_OK) rc = real->pMethods->xSync(real, flags);
  return rc;
}

int FileSize(sqlite3_file* f, sqlite3_int64* size) {
  LossyFile* file = Lossy(f);
  if (!file->image) return Real(f)->pMethods->xFileSize(Real(f), size);
  std::lock_guard lock(file->image->mutex);
  *size = static_cast<sqlite3_int64>(file->image->bytes.size());
  return SQLITE_OK;
}

int Lock(sqlite3_file* f, int level) {
  return Real(f)->pMethods->xLock(Real(f), level);
}
int Unlock(sqlite3_file* f, int level) {
  return Real(f)->pMethods->xUnlock(Real(f), level);
}
int CheckReservedLock(sqlite3_file* f, int* out) {
  return Real(f)->pMethods->xCheckReservedLock(Real(f), out);
}
int FileControl(sqlite3_file* f, int op, void* arg) {
  // A size hint would extend the real file at once, outside the sync.
  if (op == SQLITE_FCNTL_SIZE_HINT && Lossy(f)->image) return SQLITE_NOTFOUND;
  return Real(f)->pMethods->xFileControl(Real(f), op, arg);
}
int SectorSize(sqlite3_file* f) {
  return Real(f)->pMethods->xSectorSize(Real(f));
}
int DeviceCharacteristics(sqlite3_file* f) {
  // Nothing that would let SQLite skip a sync.
  return Real(f)->pMethods->xDeviceCharacteristics(Real(f)) & ~SQLITE_IOCAP_SEQUENTIAL;
}
// The WAL index (-shm) is shared memory, rebuilt from the WAL after a crash: passed through.
int ShmMap(sqlite3_file* f, int region, int size, int extend, void volatile** out) {
  return Real(f)->pMethods->xShmMap(Real(f), region, size, extend, out);
}
int ShmLock(sqlite3_file* f, int offset, int n, int flags) {
  return Real(f)->pMethods->xShmLock(Real(f), offset, n, flags);
}
void ShmBarrier(sqlite3_file* f) {
  Real(f)->pMethods->xShmBarrier(Real(f));
}
int ShmUnmap(sqlite3_file* f, int delete_flag) {
  return Real(f)->pMethods->xShmUnmap(Real(f), delete_flag);
}

const sqlite3_io_methods kMethods = {
    2,  // no xFetch: every read goes through Read, over the image
    Close,       Read,       Write,
    Truncate,    Sync,       FileSize,
    Lock,        Unlock,     CheckReservedLock,
    FileControl, SectorSize, DeviceCharacteristics,
    ShmMap,      ShmLock,    ShmBarrier,
    ShmUnmap,    nullptr,    nullptr,
};

int Open(sqlite3_vfs*, sqlite3_filename name, sqlite3_file* f, int flags, int* out_flags) {
  sqlite3_file* real = Real(f);
  std::memset(real, 0, static_cast<std::size_t>(state->real->szOsFile));
  f->pMethods = nullptr;
  const int rc = state->real->xOpen(state->real, name, real, flags, out_flags);
  if (rc != SQLITE_OK) {
    if (real->pMethods) real->pMethods->xClose(real);
    return rc;
  }
  auto* file = new (f) LossyFile{};
  file->base.pMethods = &kMethods;
  if (!name) return SQLITE_OK;  // a temporary file: never read back after a crash
  file->path = name;
  std::lock_guard lock(state->mutex);
  std::shared_ptr<Image>& image = state->images[file->path];
  if (!image) {
    // First opened since the power came back: the disk's content.
    image = std::make_shared<Image>();
    sqlite3_int64 size = 0;
    real->pMethods->xFileSize(real, &size);
    image->bytes.resize(static_cast<std::size_t>(size));
    // In pieces, as Sync writes (the unix VFS handles at most 128 KiB per call).
    for (std::size_t at = 0; at < image->bytes.size(); at += kPiece) {
      const std::size_t n = std::min(kPiece, image->bytes.size() - at);
      if (real->pMethods->xRead(real, image->bytes.data() + at, static_cast<int>(n),
                                static_cast<sqlite3_int64>(at)) != SQLITE_OK) {
        state->images.erase(file->path);
        Close(f);
        f->pMethods = nullptr;
        return SQLITE_IOERR_READ;
      }
    }
  }
  file->image = image;
  return SQLITE_OK;
}

int Delete(sqlite3_vfs*, const char* name, int sync_dir) {
  if (state->cut.load()) return SQLITE_OK;  // nothing reaches the disk any more
  {
    std::lock_guard lock(state->mutex);
    state->images.erase(name);
  }
  return state->real->xDelete(state->real, name, sync_dir);
}

}  // namespace

PowerLossVfs::PowerLossVfs() {
  if (state) throw std::logic_error("one PowerLossVfs at a time");
  state = new VfsState;
  state->real = sqlite3_vfs_find(nullptr);
  state->vfs = *state->real;  // the real one's path, time and randomness functions
  state->vfs.szOsFile = RealOffset() + state->real->szOsFile;
  state->vfs.zName = "springfit-power-loss";
  state->vfs.pNext = nullptr;
  state->vfs.xOpen = Open;
  state->vfs.xDelete = Delete;
  sqlite3_vfs_register(&state->vfs, /*makeDflt=*/1);
}

PowerLossVfs::~PowerLossVfs() {
  sqlite3_vfs_unregister(&state->vfs);
  sqlite3_vfs_register(state->real, /*makeDflt=*/1);
  delete state;
  state = nullptr;
}

void PowerLossVfs::Cut() {
  state->cut.store(true);
}

void PowerLossVfs::Restore() {
  std::lock_guard lock(state->mutex);
  state->images.clear();
  state->cut.store(false);
}

int PowerLossVfs::Syncs(const std::string& suffix) const {
  std::lock_guard lock(state->mutex);
  int n = 0;
  for (const auto& [path, count] : state->syncs) {
    if (path.size() >= suffix.size() &&
        path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0)
      n += count;
  }
  return n;
}

}  // namespace springfit::testing
