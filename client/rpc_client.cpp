#include "client/rpc_client.h"

#include <cstdlib>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>

#include "engine/api/input_error.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace asio = boost::asio;
using proto::Json;

namespace {
constexpr const char* kDefaultServer = "127.0.0.1:7117";
}

proto::ServerAddress ServerOptions::Address() const {
  if (!server.empty()) return proto::ParseServerAddress(server, "--server");
  if (const char* env = std::getenv("SPRINGFIT_SERVER"); env && *env) {
    return proto::ParseServerAddress(env, "SPRINGFIT_SERVER");
  }
  return proto::ParseServerAddress(kDefaultServer, "--server");
}

std::optional<std::string> ServerOptions::Token() const {
  std::string token;
  if (!token_file.empty()) {
    token = proto::ReadFile(token_file);
  } else if (const char* env = std::getenv("SPRINGFIT_TOKEN"); env && *env) {
    token = env;
  } else {
    return std::nullopt;
  }
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.back()))) token.pop_back();
  if (token.empty()) throw InputError("--token-file", "the token is empty");
  return token;
}

struct RpcClient::Connection {
  asio::io_context io;
  asio::ip::tcp::socket socket{io};
  asio::streambuf input;
};

RpcClient::RpcClient(const ServerOptions& options)
    : connection_(std::make_unique<Connection>()),
      timeout_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(options.timeout_seconds))) {
  const proto::ServerAddress address = options.Address();
  const std::optional<std::string> token = options.Token();
  where_ = address.host + ":" + std::to_string(address.port);
  const auto deadline = std::chrono::steady_clock::now() + timeout_;
  boost::system::error_code ec;
  bool done = false;
  asio::ip::tcp::resolver resolver(connection_->io);
  resolver.async_resolve(
      address.host, std::to_string(address.port),
      [&](const boost::system::error_code& e, asio::ip::tcp::resolver::results_type endpoints) {
        if (e) {
          ec = e;
          done = true;
          return;
        }
        asio::async_connect(connection_->socket, endpoints,
                            [&](const boost::system::error_code& c, const auto&) {
                              ec = c;
                              done = true;
                            });
      });
  if (!RunUntil(deadline, done)) {
    throw ConnectionError("cannot connect to springfitd at " + where_ + ": no answer within " +
                          NumberText(options.timeout_seconds) + " s (--timeout)");
  }
  if (ec) throw ConnectionError("cannot connect to springfitd at " + where_ + ": " + ec.message());
  if (token) {
    Json params;
    params["token"] = *token;
    Call("session.auth", params);
  }
}

RpcClient::~RpcClient() = default;

bool RpcClient::RunUntil(std::chrono::steady_clock::time_point deadline, const bool& done) {
  asio::io_context& io = connection_->io;
  io.restart();
  while (!done && std::chrono::steady_clock::now() < deadline) {
    if (io.run_one_until(deadline) == 0 && io.stopped()) break;
  }
  if (done) return true;
  // Abandon the operation: closing the socket completes it with operation_aborted.
  boost::system::error_code ignored;
  connection_->socket.close(ignored);
  io.restart();
  io.run();
  return false;
}

Json RpcClient::ReadMessage(std::optional<std::chrono::steady_clock::time_point> deadline) {
  boost::system::error_code ec;
  std::size_t n = 0;
  if (deadline) {
    bool done = false;
    asio::async_read_until(connection_->socket, connection_->input, '\n',
                           [&](const boost::system::error_code& e, std::size_t bytes) {
                             ec = e;
                             n = bytes;
                             done = true;
                           });
    if (!RunUntil(*deadline, done)) {
      throw ConnectionError("springfitd at " + where_ + " did not answer within " +
                            NumberText(std::chrono::duration<double>(timeout_).count()) +
                            " s (--timeout)");
    }
  } else {
    n = asio::read_until(connection_->socket, connection_->input, '\n', ec);
  }
  if (ec) {
    throw ConnectionError(
        "connection to springfitd at " + where_ +
        " lost: " + (ec == asio::error::eof ? std::string("closed by the server") : ec.message()));
  }
  std::string line(asio::buffers_begin(connection_->input.data()),
                   asio::buffers_begin(connection_->input.data()) + n);
  connection_->input.consume(n);
  try {
    return proto::ParseJson(line);
  } catch (const InputError& e) {
    throw ConnectionError("springfitd at " + where_ +
                          " sent something that is not JSON: " + e.what());
  }
}

Json RpcClient::Call(const std::string& method, Json params) {
  const std::int64_t id = next_id_++;
  const std::string text =
      proto::rpc::Serialize(proto::rpc::Request(id, method, std::move(params)));
  boost::system::error_code ec;
  asio::write(connection_->socket, asio::buffer(text), ec);
  if (ec) throw ConnectionError("connection to springfitd at " + where_ + " lost: " + ec.message());
  auto deadline = std::chrono::steady_clock::now() + timeout_;
  while (true) {
    Json message = ReadMessage(deadline);
    if (message.contains("method") && !message.contains("id")) {
      if (message["method"] == "job.preparing") {
        deadline = std::chrono::steady_clock::now() + timeout_;
        if (preparing_listener_) preparing_listener_(message.value("params", Json::object()));
      } else {
        notifications_.push_back(std::move(message));
      }
      continue;
    }
    if (message.contains("error")) {
      const Json& e = message["error"];
      throw RemoteError(e.value("code", 0), e.value("message", std::string("error")),
                        e.value("data", Json()));
    }
    if (message.value("id", Json()) != Json(id))
      continue;  // not ours (cannot happen with one caller)
    return message.value("result", Json());
  }
}

Json RpcClient::NextNotification() {
  if (!notifications_.empty()) {
    Json n = std::move(notifications_.front());
    notifications_.pop_front();
    return n;
  }
  while (true) {
    Json message = ReadMessage(std::nullopt);
    if (message.contains("method") && !message.contains("id")) return message;
  }
}

}  // namespace springfit::cli
