#include "client/rpc_client.h"

#include <cstdlib>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>

#include "engine/input_error.h"
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

RpcClient::RpcClient(const ServerOptions& options) : connection_(std::make_unique<Connection>()) {
  const proto::ServerAddress address = options.Address();
  const std::optional<std::string> token = options.Token();
  where_ = address.host + ":" + std::to_string(address.port);
  boost::system::error_code ec;
  asio::ip::tcp::resolver resolver(connection_->io);
  const auto endpoints = resolver.resolve(address.host, std::to_string(address.port), ec);
  if (!ec) asio::connect(connection_->socket, endpoints, ec);
  if (ec) throw ConnectionError("cannot connect to springfitd at " + where_ + ": " + ec.message());
  if (token) {
    Json params;
    params["token"] = *token;
    Call("session.auth", params);
  }
}

RpcClient::~RpcClient() = default;

Json RpcClient::ReadMessage() {
  boost::system::error_code ec;
  const std::size_t n = asio::read_until(connection_->socket, connection_->input, '\n', ec);
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
  while (true) {
    Json message = ReadMessage();
    if (message.contains("method") && !message.contains("id")) {
      notifications_.push_back(std::move(message));
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
    Json message = ReadMessage();
    if (message.contains("method") && !message.contains("id")) return message;
  }
}

}  // namespace springfit::cli
