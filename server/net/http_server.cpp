#include "server/net/http_server.h"

#include <algorithm>
#include <chrono>
#include <optional>

#include <spdlog/spdlog.h>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

namespace springfit::server {
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = boost::asio::ip::tcp;

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(HttpServer& server, tcp::socket socket)
      : server_(server), stream_(std::move(socket)) {}

  void Start() { Read(); }
  void Close() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
    stream_.close();
  }
  // A connection over the limit: one answer, then closed.
  void Refuse() {
    HttpResponse r;
    r.status = 503;
    r.body = "too many connections\n";
    Write(r, false);
  }

 private:
  std::chrono::milliseconds Timeout() const {
    return std::chrono::milliseconds(
        static_cast<long long>(server_.options_.timeout_seconds * 1000));
  }

  void Read() {
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(server_.options_.max_header_bytes));
    parser_->body_limit(server_.options_.max_body_bytes);
    // The whole request within the timeout: a client sending a byte at a time is cut off.
    stream_.expires_after(Timeout());
    http::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code ec, std::size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec == http::error::header_limit || ec == http::error::body_limit) {
      HttpResponse r;
      r.status = ec == http::error::header_limit ? 431 : 413;
      r.body = ec == http::error::header_limit ? "request headers too large\n"
                                               : "request body too large\n";
      Write(r, false);
      return;
    }
    if (ec) {
      server_.Remove(shared_from_this());
      return;
    }
    http::request<http::string_body> req = parser_->release();
    HttpRequest request;
    request.method = std::string(req.method_string());
    request.target = std::string(req.target());
    request.body = std::move(req.body());
    int count = 0;
    for (const auto& field : req) {
      ++count;
      std::string name(field.name_string());
      std::transform(name.begin(), name.end(), name.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      request.headers[name] = std::string(field.value());
    }
    const bool keep_alive = req.keep_alive();
    if (count > server_.options_.max_header_count) {
      HttpResponse r;
      r.status = 431;
      r.body = "too many request headers\n";
      Write(r, false);
      return;
    }
    // Answered off the I/O thread; written back on it. Health and metrics on their own thread:
    // a monitor's probe never waits behind pages and figures (a figure of a large job builds
    // its problem, seconds on the handler threads).
    const std::string path = request.target.substr(0, request.target.find('?'));
    boost::asio::thread_pool& pool =
        path == "/healthz" || path == "/metrics" ? server_.health_ : server_.handlers_;
    boost::asio::post(pool, [self = shared_from_this(), request, keep_alive] {
      HttpResponse response = self->server_.dashboard_.Handle(request);
      boost::asio::post(self->stream_.get_executor(),
                        [self, response = std::move(response), keep_alive] {
                          self->Write(response, keep_alive);
                        });
    });
  }

  void Write(const HttpResponse& r, bool keep_alive) {
    auto res = std::make_shared<http::response<http::string_body>>();
    res->result(static_cast<http::status>(r.status));
    res->version(11);
    res->set(http::field::server, "springfitd");
    res->set(http::field::content_type, r.content_type);
    res->set(http::field::cache_control, "no-store");
    // The pages load nothing from elsewhere; a label that slipped through escaping could not
    // run script from another origin, nor the page be framed.
    res->set("Content-Security-Policy",
             "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
             "script-src 'self' 'unsafe-inline'; frame-ancestors 'none'");
    res->set("X-Content-Type-Options", "nosniff");
    for (const auto& [name, value] : r.headers) res->set(name, value);
    res->keep_alive(keep_alive);
    res->body() = r.body;
    res->prepare_payload();
    server_.dashboard_.Count(r.status);
    stream_.expires_after(Timeout());
    http::async_write(
        stream_, *res,
        [self = shared_from_this(), res, keep_alive](beast::error_code ec, std::size_t) {
          if (ec || !keep_alive) {
            self->server_.Remove(self);
            return;
          }
          self->Read();
        });
  }

  HttpServer& server_;
  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

HttpServer::HttpServer(boost::asio::io_context& io, Dashboard& dashboard, HttpServerOptions options)
    : io_(io),
      dashboard_(dashboard),
      options_(std::move(options)),
      acceptor_(io),
      handlers_(static_cast<std::size_t>(std::max(1, options_.handler_threads))),
      health_(1) {}

HttpServer::~HttpServer() {
  handlers_.join();
  health_.join();
}

void HttpServer::Start() {
  boost::system::error_code ec;
  const auto address = boost::asio::ip::make_address(options_.host, ec);
  if (ec) throw std::runtime_error("--http: '" + options_.host + "' is not an IP address");
  const tcp::endpoint endpoint(address, options_.port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(boost::asio::socket_base::max_listen_connections, ec);
  if (ec) {
    throw std::runtime_error("--http: cannot listen on " + options_.host + ":" +
                             std::to_string(options_.port) + ": " + ec.message());
  }
  port_ = acceptor_.local_endpoint().port();
  Accept();
}

void HttpServer::Accept() {
  acceptor_.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
    if (!acceptor_.is_open()) return;
    if (ec) {
      // Out of descriptors and the like: try again shortly rather than spin.
      spdlog::warn("http: accept failed: {}", ec.message());
      auto timer = std::make_shared<boost::asio::steady_timer>(io_, std::chrono::milliseconds(100));
      timer->async_wait([this, timer](boost::system::error_code) { Accept(); });
      return;
    }
    auto session = std::make_shared<HttpSession>(*this, std::move(socket));
    sessions_.insert(session);
    if (static_cast<int>(sessions_.size()) > options_.max_connections) {
      session->Refuse();
    } else {
      session->Start();
    }
    Accept();
  });
}

void HttpServer::Remove(const std::shared_ptr<HttpSession>& session) {
  session->Close();
  sessions_.erase(session);
}

void HttpServer::Stop() {
  boost::asio::post(io_, [this] {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    for (const auto& s : sessions_) s->Close();
    sessions_.clear();
  });
}

}  // namespace springfit::server
