// The client side of the daemon's JSON-RPC (proto/RPC.md): one blocking TCP connection.
#pragma once
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
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
  // --timeout: seconds to connect, and to wait for each answer (not for a watched job's next
  // notification: a queued job may be silent for hours). A server that does not answer within
  // it is a ConnectionError (exit 5). Large submissions are prepared before they are answered.
  double timeout_seconds = 60.0;
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
  // Notifications that arrive meanwhile are kept for NextNotification(), but job.preparing
  // (a submission being prepared, proto/RPC.md): it goes to the preparing listener, and
  // the answer's timeout counts again from it, since the server is at work on the request.
  proto::Json Call(const std::string& method, proto::Json params = proto::Json::object());
  void SetPreparingListener(std::function<void(const proto::Json& params)> listener) {
    preparing_listener_ = std::move(listener);
  }
  // The next notification (job.progress, job.finished), waiting for it.
  proto::Json NextNotification();

 private:
  // Reads one message; with a deadline, throws ConnectionError when none is complete by then.
  proto::Json ReadMessage(std::optional<std::chrono::steady_clock::time_point> deadline);
  // Runs the connection's pending asynchronous operation until it completes or `deadline`;
  // false (the socket closed) when the deadline came first.
  bool RunUntil(std::chrono::steady_clock::time_point deadline, const bool& done);

  struct Connection;
  std::unique_ptr<Connection> connection_;
  std::string where_;
  std::chrono::steady_clock::duration timeout_;
  std::int64_t next_id_ = 1;
  std::deque<proto::Json> notifications_;
  std::function<void(const proto::Json&)> preparing_listener_;
};

}  // namespace springfit::cli
