#include "client/error_reporting.h"

#include <iostream>

#include "client/exit_codes.h"
#include "engine/input_error.h"

namespace springfit::cli {

int RunReportingErrors(const std::string& context, const std::function<int()>& body) {
  try {
    return body();
  } catch (const InputError& e) {
    std::cerr << "springfit: " << context << ": " << e.what() << "\n";
    return kExitInvalidInput;
  } catch (const std::exception& e) {
    std::cerr << "springfit: " << context << ": " << e.what() << "\n";
    return kExitFailure;
  }
}

}  // namespace springfit::cli
