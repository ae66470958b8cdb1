// The daemon's network side: a Boost.Asio acceptor and one session per connection, all on
// one I/O thread; requests are handled on a small pool, and submissions (a large scene's
// validation and preparation) on a pool of their own, so that a slow request never stalls
// other connections or the cheap requests.
//
// A session reads bytes, frames them into JSON messages (proto/json_framer.h), hands them
// one at a time to the RpcService, and writes each answer as one line. Notifications that
// job threads send (job.watch) are posted to the I/O thread and written after any answer
// in flight. Bounds, each ending only the offending connection: message size (error, then
// close), nesting depth and garbage (error, resynchronised at the next newline), unwritten
// output of a slow reader (close), idle time without a watched job (close), a message begun
// and not completed within message_seconds (close: a byte at a time is no way to hold a
// connection), and the number
// of connections (refused with an error).
#pragma once
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <memory>
#include <set>
#include <string>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/thread_pool.hpp>

#include "server/rpc/rpc_service.h"

namespace springfit::server {

struct TcpServerOptions {
  std::string host = "127.0.0.1";
  unsigned short port = 7117;  // 0: an ephemeral port (see TcpServer::port)
  int max_connections = 256;
  std::size_t max_message_bytes = std::size_t{16} << 20;
  std::size_t max_pending_output = std::size_t{64}
                                   << 20;  // unread answers before a slow reader is dropped
  // With a token set, a connection that has not authenticated may send messages of at most
  // this many bytes (session.auth and server.info need a few dozen): nothing larger is
  // buffered, let alone parsed, for a client that has not shown the token.
  std::size_t max_unauthenticated_message_bytes = std::size_t{64} << 10;
  // A connection's framed messages waiting for their turn, in bytes (besides at most 64 of
  // them): reading stops beyond it until they are handled.
  std::size_t max_inbox_bytes = std::size_t{32} << 20;
  double idle_seconds = 300.0;
  double message_seconds = 30.0;  // to complete a message once its first byte arrived
  int handler_threads = 2;
  // job.submit requests (their scenes validated and prepared) run on these, apart from the
  // handlers, so that a large submission never delays other requests; so does the parsing
  // of any message over 64 KiB.
  int preparation_threads = 2;
};

class Session;

class TcpServer {
 public:
  TcpServer(boost::asio::io_context& io, RpcService& service, TcpServerOptions options);
  ~TcpServer();

  // Binds and listens; throws std::runtime_error naming the address when it cannot.
  void Start();
  unsigned short port() const { return port_; }
  // Stops accepting new connections (on the I/O thread); open ones carry on.
  void StopAccepting();
  // Stops accepting and closes every connection (on the I/O thread).
  void Stop();

 private:
  friend class Session;
  // The largest message a connection may send: max_unauthenticated_message_bytes until it has
  // authenticated, where a token is required.
  std::size_t MessageBound(bool authenticated) const {
    if (authenticated || !service_.requires_token()) return options_.max_message_bytes;
    return std::min(options_.max_message_bytes, options_.max_unauthenticated_message_bytes);
  }
  void Accept();
  void Remove(const std::shared_ptr<Session>& session);

  boost::asio::io_context& io_;
  RpcService& service_;
  TcpServerOptions options_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::thread_pool handlers_;
  boost::asio::thread_pool preparers_;
  std::set<std::shared_ptr<Session>> sessions_;
  unsigned short port_ = 0;
  std::chrono::steady_clock::time_point last_accept_warning_{};
};

}  // namespace springfit::server
