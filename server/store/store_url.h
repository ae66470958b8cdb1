// Which store a daemon opens, chosen by a URL as Optuna's and SQLAlchemy's users know it:
//   sqlite:///springfit.db             the embedded store, a file relative to the working dir
//   sqlite:////var/lib/springfit/s.db  the same with an absolute path
//   postgresql://USER@HOST[:PORT]/DB   a PostgreSQL database several daemons share (libpq's
//                                      URI: ?host=/run/postgresql for a Unix socket)
// A password never goes in the URL (it would show in `ps` and in logs): a file, or libpq's
// own PGPASSWORD and PGPASSFILE.
#pragma once
#include <memory>
#include <string>

#include "server/store/job_store.h"

namespace springfit::server {

struct StoreLocation {
  enum class Kind { kSqlite, kPostgres };
  Kind kind = Kind::kSqlite;
  std::string path;               // kSqlite: the database file
  std::string url;                // kPostgres: the URI as given (no password)
  std::string password;           // kPostgres: from a file; empty: libpq's defaults
  double timeout_seconds = 10.0;  // kPostgres: every call's bound (--store-timeout)
};

// Throws std::runtime_error naming what is wrong with the URL.
StoreLocation ParseStoreUrl(const std::string& url);
// The first line of the file, without its line ending; throws when unreadable or empty.
std::string ReadPasswordFile(const std::string& path);
// Opens (and creates or migrates) the store; throws std::runtime_error with the reason.
std::unique_ptr<JobStore> OpenStore(const StoreLocation& location);

}  // namespace springfit::server
