// springfitd: the identification daemon (README.md, "The daemon"; proto/RPC.md).
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <thread>

#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/address.hpp>
#include <boost/asio/signal_set.hpp>

#include <fmt/format.h>

#include "proto/scene_codec.h"
#include "proto/server_address.h"
#include "server/jobs/scheduler.h"
#include "server/log_format.h"
#include "server/net/http_server.h"
#include "server/net/tcp_server.h"
#include "server/rpc/rpc_service.h"
#include "server/store/metered_store.h"
#include "server/store/store_url.h"
#include "server/version.h"
#include "server/web/dashboard.h"

namespace {

namespace sf = springfit::server;

struct DaemonArgs {
  std::string listen = "127.0.0.1:7117";
  std::string db;     // --db FILE: the same as --store sqlite:///FILE
  std::string store;  // --store URL
  std::string store_password_file;
  double store_timeout = 10.0;
  std::string name;
  double lease_seconds = 10.0;
  int workers = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::optional<int> max_running;
  std::string token_file;
  std::string port_file;
  std::string http;  // HOST:PORT of the dashboard; empty: none
  std::string http_port_file;
  std::string log_level = "info";
  double checkpoint_seconds = 10.0;
  double idle_seconds = 300.0;
  double message_seconds = 30.0;
  double shutdown_seconds = 10.0;
  sf::ServiceLimits limits;
  int max_connections = 256;
  std::size_t max_message_bytes = std::size_t{16} << 20;
  std::size_t max_unauthenticated_bytes = std::size_t{64} << 10;
  std::size_t max_inbox_bytes = std::size_t{32} << 20;
};

// The token file: a secret, so like ssh with its keys the daemon refuses one that others
// may read (and names a directory given in its place as one).
std::string ReadToken(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode))
      throw std::runtime_error("the token file " + path + " is a directory, not a file");
    if ((st.st_mode & 077) != 0) {
      const std::string mode = fmt::format("{:04o}", static_cast<unsigned>(st.st_mode & 07777));
      throw std::runtime_error("the token file " + path + " is readable by others (mode " + mode +
                               "): chmod 600 " + path);
    }
  }
  std::string token = springfit::proto::ReadFile(path);
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.back()))) token.pop_back();
  if (token.empty()) throw std::runtime_error("the token file " + path + " is empty");
  if (token.size() < 16)
    throw std::runtime_error("the token in " + path + " is shorter than 16 characters");
  return token;
}

// Each connection holds a descriptor; the store, logs and the dashboard some more. A limit
// below what --max-connections allows would make the daemon fail to accept (or to open its
// database) under load: the soft limit is raised to what is needed where the hard one allows,
// and the start is refused otherwise.
void CheckDescriptorLimit(int connections) {
  constexpr rlim_t kReserve = 64;  // the store's connections, the log, the port files
  const rlim_t needed = static_cast<rlim_t>(connections) + kReserve;
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) != 0 || limit.rlim_cur >= needed) return;
  if (limit.rlim_max == RLIM_INFINITY || limit.rlim_max >= needed) {
    limit.rlim_cur = needed;
    if (::setrlimit(RLIMIT_NOFILE, &limit) == 0) return;
  }
  throw std::runtime_error(
      "--max-connections " + std::to_string(connections) + " needs " + std::to_string(needed) +
      " file descriptors, above this process's limit of " + std::to_string(limit.rlim_max) +
      " (raise it with ulimit -n or LimitNOFILE=, or lower --max-connections)");
}

void WritePortFile(const std::string& path, unsigned short port) {
  if (path.empty()) return;
  const std::string tmp = path + ".tmp";
  std::ofstream(tmp) << port << "\n";
  std::rename(tmp.c_str(), path.c_str());  // readers never see a half-written file
}

// An address to listen on (--listen, --http): other hosts only with a token.
springfit::proto::ServerAddress ListenAddress(const std::string& text, const char* flag,
                                              const std::string& token, const char* risk) {
  const springfit::proto::ServerAddress address = springfit::proto::ParseServerAddress(text, flag);
  boost::system::error_code ec;
  const auto ip = boost::asio::ip::make_address(address.host, ec);
  if (ec)
    throw std::runtime_error(std::string(flag) + ": '" + address.host + "' is not an IP address");
  if (!ip.is_loopback() && token.empty())
    throw std::runtime_error(
        "refusing to " + std::string(risk) + " on " + text +
        " without a token: other hosts could " +
        (std::string(flag) == "--http" ? "read every job" : "submit and delete jobs") +
        " (--token-file FILE)");
  return address;
}

// Where the store is: --store (or --db, the SQLite default), with its password and call bound.
sf::StoreLocation StoreLocationOf(const DaemonArgs& args) {
  sf::StoreLocation location = sf::ParseStoreUrl(
      args.store.empty() ? "sqlite:///" + (args.db.empty() ? std::string("springfit.db") : args.db)
                         : args.store);
  if (!args.store_password_file.empty())
    location.password = sf::ReadPasswordFile(args.store_password_file);
  location.timeout_seconds = args.store_timeout;
  return location;
}

sf::SchedulerOptions SchedulerOptionsOf(const DaemonArgs& args, sf::Metrics& metrics) {
  sf::SchedulerOptions options;
  options.workers = args.workers;
  options.max_running = args.max_running.value_or(args.workers);
  options.runner.checkpoint_seconds = args.checkpoint_seconds;
  // (the half of the machine's memory a run has alone, split among the jobs run at once)
  options.runner.memory_share = 0.5 / options.max_running;
  options.owner = args.name;
  options.lease_seconds = args.lease_seconds;
  options.heartbeat_seconds = std::min(1.0, args.lease_seconds / 3);
  options.metrics = &metrics;
  return options;
}

sf::TcpServerOptions TcpOptionsOf(const DaemonArgs& args,
                                  const springfit::proto::ServerAddress& address) {
  sf::TcpServerOptions net;
  net.host = address.host;
  net.port = address.port;
  net.max_connections = args.max_connections;
  net.max_message_bytes = args.max_message_bytes;
  net.max_unauthenticated_message_bytes = args.max_unauthenticated_bytes;
  net.max_inbox_bytes = args.max_inbox_bytes;
  net.idle_seconds = args.idle_seconds;
  net.message_seconds = args.message_seconds;
  return net;
}

// SIGINT and SIGTERM stop the daemon: no new connections, the running jobs checkpointed (off
// the I/O thread, so that answers and job.finished notifications of the last moments still
// reach their connections), then the servers and the I/O loop; a second signal exits at once.
// The thread that waits for the jobs is returned through `stopper`.
void StopOnSignals(boost::asio::io_context& io, boost::asio::signal_set& signals,
                   sf::RpcService& service, sf::TcpServer& server, sf::Scheduler& scheduler,
                   std::optional<sf::HttpServer>& http, double shutdown_seconds,
                   std::thread& stopper) {
  signals.async_wait([&, shutdown_seconds](const boost::system::error_code& error, int signal) {
    if (error) return;
    spdlog::info("signal {}: stopping (running jobs checkpoint and resume at the next start)",
                 signal);
    service.set_stopping();
    server.StopAccepting();
    // A second signal does not wait for the jobs.
    signals.async_wait([](const boost::system::error_code& again, int) {
      if (again) return;
      spdlog::warn("second signal: exiting now; running jobs resume from their last checkpoint");
      sf::FlushLogAndExit(1);
    });
    stopper = std::thread([&, shutdown_seconds] {
      const auto timeout =
          std::chrono::milliseconds(static_cast<long long>(shutdown_seconds * 1000));
      if (!scheduler.Stop(timeout)) {
        // A job in a long generation: leave it as a crash would, to resume from its last
        // checkpoint.
        spdlog::warn(
            "jobs still running after {:.1f} s; exiting, they resume from their last checkpoint",
            shutdown_seconds);
        sf::FlushLogAndExit(1);
      }
      server.Stop();
      if (http) http->Stop();
      boost::asio::post(io, [&] {
        signals.cancel();
        io.stop();
      });
    });
  });
}

int RunDaemon(const DaemonArgs& args) {
  const auto level = spdlog::level::from_str(args.log_level);
  spdlog::set_level(level);
  sf::InstallLogFormat();  // every message escaped and bounded (server/log_format.h)

  const std::string token = args.token_file.empty() ? std::string() : ReadToken(args.token_file);
  const springfit::proto::ServerAddress address =
      ListenAddress(args.listen, "--listen", token, "listen");
  const sf::StoreLocation location = StoreLocationOf(args);
  CheckDescriptorLimit(args.max_connections + (args.http.empty() ? 0 : 64));
  const std::unique_ptr<sf::JobStore> store_owner = sf::OpenStore(location);
  sf::Metrics metrics;
  sf::MeteredStore store(*store_owner, metrics);  // store writes timed for /metrics
  const sf::SchedulerOptions scheduler_options = SchedulerOptionsOf(args, metrics);
  sf::Scheduler scheduler(store, scheduler_options);

  sf::ServiceOptions service_options;
  service_options.token = token;
  service_options.limits = args.limits;
  service_options.workers = scheduler_options.workers;
  service_options.max_running = scheduler_options.max_running;
  service_options.metrics = &metrics;
  sf::RpcService service(store, scheduler, service_options);

  boost::asio::io_context io;
  // Signals are caught from before the first connection: a SIGTERM while the daemon starts is
  // queued and stops it as any other (checkpoints), instead of killing it without them.
  boost::asio::signal_set signals(io, SIGINT, SIGTERM);
  sf::TcpServer server(io, service, TcpOptionsOf(args, address));
  server.Start();

  // The dashboard, off by default; under the same rules as the JSON-RPC port.
  std::optional<sf::Dashboard> dashboard;
  std::optional<sf::HttpServer> http;
  if (!args.http.empty()) {
    const springfit::proto::ServerAddress http_address =
        ListenAddress(args.http, "--http", token, "serve the dashboard");
    sf::DashboardOptions dashboard_options;
    dashboard_options.token = token;
    dashboard.emplace(store, scheduler, metrics, dashboard_options);
    sf::HttpServerOptions http_options;
    http_options.host = http_address.host;
    http_options.port = http_address.port;
    http.emplace(io, *dashboard, http_options);
    http->Start();
    spdlog::info("dashboard on http://{}:{}/{}", http_address.host, http->port(),
                 token.empty() ? "" : " (token required)");
    WritePortFile(args.http_port_file, http->port());
  }

  const auto unfinished = store.UnfinishedJobs().size();
  scheduler.Start();
  spdlog::info(
      "springfitd {} listening on {}:{} (store {}, {} workers, {} jobs at once{}{})",
      scheduler.owner(), address.host, server.port(), store.Describe(), scheduler_options.workers,
      scheduler_options.max_running, token.empty() ? "" : ", token required",
      unfinished ? ", " + std::to_string(unfinished) + " unfinished jobs in the store" : "");
  WritePortFile(args.port_file, server.port());

  std::thread stopper;
  StopOnSignals(io, signals, service, server, scheduler, http, args.shutdown_seconds, stopper);
  std::signal(SIGPIPE, SIG_IGN);
  io.run();
  if (stopper.joinable()) stopper.join();
  spdlog::info("springfitd stopped");
  return 0;
}

// Where the daemon listens, keeps its jobs, and how many it runs.
void AddStoreAndWorkerOptions(CLI::App& app, DaemonArgs& args) {
  app.add_option("--listen", args.listen, "Address to listen on, HOST:PORT (port 0: any free port)")
      ->capture_default_str();
  auto* store_option = app.add_option(
      "--store", args.store,
      "Where jobs are kept: sqlite:///FILE (relative) or sqlite:////ABS/FILE, one daemon; or "
      "postgresql://USER@HOST[:PORT]/DB, shared by several daemons (password: "
      "--store-password-file, PGPASSWORD or PGPASSFILE, never in the URL). Default "
      "sqlite:///springfit.db");
  app.add_option("--db", args.db, "SQLite database file: the same as --store sqlite:///FILE")
      ->excludes(store_option);
  app.add_option("--store-password-file", args.store_password_file,
                 "File holding the PostgreSQL password (first line)");
  app.add_option("--store-timeout", args.store_timeout,
                 "PostgreSQL: every call to the database (heartbeat, claim, read, write) gives up "
                 "after this many seconds when the server does not answer (stopped, "
                 "partitioned), and is tried again later; server.info's count of the queue "
                 "after at most 1.5")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--name", args.name,
                 "This daemon's name in the leases of the jobs it runs; unique among the daemons "
                 "of one store (default host:pid:random)");
  app.add_option("--lease-seconds", args.lease_seconds,
                 "A running job's lease: how long after a daemon dies (or is cut off) another "
                 "daemon of the store takes its jobs over")
      ->check(CLI::Range(0.5, 3600.0))
      ->capture_default_str();
  app.add_option("--workers", args.workers, "Threads for fitness evaluations, all jobs together")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  app.add_option("--jobs", args.max_running, "Jobs run at once (default: --workers)")
      ->check(CLI::Range(1, 1024));
}

// Who may connect, what it serves beside the RPC, and its timings.
void AddServiceOptions(CLI::App& app, DaemonArgs& args) {
  app.add_option("--token-file", args.token_file,
                 "File holding the token clients must present (session.auth)");
  app.add_option("--port-file", args.port_file,
                 "Write the port listened on to this file once listening");
  app.add_option("--http", args.http,
                 "Serve the web dashboard, /healthz and /metrics on HOST:PORT (off by default; "
                 "beyond loopback only with --token-file)");
  app.add_option("--http-port-file", args.http_port_file,
                 "Write the dashboard's port to this file once listening");
  app.add_option("--log-level", args.log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  app.add_option("--checkpoint-seconds", args.checkpoint_seconds,
                 "Checkpoint running jobs at least this often")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  app.add_option("--idle-seconds", args.idle_seconds,
                 "Close connections idle this long (not while watching a job)")
      ->check(CLI::Range(1.0, 86400.0))
      ->capture_default_str();
  app.add_option("--message-seconds", args.message_seconds,
                 "Close a connection whose message is not complete this long after it began")
      ->check(CLI::Range(0.1, 86400.0))
      ->capture_default_str();
  app.add_option("--shutdown-seconds", args.shutdown_seconds,
                 "On SIGTERM, wait this long for running jobs to checkpoint")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
}

// The bounds a submission is checked against before any work (ServiceLimits) and the
// connections' bounds.
void AddLimitOptions(CLI::App& app, DaemonArgs& args) {
  app.add_option("--max-queued", args.limits.max_queued, "Queued jobs, all clients together")
      ->check(CLI::Range(1, 100000000))
      ->capture_default_str();
  app.add_option("--max-connections", args.max_connections, "Open connections")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--max-message-bytes", args.max_message_bytes, "Bytes in one JSON-RPC message")
      ->check(CLI::Range(std::size_t{1024}, std::size_t{1} << 30))
      ->capture_default_str();
  app.add_option("--max-unauthenticated-bytes", args.max_unauthenticated_bytes,
                 "With a token: bytes in one message before the connection's session.auth")
      ->check(CLI::Range(std::size_t{256}, std::size_t{1} << 30))
      ->capture_default_str();
  app.add_option("--max-inbox-bytes", args.max_inbox_bytes,
                 "Bytes of one connection's messages waiting to be handled; reading pauses "
                 "beyond")
      ->check(CLI::Range(std::size_t{1024}, std::size_t{1} << 34))
      ->capture_default_str();
  app.add_option("--max-nodes", args.limits.max_nodes, "Nodes in a submitted scene")
      ->check(CLI::Range(2, 100000000))
      ->capture_default_str();
  app.add_option("--max-genes", args.limits.max_genes, "Candidate springs in a submitted scene")
      ->check(CLI::Range(1, 100000000))
      ->capture_default_str();
  app.add_option(
         "--max-candidates", args.limits.max_candidates,
         "Candidate springs a submitted scene may ask for, estimated before generating them")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 40))
      ->capture_default_str();
  app.add_option("--max-population", args.limits.max_population,
                 "Population of a submitted job's genetic search")
      ->check(CLI::Range(2, 100000000))
      ->capture_default_str();
  app.add_option("--max-population-genes", args.limits.max_population_genes,
                 "Population times genes of a submitted job (bytes of one generation)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 50))
      ->capture_default_str();
  app.add_option("--max-generations", args.limits.max_generations,
                 "Generation limit of a submitted job")
      ->check(CLI::Range(1, 1000000000))
      ->capture_default_str();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"springfitd: the springfit identification daemon (JSON-RPC over TCP, proto/RPC.md)"};
  app.set_version_flag("--version", std::string("springfitd ") + springfit::server::kVersion);
  DaemonArgs args;
  AddStoreAndWorkerOptions(app, args);
  AddServiceOptions(app, args);
  AddLimitOptions(app, args);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 64;
  }
  try {
    return RunDaemon(args);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    std::cerr << "springfitd: " << e.what() << "\n";
    return 1;
  }
}
