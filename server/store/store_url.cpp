#include "server/store/store_url.h"

#include <fstream>
#include <stdexcept>

#include "server/store/postgres_store.h"
#include "server/store/sqlite_store.h"

namespace springfit::server {
namespace {

bool StartsWith(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

}  // namespace

StoreLocation ParseStoreUrl(const std::string& url) {
  StoreLocation location;
  if (StartsWith(url, "sqlite:///")) {
    location.kind = StoreLocation::Kind::kSqlite;
    location.path = url.substr(std::string("sqlite:///").size());
    if (location.path.empty())
      throw std::runtime_error("--store " + url + ": no database file after sqlite:///");
    return location;
  }
  if (StartsWith(url, "sqlite:")) {
    throw std::runtime_error("--store " + url +
                             ": a SQLite URL is sqlite:///FILE (relative) or sqlite:////ABS/FILE");
  }
  if (StartsWith(url, "postgresql://") || StartsWith(url, "postgres://")) {
    const std::size_t scheme_end = url.find("://") + 3;
    const std::size_t authority_end = url.find_first_of("/?", scheme_end);
    const std::string authority = url.substr(scheme_end, authority_end - scheme_end);
    const std::size_t at = authority.rfind('@');
    // USER:PASSWORD@ or ?password=: refused, and not echoed.
    if ((at != std::string::npos && authority.substr(0, at).find(':') != std::string::npos) ||
        url.find("password=") != std::string::npos) {
      throw std::runtime_error(
          "--store: the PostgreSQL URL holds a password; give it with --store-password-file "
          "FILE, PGPASSWORD or PGPASSFILE instead (a URL shows in process lists and logs)");
    }
    location.kind = StoreLocation::Kind::kPostgres;
    location.url = url;
    return location;
  }
  throw std::runtime_error("--store " + url +
                           ": unknown store (expected sqlite:///FILE or postgresql://...)");
}

std::string ReadPasswordFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read the password file " + path);
  std::string password;
  std::getline(in, password);
  if (!password.empty() && password.back() == '\r') password.pop_back();
  if (password.empty()) throw std::runtime_error("the password file " + path + " is empty");
  return password;
}

std::unique_ptr<JobStore> OpenStore(const StoreLocation& location) {
  if (location.kind == StoreLocation::Kind::kSqlite)
    return std::make_unique<SqliteStore>(location.path);
  PostgresStore::Options options;
  options.call_seconds = location.timeout_seconds;
  return std::make_unique<PostgresStore>(location.url, location.password, options);
}

}  // namespace springfit::server
