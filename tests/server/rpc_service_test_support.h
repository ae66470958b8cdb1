// What the RpcService tests (rpc_*_test.cpp) share: a session's inbox and the fixture, the
// service over a real SQLite store and scheduler.
#pragma once
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "io/example_catalog.h"
#include "proto/json_reader.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "server/jobs/scheduler.h"
#include "server/rpc/rpc_service.h"
#include "server/store/sqlite_store.h"

namespace springfit::server {

// Collects notifications sent to a session, from any thread.
class Inbox {
 public:
  void Push(const proto::Json& n) {
    std::lock_guard lock(mutex_);
    messages_.push_back(n);
    cv_.notify_all();
  }
  // Waits (at most 60 s) for a notification of `method`; null when none came.
  proto::Json WaitFor(const std::string& method) {
    std::unique_lock lock(mutex_);
    proto::Json found;
    cv_.wait_for(lock, std::chrono::seconds(60), [&] {
      for (const proto::Json& m : messages_) {
        if (m["method"] == method) {
          found = m;
          return true;
        }
      }
      return false;
    });
    return found;
  }
  std::vector<proto::Json> All() {
    std::lock_guard lock(mutex_);
    return messages_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<proto::Json> messages_;
};

class RpcServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           (std::string("springfit-rpc-") +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    store_ = std::make_unique<SqliteStore>((dir_ / "jobs.db").string());
    session_.notify = [this](const proto::Json& n) { inbox_.Push(n); };
  }
  void TearDown() override {
    service_.reset();
    scheduler_.reset();
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  // `start` = false leaves every job queued (no runner threads).
  void MakeService(bool start, ServiceOptions options = {}) {
    SchedulerOptions so;
    so.workers = 2;
    so.max_running = 1;
    scheduler_ = std::make_unique<Scheduler>(*store_, so);
    if (start) scheduler_->Start();
    service_ = std::make_unique<RpcService>(*store_, *scheduler_, options);
  }
  proto::Json Call(const std::string& method, proto::Json params = proto::Json::object()) {
    const std::string text =
        proto::rpc::Serialize(proto::rpc::Request(++id_, method, std::move(params)));
    return proto::ParseJson(service_->HandleMessage(text, session_));
  }
  static int Code(const proto::Json& response) {
    return response.at("error").at("code").get<int>();
  }
  static proto::Json Scene(const std::string& name) {
    return proto::SceneToJson(examples::Make(name));
  }
  proto::Json Submit(const std::string& name, proto::Json extra = proto::Json::object()) {
    proto::Json params = std::move(extra);
    params["scene"] = Scene(name);
    return Call("job.submit", params);
  }

  std::filesystem::path dir_;
  std::unique_ptr<SqliteStore> store_;
  std::unique_ptr<Scheduler> scheduler_;
  std::unique_ptr<RpcService> service_;
  SessionContext session_;
  Inbox inbox_;
  std::int64_t id_ = 0;
};

}  // namespace springfit::server
