// Measures springfitd from the outside (bench/RESULTS.md, "The daemon"; run through
// bench/daemon_bench.sh, which starts a daemon on loopback):
//   --get:       job.get requests per second with N concurrent clients, and their latency;
//   --overhead:  a job through the daemon (submit -> job.finished, end to end) against the
//                same search in this process with the same seed and thread count.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "client/rpc_client.h"
#include "engine/api/problem.h"
#include "engine/identification/identify.h"
#include "proto/names.h"
#include "proto/scene_codec.h"

namespace {
using springfit::proto::Json;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

Json SceneWith(const std::string& path, const std::string& strategy, int generations) {
  Json scene = springfit::proto::ParseJson(springfit::proto::ReadFile(path));
  scene["search"]["strategy"] = strategy;
  scene["search"]["max_generations"] = generations;
  return scene;
}

void BenchGet(const springfit::cli::ServerOptions& server, const std::string& scene_path,
              int clients, double seconds) {
  std::int64_t id = 0;
  {
    springfit::cli::RpcClient c(server);
    Json params;
    params["scene"] = springfit::proto::ParseJson(springfit::proto::ReadFile(scene_path));
    id = c.Call("job.submit", params)["job"]["job_id"].get<std::int64_t>();
  }
  std::atomic<bool> go{false};
  std::vector<std::vector<double>> latencies(clients);
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i) {
    threads.emplace_back([&, i] {
      springfit::cli::RpcClient c(server);
      Json params;
      params["job_id"] = id;
      while (!go.load()) std::this_thread::yield();
      const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                          std::chrono::duration<double>(seconds));
      while (Clock::now() < end) {
        const auto t0 = Clock::now();
        c.Call("job.get", params);
        latencies[i].push_back(Seconds(Clock::now() - t0));
      }
    });
  }
  const auto t0 = Clock::now();
  go.store(true);
  for (auto& t : threads) t.join();
  const double wall = Seconds(Clock::now() - t0);
  std::vector<double> all;
  for (const auto& l : latencies) all.insert(all.end(), l.begin(), l.end());
  std::printf(
      "job.get: %d clients, %.1f s: %zu requests, %.0f requests/s, latency median %.3f ms, p99 "
      "%.3f ms\n",
      clients, wall, all.size(), static_cast<double>(all.size()) / wall, 1e3 * Percentile(all, 0.5),
      1e3 * Percentile(all, 0.99));
}

void BenchOverhead(const springfit::cli::ServerOptions& server, const std::string& scene_path,
                   const std::string& strategy, int generations, int threads, int repeats) {
  const Json scene = SceneWith(scene_path, strategy, generations);
  std::vector<double> daemon_wall, daemon_search, local_wall;
  for (int r = 0; r < repeats; ++r) {
    const std::uint64_t seed = 100 + static_cast<std::uint64_t>(r);
    {
      springfit::cli::RpcClient c(server);
      Json params;
      params["scene"] = scene;
      params["seed"] = seed;
      const auto t0 = Clock::now();
      const std::int64_t id = c.Call("job.submit", params)["job"]["job_id"].get<std::int64_t>();
      Json watch;
      watch["job_id"] = id;
      c.Call("job.watch", watch);
      while (true) {
        const Json n = c.NextNotification();
        if (n["method"] == "job.finished" && n["params"]["job_id"] == id) break;
      }
      daemon_wall.push_back(Seconds(Clock::now() - t0));
      daemon_search.push_back(c.Call("job.result", watch)["wall_seconds"].get<double>());
    }
    {
      const auto t0 = Clock::now();
      springfit::Scene s = springfit::proto::SceneFromJson(scene);
      s.search.seed = seed;
      const springfit::Problem problem = springfit::Problem::Build(std::move(s));
      springfit::RunContext run;
      run.threads = threads;
      springfit::RunIdentification(
          problem, springfit::ResolveSearchOptions(problem.scene().search, problem.gene_count()),
          run);
      local_wall.push_back(Seconds(Clock::now() - t0));
    }
  }
  // Run times vary a lot between seeds: compare each seed with itself.
  std::vector<double> ratios;
  for (int r = 0; r < repeats; ++r) ratios.push_back(daemon_wall[r] / local_wall[r]);
  std::printf(
      "overhead: %s, %s, %d generations, %d threads, %d seeds: daemon end to end median %.3f s "
      "(search %.3f s), in-process median %.3f s; daemon/in-process per seed: median %.3f, max "
      "%.3f\n",
      scene_path.c_str(), strategy.c_str(), generations, threads, repeats,
      Percentile(daemon_wall, 0.5), Percentile(daemon_search, 0.5), Percentile(local_wall, 0.5),
      Percentile(ratios, 0.5), Percentile(ratios, 1.0));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"daemon_bench: springfitd throughput and overhead"};
  springfit::cli::ServerOptions server;
  std::string scene = "examples/paper-iso-5x5.json";
  bool get = false;
  int clients = 50;
  double seconds = 5.0;
  std::string overhead_scene;
  std::string strategy = "paper";
  int generations = 100;
  int threads = 2;
  int repeats = 5;
  app.add_option("--server", server.server, "springfitd HOST:PORT")->required();
  app.add_flag("--get", get, "Measure job.get requests per second");
  app.add_option("--scene", scene, "Scene of the job that --get reads");
  app.add_option("--clients", clients, "Concurrent clients for --get")->capture_default_str();
  app.add_option("--seconds", seconds, "Duration of --get")->capture_default_str();
  app.add_option("--overhead", overhead_scene,
                 "Scene for the daemon-against-in-process comparison");
  app.add_option("--strategy", strategy, "Strategy of the --overhead runs")->capture_default_str();
  app.add_option("--generations", generations, "Generations of the --overhead runs")
      ->capture_default_str();
  app.add_option("--threads", threads, "In-process threads (match the daemon's --workers)")
      ->capture_default_str();
  app.add_option("--repeats", repeats, "Seeds of the --overhead runs")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    if (get) BenchGet(server, scene, clients, seconds);
    if (!overhead_scene.empty())
      BenchOverhead(server, overhead_scene, strategy, generations, threads, repeats);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "daemon_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
