#include "client/error_reporting.h"

#include <iostream>

#include "client/exit_codes.h"
#include "client/rpc_client.h"
#include "engine/api/input_error.h"
#include "proto/rpc.h"

namespace springfit::cli {

int ExitCodeOfRemoteError(int code) {
  namespace rpc = proto::rpc;
  switch (code) {
    case rpc::kInvalidScene:
    case rpc::kInvalidParams:
      return kExitInvalidInput;
    case rpc::kNoSuchJob:
      return kExitNotFound;
    case rpc::kUnauthorized:
      return kExitUnauthorized;
    case rpc::kBusy:
    case rpc::kLimitExceeded:
      return kExitBusy;
    case rpc::kWrongState:
      return kExitWrongState;
    default:
      return kExitFailure;
  }
}

int RunReportingErrors(const std::string& context, const std::function<int()>& body) {
  try {
    return body();
  } catch (const InputError& e) {
    std::cerr << "springfit: " << context << ": " << e.what() << "\n";
    return kExitInvalidInput;
  } catch (const ConnectionError& e) {
    std::cerr << "springfit: " << e.what() << "\n";
    return kExitConnection;
  } catch (const RemoteError& e) {
    std::cerr << "springfit: " << context << ": " << e.what() << "\n";
    return ExitCodeOfRemoteError(e.code());
  } catch (const std::exception& e) {
    std::cerr << "springfit: " << context << ": " << e.what() << "\n";
    return kExitFailure;
  }
}

}  // namespace springfit::cli
