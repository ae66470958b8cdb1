// HOST:PORT, as springfitd's --listen and the client's --server (or SPRINGFIT_SERVER) take it.
#pragma once
#include <string>

namespace springfit::proto {

struct ServerAddress {
  std::string host;
  unsigned short port = 0;
};

// "127.0.0.1:7117", "[::1]:7117", "build-host:7117". Throws InputError (path `what`) saying
// what is wrong.
ServerAddress ParseServerAddress(const std::string& text, const std::string& what);

}  // namespace springfit::proto
