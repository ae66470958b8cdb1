#include "engine/runtime/options_check.h"

#include <fmt/format.h>

namespace springfit {

void OptionsCheck::Fail(std::string_view field, double value, std::string_view rule) const {
  // (17 digits: the value exactly as the caller set it.)
  throw std::invalid_argument(
      fmt::format("{}::{} = {:.17g}. Violated constraint: {}", owner_, field, value, rule));
}

}  // namespace springfit
