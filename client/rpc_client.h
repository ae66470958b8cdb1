// The client side of the daemon's JSON-RPC (proto/RPC.md): one blocking TCP connection.
#pragma once
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "proto/json_reader.h"
#include "proto/server_address.h"

namespace springfit::cli {

// The server cannot be reached, or the connection broke.
class ConnectionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The server answered with an error object.
class RemoteError : public std::runtime_error {
 public:
  RemoteError(int code, const std::string& message, proto::Json data)
      : std::runtime_error(message), code_(code), data_(std::move(data)) {}
  int code() const { return code_; }
  const proto::Json& data() const { return data_; }

 private:
  int code_;
  proto::Json data_;
};

// Where the server is and how to prove who we are: --server / SPRINGFIT_SERVER (default
// 127.0.0.1:7117), --token-file / SPRINGFIT_TOKEN.
struct ServerOptions {
  std::string server;
  std::string token_file;
  // Resolves the flags and the environment; throws InputError on a bad address or token file.
  proto::ServerAddress Address() const;
  std::optional<std::string> Token() const;
};

class RpcClient {
 public:
  // Connects (and authenticates when a token is given); throws ConnectionError.
  explicit RpcClient(const ServerOptions& options);
  ~RpcClient();
  RpcClient(const RpcClient&) = delete;
  RpcClient& operator=(const RpcClient&) = delete;

  // Sends a request and returns its result; throws RemoteError or ConnectionError.
  // Notifications that arrive meanwhile are kept for NextNotification().
  proto::Json Call(const std::string& method, proto::Json params = proto::Json::object());
  // The next notification (job.progress, job.finished), waiting for it.
  proto::Json NextNotification();

 private:
  proto::Json ReadMessage();

  struct Connection;
  std::unique_ptr<Connection> connection_;
  std::string where_;
  std::int64_t next_id_ = 1;
  std::deque<proto::Json> notifications_;
};

}  // namespace springfit::cli
