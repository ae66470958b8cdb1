#include "server/store/store_url.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace springfit::server {
namespace {

std::string Refusal(const std::string& url) {
  try {
    ParseStoreUrl(url);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(StoreUrl, SqlitePathsFollowSqlAlchemysSlashes) {
  const StoreLocation relative = ParseStoreUrl("sqlite:///springfit.db");
  EXPECT_EQ(relative.kind, StoreLocation::Kind::kSqlite);
  EXPECT_EQ(relative.path, "springfit.db");
  EXPECT_EQ(ParseStoreUrl("sqlite:////var/lib/springfit/s.db").path, "/var/lib/springfit/s.db");
  EXPECT_NE(Refusal("sqlite:///"), "");
  EXPECT_NE(Refusal("sqlite:springfit.db").find("sqlite:///FILE"), std::string::npos);
}

TEST(StoreUrl, PostgresUrlsGoToLibpqWithoutAPassword) {
  const StoreLocation pg =
      ParseStoreUrl("postgresql://springfit@db-host:5433/jobs?sslmode=require");
  EXPECT_EQ(pg.kind, StoreLocation::Kind::kPostgres);
  EXPECT_EQ(pg.url, "postgresql://springfit@db-host:5433/jobs?sslmode=require");
  EXPECT_EQ(ParseStoreUrl("postgres:///jobs?host=/run/postgresql").kind,
            StoreLocation::Kind::kPostgres);
  // A password in the URL is refused, and not repeated in the message.
  for (const std::string url : {"postgresql://springfit:s3cret@db-host/jobs",
                                "postgresql://db-host/jobs?user=u&password=s3cret"}) {
    const std::string why = Refusal(url);
    EXPECT_NE(why.find("password"), std::string::npos) << url;
    EXPECT_EQ(why.find("s3cret"), std::string::npos) << why;
  }
  EXPECT_NE(Refusal("mysql://x/y").find("unknown store"), std::string::npos);
}

}  // namespace
}  // namespace springfit::server
