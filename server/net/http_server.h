// The dashboard's HTTP/1.1 server (springfitd --http): Boost.Beast sessions on the daemon's
// I/O context; each request is answered on a small handler pool (a figure of a large scene
// takes a while to draw), so that one slow page never stalls other connections or the
// JSON-RPC port. Bounds, each ending only the offending connection: header bytes and count
// (431), body bytes (413), time to send a whole request and to read an answer (the socket
// is closed), the number of connections (503, then closed).
#pragma once
#include <cstddef>
#include <memory>
#include <set>
#include <string>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/thread_pool.hpp>

#include "server/web/dashboard.h"

namespace springfit::server {

struct HttpServerOptions {
  std::string host = "127.0.0.1";
  unsigned short port = 7118;  // 0: an ephemeral port (see HttpServer::port)
  int max_connections = 64;
  std::size_t max_header_bytes = 8192;
  int max_header_count = 64;
  std::size_t max_body_bytes = 16384;  // GET pages and the login form only
  double timeout_seconds = 15.0;       // to receive a request, or to send an answer
  int handler_threads = 2;  // pages and figures; /healthz and /metrics have a thread of their own
};

class HttpSession;

class HttpServer {
 public:
  HttpServer(boost::asio::io_context& io, Dashboard& dashboard, HttpServerOptions options);
  ~HttpServer();

  // Binds and listens; throws std::runtime_error naming the address when it cannot.
  void Start();
  unsigned short port() const { return port_; }
  // Stops accepting and closes every connection (on the I/O thread).
  void Stop();

 private:
  friend class HttpSession;
  void Accept();
  void Remove(const std::shared_ptr<HttpSession>& session);

  boost::asio::io_context& io_;
  Dashboard& dashboard_;
  HttpServerOptions options_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::thread_pool handlers_;
  boost::asio::thread_pool health_;  // /healthz and /metrics alone
  std::set<std::shared_ptr<HttpSession>> sessions_;
  unsigned short port_ = 0;
};

}  // namespace springfit::server
