// A SQLite VFS for tests that loses what was not synced, as a power cut does (in the spirit
// of leveldb's fault-injection Env).
//
// Every file opened through it is held in memory, as the operating system's page cache
// holds it: reads see every write, from any connection of the process, but a write reaches
// the real file only when SQLite syncs that file (xSync). PowerLossVfs::Cut() is the power
// cut: from then on nothing reaches the disk (the writes and syncs of connections still
// open, their closing checkpoints included, go nowhere), and once they are closed the
// memory images are dropped. Whatever SQLite did not sync is gone; a store opened on the
// same path afterwards sees only what was.
//
// What it does not model: a torn write inside one sync (a sync is all or nothing here), and
// directory entries (a file created exists at once, a deleted one is gone at once).
#pragma once

#include <string>

namespace springfit::testing {

class PowerLossVfs {
 public:
  // Registers the VFS as SQLite's default for this process (every database opened after it,
  // by any library, goes through it); unregisters it, restoring the previous default, when
  // destroyed. One at a time.
  PowerLossVfs();
  ~PowerLossVfs();
  PowerLossVfs(const PowerLossVfs&) = delete;
  PowerLossVfs& operator=(const PowerLossVfs&) = delete;

  // The power cut. Close every connection, then call Restore() before opening anew.
  void Cut();
  // Power back: the memory images are dropped, and files are read from the disk again.
  void Restore();

  // Syncs of a file whose name ends with `suffix` so far ("-wal", ".db").
  int Syncs(const std::string& suffix) const;
};

}  // namespace springfit::testing
