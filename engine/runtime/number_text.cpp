#include "engine/runtime/number_text.h"

#include <fmt/format.h>

namespace springfit {

std::string NumberText(double value, int digits) {
  return fmt::format("{:.{}g}", value, digits);
}

}  // namespace springfit
