#include "server/net/tcp_server.h"

#include <array>
#include <chrono>
#include <deque>
#include <optional>
#include <vector>

#include <spdlog/spdlog.h>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/write.hpp>

#include "proto/json_framer.h"
#include "proto/rpc.h"

namespace springfit::server {
namespace asio = boost::asio;
using asio::ip::tcp;
namespace rpc = proto::rpc;

// Messages longer than this are parsed on the preparation threads (Session::HandleNext).
constexpr std::size_t kParsedOnPreparers = 64 * 1024;

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(TcpServer& server, tcp::socket socket)
      : server_(server),
        socket_(std::move(socket)),
        idle_timer_(server.io_),
        message_timer_(server.io_),
        framer_(proto::JsonFramer::Options{server.MessageBound(false), 64}) {
    boost::system::error_code ec;
    const auto remote = socket_.remote_endpoint(ec);
    peer_ =
        ec ? std::string("?") : remote.address().to_string() + ":" + std::to_string(remote.port());
  }

  void Start() {
    std::weak_ptr<Session> weak = weak_from_this();
    asio::io_context& io = server_.io_;
    context_.notify = [weak, &io](const proto::Json& notification) {
      asio::post(io, [weak, notification] {
        if (auto self = weak.lock()) self->Notify(notification);
      });
    };
    context_.notify_now = [weak, &io](const proto::Json& notification) {
      asio::post(io, [weak, notification] {
        if (auto self = weak.lock()) self->SendNotification(notification);
      });
    };
    ArmIdleTimer();
    Read();
  }

  // Sends `text` and closes once everything queued is written.
  void SendAndClose(std::string text) {
    Send(std::move(text));
    close_after_write_ = true;
    if (!writing_) Close();
  }

  void Close() {
    if (closed_) return;
    closed_ = true;
    context_.peer_gone->store(true);
    boost::system::error_code ignored;
    socket_.shutdown(tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
    idle_timer_.cancel();
    message_timer_.cancel();
    // A handler still running owns the context; OnHandled ends the session then.
    if (!handling_) server_.service_.EndSession(context_);
    server_.Remove(shared_from_this());
  }

 private:
  // Reads unless a read is outstanding, the connection is ending, or many messages wait:
  // one client cannot queue unbounded work.
  void Read() {
    if (reading_ || closed_ || close_after_write_ || too_large_ || inbox_.size() >= 64 ||
        inbox_bytes_ >= server_.options_.max_inbox_bytes)
      return;
    reading_ = true;
    socket_.async_read_some(asio::buffer(buffer_),
                            [self = shared_from_this()](boost::system::error_code ec,
                                                        std::size_t n) { self->OnRead(ec, n); });
  }

  void OnRead(boost::system::error_code ec, std::size_t n) {
    reading_ = false;
    if (closed_) return;
    if (ec) {
      if (ec != asio::error::eof && ec != asio::error::operation_aborted) {
        spdlog::info("connection {}: read error: {}", peer_, ec.message());
      }
      if (!framer_.at_boundary())
        spdlog::info("connection {}: closed in the middle of a message", peer_);
      Close();
      return;
    }
    last_activity_ = std::chrono::steady_clock::now();
    // A message, once begun, must be complete within message_seconds: a client trickling a
    // byte at a time would otherwise hold its connection (and a slot) for ever, since every
    // byte resets the idle clock.
    // (ArmMessageTimer closes it when the bytes stop coming too.)
    if (message_started_ && last_activity_ - *message_started_ > MessageSeconds()) {
      CloseUnfinishedMessage();
      return;
    }
    for (proto::JsonFramer::Frame& frame : framer_.Feed(std::string_view(buffer_.data(), n))) {
      switch (frame.kind) {
        case proto::JsonFramer::Frame::Kind::kMessage:
          inbox_bytes_ += frame.text.size();
          inbox_.push_back(std::move(frame.text));
          break;
        case proto::JsonFramer::Frame::Kind::kMalformed:
          spdlog::info("connection {}: malformed message: {}", peer_, frame.error);
          inbox_.push_back({});  // answered in order with the requests around it
          errors_.push_back(
              rpc::Serialize(rpc::Error(nullptr, rpc::kParseError, "parse error: " + frame.error)));
          break;
        case proto::JsonFramer::Frame::Kind::kTooLarge: {
          spdlog::warn("connection {}: {}; closing", peer_, frame.error);
          proto::Json data;
          const bool before_auth = framer_.max_message_bytes() < server_.MessageBound(true);
          data["limit"] = before_auth ? "max_unauthenticated_message_bytes" : "max_message_bytes";
          data["max"] = framer_.max_message_bytes();
          too_large_ = rpc::Serialize(rpc::Error(
              nullptr, rpc::kLimitExceeded,
              before_auth ? frame.error + " before session.auth (the token first)" : frame.error,
              data));
          break;
        }
      }
    }
    if (framer_.at_boundary()) {
      message_started_.reset();
      message_timer_.cancel();
    } else if (!message_started_) {
      message_started_ = last_activity_;
      ArmMessageTimer();
    }
    HandleNext();
    Read();
  }

  // Hands the next waiting message to the handler pool; one at a time per connection, so
  // that answers come back in the order of the requests.
  void HandleNext() {
    if (closed_ || handling_) return;
    if (inbox_.empty()) {
      if (too_large_) SendAndClose(std::move(*too_large_));
      return;
    }
    std::string text = std::move(inbox_.front());
    inbox_.pop_front();
    inbox_bytes_ -= text.size();
    if (text.empty()) {  // a malformed frame
      Send(std::move(errors_.front()));
      errors_.pop_front();
      HandleNext();
      Read();
      return;
    }
    handling_ = true;
    // A submission validates and prepares its scene, which can take seconds for a large one:
    // once parsed, it waits for a preparation thread, so that every other request
    // (server.info, job.get) is answered at once meanwhile. A large message is parsed there
    // too: parsing a 100,000-node scene takes tens of milliseconds, which a request thread
    // would spend instead of answering; no other request is that large.
    if (text.size() > kParsedOnPreparers) {
      asio::post(server_.preparers_, [self = shared_from_this(), text = std::move(text)] {
        self->Answer(self->server_.service_.Handle(RpcService::Parse(text), self->context_));
      });
      return;
    }
    asio::post(server_.handlers_, [self = shared_from_this(), text = std::move(text)] {
      auto parsed = std::make_shared<RpcService::ParsedMessage>(RpcService::Parse(text));
      if (!parsed->prepares_scene) {
        self->Answer(self->server_.service_.Handle(*parsed, self->context_));
        return;
      }
      asio::post(self->server_.preparers_, [self, parsed] {
        self->Answer(self->server_.service_.Handle(*parsed, self->context_));
      });
    });
  }

  // From a handler or preparation thread: the answer goes out on the connection's thread.
  void Answer(std::string answer) {
    asio::post(server_.io_, [self = shared_from_this(), answer = std::move(answer)]() mutable {
      self->OnHandled(std::move(answer));
    });
  }

  void OnHandled(std::string answer) {
    handling_ = false;
    // (context_ was written by the handler thread; this post back is the hand-over.)
    if (context_.authenticated) framer_.set_max_message_bytes(server_.MessageBound(true));
    if (closed_) {
      server_.service_.EndSession(context_);
      return;
    }
    if (context_.close) {  // the service asked to close this connection after its answer
      SendAndClose(std::move(answer));
      return;
    }
    if (!answer.empty()) Send(std::move(answer));
    for (std::string& n : deferred_) Send(std::move(n));
    deferred_.clear();
    deferred_bytes_ = 0;
    HandleNext();
    Read();
  }

  void Notify(const proto::Json& notification) {
    if (closed_) return;
    if (handling_) {
      // After the answer being prepared; counted in the output bound meanwhile, so that a
      // watch during a long request cannot queue without limit.
      std::string text = rpc::Serialize(notification);
      deferred_bytes_ += text.size();
      if (pending_output_ + deferred_bytes_ > server_.options_.max_pending_output) {
        spdlog::warn("connection {}: {} bytes of notifications waiting; closing", peer_,
                     deferred_bytes_);
        Close();
        return;
      }
      deferred_.push_back(std::move(text));
    } else {
      SendNotification(notification);
    }
  }

  void SendNotification(const proto::Json& notification) { Send(rpc::Serialize(notification)); }

  void Send(std::string text) {
    if (closed_) return;
    pending_output_ += text.size();
    if (pending_output_ > server_.options_.max_pending_output) {
      spdlog::warn("connection {}: {} bytes unread by the client; closing", peer_, pending_output_);
      Close();
      return;
    }
    outbox_.push_back(std::move(text));
    if (!writing_) WriteNext();
  }

  void WriteNext() {
    writing_ = true;
    asio::async_write(socket_, asio::buffer(outbox_.front()),
                      [self = shared_from_this()](boost::system::error_code ec, std::size_t) {
                        self->OnWritten(ec);
                      });
  }

  void OnWritten(boost::system::error_code ec) {
    if (closed_) return;
    pending_output_ -= outbox_.front().size();
    outbox_.pop_front();
    last_activity_ = std::chrono::steady_clock::now();
    if (ec) {
      spdlog::info("connection {}: write error: {}", peer_, ec.message());
      Close();
      return;
    }
    if (!outbox_.empty()) {
      WriteNext();
      return;
    }
    writing_ = false;
    if (close_after_write_) Close();
  }

  std::chrono::steady_clock::duration MessageSeconds() const {
    return std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(server_.options_.message_seconds));
  }

  void CloseUnfinishedMessage() {
    spdlog::info("connection {}: a message not completed within {:.0f} s; closing", peer_,
                 server_.options_.message_seconds);
    Close();
  }

  // The message begun at message_started_ must be complete by message_seconds after it, even
  // when no byte comes after the first: half a message and then silence held a connection
  // until the idle timeout, and for ever with a watch open.
  void ArmMessageTimer() {
    const auto started = *message_started_;
    message_timer_.expires_at(started + MessageSeconds());
    message_timer_.async_wait([self = shared_from_this(), started](boost::system::error_code ec) {
      if (ec || self->closed_ || self->message_started_ != started) return;
      self->CloseUnfinishedMessage();
    });
  }

  void ArmIdleTimer() {
    const auto idle = std::chrono::duration<double>(server_.options_.idle_seconds);
    idle_timer_.expires_at(last_activity_ +
                           std::chrono::duration_cast<std::chrono::steady_clock::duration>(idle));
    idle_timer_.async_wait([self = shared_from_this(), idle](boost::system::error_code ec) {
      if (ec || self->closed_) return;
      // Not idle: a request being handled, or a watched job that has not finished.
      const bool watching = !self->handling_ && self->context_.OpenWatches() > 0;
      if (!watching && !self->handling_ &&
          std::chrono::steady_clock::now() - self->last_activity_ >= idle) {
        spdlog::info("connection {}: idle for {:.0f} s; closing", self->peer_, idle.count());
        self->Close();
        return;
      }
      if (watching) self->last_activity_ = std::chrono::steady_clock::now();
      self->ArmIdleTimer();
    });
  }

  TcpServer& server_;
  tcp::socket socket_;
  asio::steady_timer idle_timer_;
  asio::steady_timer message_timer_;  // ArmMessageTimer
  proto::JsonFramer framer_;
  SessionContext context_;
  std::string peer_;
  std::array<char, 65536> buffer_{};
  std::deque<std::string> inbox_;   // framed messages; "" marks a malformed one
  std::deque<std::string> errors_;  // the answers of the malformed ones, in order
  std::optional<std::string> too_large_;
  std::deque<std::string> outbox_;
  std::vector<std::string> deferred_;  // notifications held behind the answer being prepared
  std::size_t deferred_bytes_ = 0;
  std::size_t inbox_bytes_ = 0;
  std::size_t pending_output_ = 0;
  // When the message being received began (unset between messages).
  std::optional<std::chrono::steady_clock::time_point> message_started_;
  bool reading_ = false;
  bool handling_ = false;
  bool writing_ = false;
  bool close_after_write_ = false;
  bool closed_ = false;
  std::chrono::steady_clock::time_point last_activity_ = std::chrono::steady_clock::now();
};

TcpServer::TcpServer(asio::io_context& io, RpcService& service, TcpServerOptions options)
    : io_(io),
      service_(service),
      options_(std::move(options)),
      acceptor_(io),
      handlers_(static_cast<std::size_t>(std::max(1, options_.handler_threads))),
      preparers_(static_cast<std::size_t>(std::max(1, options_.preparation_threads))) {}

TcpServer::~TcpServer() {
  handlers_.join();
  preparers_.join();
}

void TcpServer::Start() {
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(options_.host, ec);
  if (ec) throw std::runtime_error("cannot listen on '" + options_.host + "': not an IP address");
  const tcp::endpoint endpoint(address, options_.port);
  const std::string where = options_.host + ":" + std::to_string(options_.port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) throw std::runtime_error("cannot listen on " + where + ": " + ec.message());
  port_ = acceptor_.local_endpoint().port();
  Accept();
}

void TcpServer::Accept() {
  acceptor_.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
    if (ec) {
      if (ec == asio::error::operation_aborted) return;
      // Out of file descriptors (EMFILE) and the like: the pending connection stays in the
      // backlog, so accepting again at once would fail again at once. Wait a little, and log
      // the condition once per second at most.
      const auto now = std::chrono::steady_clock::now();
      if (now - last_accept_warning_ > std::chrono::seconds(1)) {
        spdlog::warn("accept: {}; retrying in 100 ms", ec.message());
        last_accept_warning_ = now;
      }
      auto timer = std::make_shared<asio::steady_timer>(io_, std::chrono::milliseconds(100));
      timer->async_wait([this, timer](boost::system::error_code) {
        if (acceptor_.is_open()) Accept();
      });
      return;
    }
    auto session = std::make_shared<Session>(*this, std::move(socket));
    sessions_.insert(session);
    if (static_cast<int>(sessions_.size()) > options_.max_connections) {
      spdlog::warn("refusing a connection: {} connections open", options_.max_connections);
      session->SendAndClose(rpc::Serialize(rpc::Error(
          nullptr, rpc::kBusy,
          "busy: " + std::to_string(options_.max_connections) + " connections are open")));
    } else {
      session->Start();
    }
    Accept();
  });
}

void TcpServer::Remove(const std::shared_ptr<Session>& session) {
  sessions_.erase(session);
}

void TcpServer::StopAccepting() {
  asio::post(io_, [this] {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
  });
}

void TcpServer::Stop() {
  asio::post(io_, [this] {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    const auto open = sessions_;  // Close() removes from sessions_
    for (const auto& s : open) s->Close();
  });
}

}  // namespace springfit::server
